// find_color on tiny hand-built scenes against Phong / Blinn-Phong values worked out by hand:
//   R = E + sum_j V_j L_j (Ca + Cd max(n.l, 0) + Cs max(n.h, 0)^s) + Cs FindColor(reflected).

#include "catch.h"

#include <cmath>
#include <memory>
#include <numbers>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/core/error.h"
#include "rt/render/shade.h"
#include "test_util.h"

namespace {

using rt::Color;
using rt::Vec3d;
using rt::Vec3f;

// The floor: one large triangle in the plane z = 0, facing +z, containing (0.3, 0.2, 0) well
// inside (far from its edges).
const std::array<Vec3f, 3> kFloor{Vec3f(-50, -50, 0), Vec3f(50, -50, 0), Vec3f(0, 50, 0)};
// The hit point most tests shade, and rays that reach it.
const Vec3f kPoint(0.3f, 0.2f, 0.0f);

// Scene, flattened geometry, accelerator and shading context, built in place (the context holds
// references into the fixture, so it is neither copied nor moved).
struct Fixture {
  rt::Scene scene;
  rt::FlatScene flat;
  std::unique_ptr<rt::Accel> accel;
  rt::EffectsOptions effects;  // the plan is made per shade() call, after sections edit the scene

  Fixture(rt::Scene s, rt::AccelKind kind) : scene(std::move(s)), flat(rt::flatten_scene(scene)) {
    accel = rt::build_accel(kind, flat);
  }
  Fixture(const Fixture&) = delete;
  Fixture& operator=(const Fixture&) = delete;

  Color shade(Vec3f origin, Vec3f direction, rt::RayCounts& counts, int depth = 0) const {
    rt::Ray ray;
    ray.origin = origin;
    ray.direction = direction;
    const rt::EffectsPlan plan = rt::plan_effects(scene, flat, rt::RayOffset{}, effects);
    return rt::find_color(rt::ShadingContext{scene, flat, *accel, plan}, ray, depth, counts);
  }
};

rt::Material material(Vec3d ambient, Vec3d diffuse, Vec3d specular, float shininess, Vec3d emission = Vec3d(0.0)) {
  rt::Material m;
  m.ambient = Color(ambient);
  m.diffuse = Color(diffuse);
  m.specular = Color(specular);
  m.emission = Color(emission);
  m.shininess = shininess;
  return m;
}

rt::Light directional(Vec3d towards_light, Vec3d color) {
  rt::Light light;
  light.position = rt::Vec4d(towards_light, 0.0);
  light.color = Color(color);
  return light;
}

rt::Light point(Vec3d position, Vec3d color, Vec3d attenuation) {
  rt::Light light;
  light.position = rt::Vec4d(position, 1.0);
  light.color = Color(color);
  light.attenuation = attenuation;
  return light;
}

// One floor with `floor_material`, no reflections, black background, the given lights.
rt::Scene floor_scene(const rt::Material& floor_material, std::vector<rt::Light> lights) {
  rt::Scene scene = rt_test::make_scene({{rt_test::make_flat_mesh({kFloor}), 0}});
  scene.materials = {floor_material};
  scene.lights = std::move(lights);
  scene.settings.max_depth = 0;
  return scene;
}

void check_color(const Color& actual, const Vec3d& expected) {
  INFO("actual (" << actual.r << ", " << actual.g << ", " << actual.b << "), expected (" << expected.r << ", "
                  << expected.g << ", " << expected.b << ")");
  CHECK(actual.r == Approx(expected.r).margin(1e-5));
  CHECK(actual.g == Approx(expected.g).margin(1e-5));
  CHECK(actual.b == Approx(expected.b).margin(1e-5));
}

}  // namespace

TEST_CASE("diffuse shading from one directional light", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  // Light towards (0, 1, 1): n.l = cos 45 deg = 1/sqrt2. Only diffuse: R = L Cd / sqrt2.
  Fixture f(floor_scene(material(Vec3d(0.0), {0.8, 0.4, 0.2}, Vec3d(0.0), 1.0f),
                        {directional({0.0, 1.0, 1.0}, {1.0, 0.5, 2.0})}),
            kind);
  rt::RayCounts counts;
  const Color c = f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, counts);
  const double k = 1.0 / std::sqrt(2.0);
  check_color(c, {1.0 * 0.8 * k, 0.5 * 0.4 * k, 2.0 * 0.2 * k});
  CHECK(counts.camera == 0);  // find_color counts secondary rays only; the render loop counts camera rays
  CHECK(counts.shadow == 0);  // a lone floor is convex: facing the light, it is lit for certain
  CHECK(counts.skipped[int(rt::SkipRule::convex_facing)] == 1);
  CHECK(counts.reflection == 0);

  SECTION("the light's direction need not be unit length") {
    f.scene.lights[0].position = rt::Vec4d(0.0, 7.0, 7.0, 0.0);
    rt::RayCounts again;
    check_color(f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, again), {0.8 * k, 0.2 * k, 0.4 * k});
  }
  SECTION("a light below the surface gives no diffuse term") {
    f.scene.lights[0].position = rt::Vec4d(0.0, 1.0, -1.0, 0.0);
    rt::RayCounts again;
    check_color(f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, again), Vec3d(0.0));
  }
  SECTION("with max_depth 1 the reflection, weighted by the (zero) specular colour, is pruned") {
    f.scene.settings.max_depth = 1;
    f.scene.settings.background = Color(0.5f, 0.6f, 0.7f);
    rt::RayCounts again;
    check_color(f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, again), {0.8 * k, 0.2 * k, 0.4 * k});
    CHECK(again.skipped[int(rt::SkipRule::convex_facing)] == 1);
    CHECK(again.reflection == 0);
    CHECK(again.skipped[int(rt::SkipRule::black_reflection)] == 1);
    f.effects.prune = false;  // --no-prune traces it, and it adds zero
    rt::RayCounts unpruned;
    check_color(f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, unpruned), {0.8 * k, 0.2 * k, 0.4 * k});
    CHECK(unpruned.reflection == 1);
    CHECK(unpruned.skipped_total() == 0);
  }
}

// When the light lies exactly opposite the viewer (l = -v), l + v = 0 and the half vector is
// undefined; n.l < 0 and n.h cannot be positive, so the unshadowed light adds only L Ca (no NaN).
TEST_CASE("a light exactly opposite the viewer adds only its ambient term", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  // Light towards -z (below the floor), nothing below to block it; view from straight above.
  Fixture f(floor_scene(material(Vec3d(0.25), Vec3d(0.5), Vec3d(0.0), 8.0f), {directional({0, 0, -1}, Vec3d(1.0))}),
            kind);
  rt::RayCounts counts;
  const Color c = f.shade(kPoint + Vec3f(0, 0, 1), {0, 0, -1}, counts);
  CHECK(std::isfinite(c.r));
  check_color(c, Vec3d(0.25));
}

TEST_CASE("Blinn-Phong specular term", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  const Vec3d cs(0.5, 0.25, 1.0);
  Fixture f(floor_scene(material(Vec3d(0.0), Vec3d(0.0), cs, 10.0f), {directional({0.0, 1.0, 1.0}, Vec3d(1.0))}),
            kind);
  rt::RayCounts counts;

  SECTION("viewed from straight above: h halfway between l (45 deg) and v (0 deg)") {
    // n.h = cos 22.5 deg.
    const double nh = std::cos(std::numbers::pi / 8.0);
    check_color(f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, counts), cs * std::pow(nh, 10.0));
  }
  SECTION("viewed from the mirror direction: h = n, full highlight") {
    // v = (0, -1, 1)/sqrt2 and l = (0, 1, 1)/sqrt2: h = (0, 0, 1), n.h = 1.
    check_color(f.shade(kPoint + Vec3f(0, -1, 1), {0, 1, -1}, counts), cs);
  }
  SECTION("ambient, diffuse and specular add up") {
    f.scene.materials[0] = material(Vec3d(0.1), Vec3d(0.3), cs, 10.0f);
    const double nl = 1.0 / std::sqrt(2.0), nh = std::cos(std::numbers::pi / 8.0);
    check_color(f.shade(kPoint + Vec3f(0, 0, 2), {0, 0, -1}, counts),
                Vec3d(0.1) + Vec3d(0.3) * nl + cs * std::pow(nh, 10.0));
  }
  CHECK(counts.shadow == 0);  // a lone floor is convex: facing the light, it is lit for certain
  CHECK(counts.skipped[int(rt::SkipRule::convex_facing)] == 1);
}

TEST_CASE("point lights are attenuated by 1 / (c0 + c1 d + c2 d^2)", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  const Vec3d color(0.9, 0.6, 0.3);

  SECTION("light straight above at d = 2") {
    // c0 + c1 d + c2 d^2 = 0.5 + 0.25 * 2 + 0.125 * 4 = 1.5; n.l = 1.
    Fixture f(floor_scene(material(Vec3d(0.1), Vec3d(0.6), Vec3d(0.0), 1.0f),
                          {point(Vec3d(kPoint) + Vec3d(0, 0, 2), color, {0.5, 0.25, 0.125})}),
              kind);
    rt::RayCounts counts;
    check_color(f.shade(kPoint + Vec3f(0, 0, 1), {0, 0, -1}, counts), color / 1.5 * (0.1 + 0.6));
    CHECK(counts.shadow == 0);  // a lone floor is convex: facing the light, it is lit for certain
  CHECK(counts.skipped[int(rt::SkipRule::convex_facing)] == 1);
  }
  SECTION("light off to the side at d = 5 (a 3-4-5 triangle)") {
    // l = (0.6, 0, 0.8): n.l = 0.8. Seen from above, h ~ (0.6, 0, 1.8), n.h = 3 / sqrt10,
    // (n.h)^4 = 0.81. Attenuation 1 + 0.2 * 5 + 0.04 * 25 = 3.
    Fixture f(floor_scene(material(Vec3d(0.05), Vec3d(0.5), Vec3d(0.2), 4.0f),
                          {point(Vec3d(kPoint) + Vec3d(3, 0, 4), color, {1.0, 0.2, 0.04})}),
              kind);
    rt::RayCounts counts;
    check_color(f.shade(kPoint + Vec3f(0, 0, 1), {0, 0, -1}, counts), color / 3.0 * (0.05 + 0.5 * 0.8 + 0.2 * 0.81));
  }
  SECTION("directional lights are never attenuated") {
    rt::Light light = directional({0, 0, 1}, color);
    light.attenuation = {2.0, 1.0, 1.0};
    Fixture f(floor_scene(material(Vec3d(0.0), Vec3d(0.5), Vec3d(0.0), 1.0f), {light}), kind);
    rt::RayCounts counts;
    check_color(f.shade(kPoint + Vec3f(0, 0, 1), {0, 0, -1}, counts), color * 0.5);
  }
}

TEST_CASE("a shadowed light contributes nothing, not even ambient", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  // An occluder at z = 1 right above the shaded point (0.3, 0.2, 0); it spans x in [-0.2, 0.8].
  const auto occluder = rt_test::make_flat_mesh(
      {{Vec3f(-0.2f, -0.3f, 1.0f), Vec3f(0.8f, -0.3f, 1.0f), Vec3f(0.3f, 0.7f, 1.0f)}});
  const Vec3d ca(0.1, 0.2, 0.3), cd(0.5), emission(0.01, 0.02, 0.03);
  rt::Scene scene = rt_test::make_scene({{rt_test::make_flat_mesh({kFloor}), 0}, {occluder, 1}});
  scene.materials = {material(ca, cd, Vec3d(0.0), 1.0f, emission), material(Vec3d(1.0), Vec3d(1.0), Vec3d(0.0), 1.0f)};
  scene.settings.max_depth = 0;
  const Vec3d l_point(1.0, 0.9, 0.8), l_up(0.7, 0.6, 0.5), l_side(0.5, 0.4, 0.3);
  scene.lights = {point(Vec3d(kPoint) + Vec3d(0, 0, 2), l_point, {1, 0, 0}),  // behind the occluder
                  directional({0, 0, 1}, l_up),                               // behind the occluder
                  directional({1, 0, 1}, l_side)};                            // passes it at x = 1.3
  // Look from (3.3, 0.2, 3) along (-1, 0, -1): the ray passes z = 1 at x = 1.3, beside the occluder.
  const Vec3f eye = kPoint + Vec3f(3, 0, 3), towards(-1, 0, -1);
  const double k = 1.0 / std::sqrt(2.0);

  SECTION("two lights blocked") {
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts), emission + l_side * (ca + cd * k));
    CHECK(counts.shadow == 3);
    CHECK(counts.reflection == 0);
  }
  SECTION("without the occluder all three lights reach the point") {
    scene.nodes[0].models.pop_back();
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts),
                emission + l_point * (ca + cd) + l_up * (ca + cd) + l_side * (ca + cd * k));
    CHECK(counts.skipped[int(rt::SkipRule::convex_facing)] == 3);  // the floor alone is convex
  }
  SECTION("an occluder beyond a point light does not shadow it") {
    scene.lights = {point(Vec3d(kPoint) + Vec3d(0, 0, 0.5), l_point, {1, 0, 0})};
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts), emission + l_point * (ca + cd));
    CHECK(counts.shadow == 1);
  }
}

TEST_CASE("emission and background", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  // No lights: ambient is per light, so only the emission remains.
  const Vec3d emission(0.2, 0.3, 0.4);
  rt::Scene scene = floor_scene(material(Vec3d(0.5), Vec3d(0.5), Vec3d(0.0), 1.0f, emission), {});
  scene.settings.background = Color(0.1f, 0.2f, 0.3f);
  Fixture f(std::move(scene), kind);
  rt::RayCounts counts;
  check_color(f.shade(kPoint + Vec3f(0, 0, 1), {0, 0, -1}, counts), emission);
  CHECK(counts.total() == 0);

  // A ray that misses everything returns the background and traces nothing else.
  check_color(f.shade(kPoint + Vec3f(0, 0, 1), {0, 0, 1}, counts), {0.1, 0.2, 0.3});
  check_color(f.shade(kPoint + Vec3f(0, 0, -1), {1, 0, 0}, counts), {0.1, 0.2, 0.3});
  CHECK(counts.total() == 0);
}

TEST_CASE("mirror reflection recurses while depth < max_depth", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  // A mirror floor at z = 0 and an emissive, partly mirroring ceiling at z = 2 facing down, no
  // lights. The primary ray from (-1, 0, 1) along (1, 0, -1) hits the floor at the origin (depth
  // 0), then bounces to the ceiling at (2, 0, 2) (depth 1), the floor at (4, 0, 0) (depth 2), ...
  // so R(d) = E(d) + Cs(d) R(d + 1) for d < max_depth and R(max_depth) = E(max_depth).
  const Vec3d e_floor(0.01, 0.02, 0.03), cs_floor(0.5, 0.6, 0.7);
  const Vec3d e_ceiling(1.0, 0.5, 0.25), cs_ceiling(0.5, 0.25, 0.5);
  const auto ceiling = rt_test::make_flat_mesh({{Vec3f(-50, -50, 2), Vec3f(0, 50, 2), Vec3f(50, -50, 2)}});
  rt::Scene scene = rt_test::make_scene({{rt_test::make_flat_mesh({kFloor}), 0}, {ceiling, 1}});
  scene.materials = {material(Vec3d(0.0), Vec3d(0.0), cs_floor, 1.0f, e_floor),
                     material(Vec3d(0.0), Vec3d(0.0), cs_ceiling, 1.0f, e_ceiling)};
  scene.settings.background = Color(0.9f);  // never reached
  const Vec3f eye(-1, 0, 1), towards(1, 0, -1);

  auto expected = [&](int max_depth) {
    const auto emission = [&](int d) { return d % 2 == 0 ? e_floor : e_ceiling; };
    const auto specular = [&](int d) { return d % 2 == 0 ? cs_floor : cs_ceiling; };
    Vec3d value = emission(max_depth);
    for (int d = max_depth - 1; d >= 0; --d) value = emission(d) + specular(d) * value;
    return value;
  };

  SECTION("max_depth 0: no reflection ray") {
    scene.settings.max_depth = 0;
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts), e_floor);
    CHECK(counts.reflection == 0);
    CHECK(counts.shadow == 0);
  }
  SECTION("max_depth 1: the floor reflects the ceiling's emission") {
    scene.settings.max_depth = 1;
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts), e_floor + cs_floor * e_ceiling);
    CHECK(counts.reflection == 1);
  }
  SECTION("max_depth 2: ... which reflects the floor's emission") {
    scene.settings.max_depth = 2;
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts), e_floor + cs_floor * (e_ceiling + cs_ceiling * e_floor));
    CHECK(counts.reflection == 2);
  }
  SECTION("max_depth 5") {
    scene.settings.max_depth = 5;
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    check_color(f.shade(eye, towards, counts), expected(5));
    CHECK(counts.reflection == 5);
    CHECK(counts.shadow == 0);
    // Starting deeper leaves fewer levels: a primary ray at depth 3 recurses twice.
    rt::RayCounts deeper;
    check_color(f.shade(eye, towards, deeper, 3), expected(2));
    CHECK(deeper.reflection == 2);
  }
  SECTION("one shadow ray per light at every hit") {
    scene.settings.max_depth = 3;
    scene.lights = {directional({0, 1, 0}, Vec3d(1.0)), point({0, 5, 1}, Vec3d(1.0), {1, 0, 0})};
    Fixture f(std::move(scene), kind);
    rt::RayCounts counts;
    f.shade(eye, towards, counts);
    CHECK(counts.reflection == 3);
    CHECK(counts.shadow == 2 * 4);  // four hits (depth 0..3), two lights
  }
}

TEST_CASE("a mirror alone reflects the background once", "[shade]") {
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  INFO("accel " << rt::to_string(kind));
  const Vec3d e(0.05, 0.0, 0.1), cs(0.5, 0.6, 0.7), background(0.2, 0.4, 0.8);
  rt::Scene scene = floor_scene(material(Vec3d(0.0), Vec3d(0.0), cs, 1.0f, e), {});
  scene.settings.max_depth = 5;
  scene.settings.background = Color(background);
  Fixture f(std::move(scene), kind);
  rt::RayCounts counts;
  check_color(f.shade(kPoint + Vec3f(-1, 0, 1), {1, 0, -1}, counts), e + cs * background);
  CHECK(counts.reflection == 1);  // the reflected ray escapes; a miss spawns nothing
  CHECK(counts.shadow == 0);
}

TEST_CASE("offset_ray_origin moves off the surface to the side of the direction", "[shade]") {
  const rt::RayOffset policy = GENERATE(rt::RayOffset{}, rt::parse_ray_offset("fixed:1e-3"));
  INFO("ray offset " << rt::to_string(policy));
  const rt::SurfacePoint surface = rt::make_surface_point({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0.3, 0.2);
  REQUIRE(surface.point == Vec3d(0.3, 0.2, 0.0));
  REQUIRE(surface.geometric_normal == Vec3d(0.0, 0.0, 1.0));
  const Vec3f above = rt::offset_ray_origin(policy, surface, {0.0, 1.0, 1.0});
  const Vec3f below = rt::offset_ray_origin(policy, surface, {0.0, 1.0, -1.0});
  CHECK(above.x == 0.3f);
  CHECK(above.y == 0.2f);
  CHECK(above.z > 0.0f);
  CHECK(above.z < 1e-2f);
  CHECK(below.z < 0.0f);
  CHECK(below.z > -1e-2f);
  CHECK(below.z == -above.z);
  if (policy.mode == rt::RayOffset::Mode::fixed) CHECK(above.z == 1e-3f);
}

TEST_CASE("ray offsets parse and print", "[shade]") {
  CHECK(rt::parse_ray_offset("robust").mode == rt::RayOffset::Mode::robust);
  const rt::RayOffset fixed = rt::parse_ray_offset("fixed:2.5e-4");
  CHECK(fixed.mode == rt::RayOffset::Mode::fixed);
  CHECK(fixed.epsilon == 2.5e-4);
  CHECK(rt::to_string(fixed) == "fixed:0.00025");
  for (const char* bad : {"", "fixed", "fixed:", "fixed:0", "fixed:-1", "fixed:abc", "fixed:1e-4x", "fixed:inf", "tight"})
    CHECK_THROWS_AS(rt::parse_ray_offset(bad), rt::InputError);
}

TEST_CASE("RayCounts add per kind", "[shade]") {
  rt::RayCounts a, b;
  a.camera = 1;
  a.shadow = 2;
  a.reflection = 3;
  b.camera = 10;
  b.shadow = 20;
  b.reflection = 30;
  a += b;
  CHECK(a.camera == 11);
  CHECK(a.shadow == 22);
  CHECK(a.reflection == 33);
  CHECK(a.total() == 66);
}
