// Area lights: the sample patterns and warps against their defining properties, the estimator
// against closed-form irradiance (Lambert's polygon formula) and against a point light in the
// limit of a small emitter, one-sided emission, exact pruning, and the loaders' emitters.

#include "catch.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <set>
#include <tuple>

#include "rt/accel/accel.h"
#include <glm/gtc/matrix_transform.hpp>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/render/area_lights.h"
#include "rt/render/render.h"
#include "rt/render/sampling.h"
#include "rt/render/shade.h"
#include "rt/scene/shapes.h"
#include "render/lane_libm.h"
#include "render/light_sample_lanes.h"
#include "test_util.h"

namespace {

using rt::Color;
using rt::Vec2d;
using rt::Vec3d;
using rt::Vec3f;

constexpr double kPi = std::numbers::pi;

// Every build of the light-sample kernels this CPU runs, the baseline first.
std::vector<const rt::light_sample_lanes::Kernels*> every_lanes_build() {
  std::vector<const rt::light_sample_lanes::Kernels*> builds{&rt::light_sample_lanes::baseline_kernels()};
  for (const rt::light_sample_lanes::Kernels* build : rt::light_sample_lanes::wider_kernels()) builds.push_back(build);
  return builds;
}

// Lambert's formula (1760) for the cosine-weighted solid angle of a polygon seen from p with unit
// normal n: integral of max(n.w, 0) over the directions w towards the polygon, when the polygon is
// entirely above p's tangent plane: (1/2) |sum_i theta_i n . normalize(v_i x v_i+1)|, v_i the unit
// directions to the vertices, theta_i the angle between consecutive ones.
double lambert_cosine_solid_angle(const Vec3d& p, const Vec3d& n, const std::vector<Vec3d>& polygon) {
  double sum = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Vec3d a = glm::normalize(polygon[i] - p), b = glm::normalize(polygon[(i + 1) % polygon.size()] - p);
    const Vec3d cross = glm::cross(a, b);
    sum += std::atan2(glm::length(cross), glm::dot(a, b)) * glm::dot(n, glm::normalize(cross));
  }
  return 0.5 * std::abs(sum);
}

rt::Material diffuse_material(Vec3d diffuse, Vec3d specular = Vec3d(0.0), float shininess = 1.0f) {
  rt::Material m;
  m.name = "surface";
  m.diffuse = Color(diffuse);
  m.specular = Color(specular);
  m.shininess = shininess;
  m.reflective = Color(0.0f);
  return m;
}

rt::Material emitter_material(Vec3d radiance) {
  rt::Material m;
  m.name = "lamp";
  m.emission = Color(radiance);
  m.emits_light = true;
  m.reflective = Color(0.0f);
  return m;
}

// A floor in z = 0 (material 0, facing +z) and the emitter polygon (material 1), a triangle or a
// quad given counter-clockwise seen from its front, fanned into triangles.
rt::Scene floor_and_emitter(const std::vector<Vec3f>& emitter, Vec3d radiance, rt::Material floor_material) {
  std::vector<std::array<Vec3f, 3>> lamp;
  for (std::size_t i = 1; i + 1 < emitter.size(); ++i) lamp.push_back({emitter[0], emitter[i], emitter[i + 1]});
  rt::Scene scene = rt_test::make_scene(
      {{rt_test::make_flat_mesh({{Vec3f(-50, -50, 0), Vec3f(50, -50, 0), Vec3f(0, 50, 0)}}), 0},
       {rt_test::make_flat_mesh(lamp), 1}});
  scene.materials = {floor_material, emitter_material(radiance)};
  scene.camera.eye = Vec3d(0.0, -3.0, 3.0);
  scene.camera.target = Vec3d(0.0);
  scene.settings.max_depth = 0;
  return scene;
}

// find_color along `ray` with the given sampling options, through Embree.
struct Shader {
  rt::Scene scene;
  rt::FlatScene flat;
  std::unique_ptr<rt::Accel> accel;
  const rt::TextureSampler* textures = nullptr;  // emission textures, when the test has any

  explicit Shader(rt::Scene s) : scene(std::move(s)), flat(rt::flatten_scene(scene)) {
    accel = rt::build_accel(rt::AccelKind::embree, flat);
  }
  Color shade(Vec3f origin, Vec3f direction, const rt::EffectsOptions& options, rt::RayCounts& counts,
              std::uint64_t seed = 1) const {
    rt::Ray ray;
    ray.origin = origin;
    ray.direction = glm::normalize(direction);
    const rt::EffectsPlan plan = rt::plan_effects(scene, flat, rt::RayOffset{}, options, textures);
    return rt::find_color(rt::ShadingContext{scene, flat, *accel, plan, {}, textures}, ray, 0, counts, Vec3d(1.0),
                          seed);
  }
};

}  // namespace

TEST_CASE("cmj_sample: every point in the unit square, one per y stratum, columns balanced, deterministic") {
  for (std::uint32_t count : {1u, 2u, 3u, 7u, 16u, 33u, 100u}) {
    for (std::uint32_t pattern : {0u, 1u, 0xdeadbeefu}) {
      const auto columns = static_cast<std::uint32_t>(std::sqrt(double(count)));
      std::set<std::uint32_t> y_strata;
      std::vector<std::uint32_t> per_column(columns, 0);
      for (std::uint32_t i = 0; i < count; ++i) {
        const Vec2d u = rt::cmj_sample(i, count, pattern);
        REQUIRE(u.x >= 0.0);
        REQUIRE(u.x < 1.0);
        REQUIRE(u.y >= 0.0);
        REQUIRE(u.y < 1.0);
        y_strata.insert(static_cast<std::uint32_t>(u.y * count));
        ++per_column[static_cast<std::uint32_t>(u.x * columns)];
        CHECK(rt::cmj_sample(i, count, pattern) == u);
      }
      CHECK(y_strata.size() == count);
      for (std::uint32_t n : per_column) CHECK(n <= (count + columns - 1) / columns);
    }
  }
  CHECK(rt::cmj_sample(3, 16, 1) != rt::cmj_sample(3, 16, 2));
}

// The batch form the area-light shader draws its samples with: the same bits as cmj_sample, for
// counts that are and are not powers of two or squares (the cycle walk and the mask shortcuts),
// from any first point, across its 64-point chunks.
TEST_CASE("cmj_samples: the points of cmj_sample bit for bit, from any first index, in any chunking") {
  std::mt19937 random(167);
  int compared = 0;
  for (std::uint32_t count : {1u, 2u, 3u, 4u, 5u, 8u, 9u, 12u, 16u, 17u, 31u, 36u, 64u, 65u, 100u, 200u}) {
    for (int round = 0; round < 40; ++round) {
      const std::uint32_t pattern = round == 0 ? 0u : std::uint32_t(random());
      const std::uint32_t first = round % 4 == 0 ? 0u : std::uint32_t(random() % count);
      std::vector<Vec2d> points(count - first);
      rt::cmj_samples(first, points, count, pattern);
      for (std::uint32_t k = 0; k < points.size(); ++k) {
        const Vec2d u = rt::cmj_sample(first + k, count, pattern);
        CHECK(std::memcmp(&u, &points[k], sizeof u) == 0);
        ++compared;
      }
    }
  }
  CHECK(compared > 10000);
}

// The samples the area-light shader draws (EmitterSampler::sample_many, its warp in SIMD lanes)
// are sample()'s bit for bit: by solid angle, by area and automatic, on a quad and on a sphere of
// many triangles (views past the cache, backs turned to the point), from points near and far, on
// the lamp's plane and behind it, in chunks of every size.
TEST_CASE("EmitterSampler::sample_many: sample's bits in every lane, whatever the strategy and the chunk") {
  const auto same = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  std::mt19937 random(2024);
  const auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(random); };
  rt::Scene quad = floor_and_emitter({Vec3f(-1, -1, 1), Vec3f(-1, 1, 1), Vec3f(1, 1, 1), Vec3f(1, -1, 1)}, Vec3d(2.0),
                                     diffuse_material(Vec3d(0.5)));
  rt::Scene ball = floor_and_emitter({Vec3f(0, 0, 5), Vec3f(0.1f, 0, 5), Vec3f(0, 0.1f, 5)}, Vec3d(3.0),
                                     diffuse_material(Vec3d(0.5)));
  ball.nodes[0].models.pop_back();
  rt::Node lamp;
  lamp.parent_from_node = glm::translate(rt::Mat4d(1.0), Vec3d(0.2, -0.1, 1.0));
  lamp.models.push_back({std::make_shared<const rt::TriangleMesh>(rt::make_sphere_mesh(0.3, 12, 6)), 1});
  ball.nodes.push_back(lamp);
  ball.nodes[0].children.push_back(1);
  // An octagon: six triangles of unequal power, past the four cached views, with the lanes' choice.
  std::vector<Vec3f> octagon;
  for (int i = 0; i < 8; ++i)
    octagon.emplace_back(std::cos(i * 0.785f) * (1.0f + 0.1f * float(i)), std::sin(i * 0.785f), 1.0f);
  rt::Scene fan = floor_and_emitter(octagon, Vec3d(2.0), diffuse_material(Vec3d(0.5)));
  // One, three and four triangles: the lanes read each triangle's inputs from its slot, as for the quad.
  std::vector<rt::Scene> fans;
  for (std::size_t corners : {3, 5, 6})
    fans.push_back(floor_and_emitter({octagon.begin(), octagon.begin() + std::ptrdiff_t(corners)}, Vec3d(2.0),
                                     diffuse_material(Vec3d(0.5))));
  int compared = 0, invalid = 0, unlit = 0;
  for (const rt::Scene* scene : {&quad, &ball, &fan, &fans[0], &fans[1], &fans[2]}) {
    const rt::FlatScene flat = rt::flatten_scene(*scene);
    const rt::AreaLights lights = rt::collect_area_lights(*scene, flat);
    REQUIRE(lights.emitters.size() == 1);
    for (rt::LightSampling sampling : {rt::LightSampling::automatic, rt::LightSampling::area, rt::LightSampling::solid_angle}) {
      for (int round = 0; round < 60; ++round) {
        const double scale = round % 3 == 0 ? 0.05 : round % 3 == 1 ? 1.0 : 100.0;
        Vec3d point(uniform(-scale, scale), uniform(-scale, scale), 1.0 + uniform(-scale, scale));
        if (round % 10 == 7) point.z = 1.0;  // on the quad's plane
        const std::uint32_t count = 1 + std::uint32_t(random() % 40);
        std::vector<Vec2d> u(count);
        rt::cmj_samples(0, u, count, std::uint32_t(random()));
        rt::EmitterSampler many(lights.emitters[0], flat, *scene, nullptr, point, sampling);
        rt::EmitterSampler one(lights.emitters[0], flat, *scene, nullptr, point, sampling);
        std::vector<rt::LightSample> drawn(count);
        const std::size_t chunk = 1 + std::size_t(round % 19);
        for (std::size_t first = 0; first < count; first += chunk) {
          const std::size_t n = std::min<std::size_t>(chunk, count - first);
          many.sample_many(std::span(u).subspan(first, n), std::span(drawn).subspan(first, n));
        }
        for (std::uint32_t k = 0; k < count; ++k) {
          const rt::LightSample expected = one.sample(u[k]);
          const rt::LightSample& got = drawn[k];
          REQUIRE(got.valid == expected.valid);
          ++compared;
          if (!expected.valid) {
            ++invalid;
            continue;
          }
          unlit += expected.radiance_over_pdf == Vec3d(0.0);
          CHECK(same(got.direction, expected.direction));
          CHECK(same(got.distance, expected.distance));
          CHECK(same(got.radiance_over_pdf, expected.radiance_over_pdf));
          CHECK(same(got.light_point.point, expected.light_point.point));
          CHECK(same(got.light_point.geometric_normal, expected.light_point.geometric_normal));
          CHECK(same(got.light_point.error_bound, expected.light_point.error_bound));
          CHECK(got.texcoord.has_value() == expected.texcoord.has_value());
        }
      }
    }
  }
  CHECK(compared > 5000);
  CHECK(invalid > 0);  // points on the quad's plane
  CHECK(unlit > 0);    // the sphere's far side
}

// The builds of sample_many's lanes (render/light_sample_lanes.h: baseline SSE2, AVX2 and
// AVX-512, whichever this CPU runs) on the same random lanes give the same bits, for every count of
// lanes (the AVX-512 build takes 16, 8 and 4 at a time); the test above ties the CPU's build to
// sample().
TEST_CASE("light sample lanes: the AVX2 and AVX-512 builds compute the baseline build's bits") {
  namespace lanes = rt::light_sample_lanes;
  const std::vector<const lanes::Kernels*> wider = lanes::wider_kernels();
  if (wider.empty()) {
    SUCCEED("this CPU has no AVX2: only the baseline build runs here");
    return;
  }
  std::mt19937_64 random(77);
  const auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(random); };
  const auto fill = [&](lanes::Vec3& v, double scale) {
    for (int i = 0; i < lanes::kLanes; ++i) {
      v.x.v[i] = uniform(-scale, scale);
      v.y.v[i] = uniform(-scale, scale);
      v.z.v[i] = uniform(-scale, scale);
    }
  };
  for (int round = 0; round < 200; ++round) {
    const double scale = round % 3 == 0 ? 1e4 : round % 3 == 1 ? 1e-3 : 1.0;
    lanes::Input in;
    for (double& x : in.point) x = uniform(-scale, scale);
    for (lanes::Vec3* v : {&in.a, &in.b, &in.c_perp}) fill(*v, 1.0);
    for (lanes::Vec3* v : {&in.p0, &in.p1, &in.p2}) fill(*v, scale);
    for (int i = 0; i < lanes::kLanes; ++i) {
      const double angle = uniform(-4.0, 4.0), alpha = uniform(0.0, 3.0);
      in.angle.v[i] = angle;
      in.sin_alpha.v[i] = std::sin(alpha);
      in.cos_alpha.v[i] = std::cos(alpha);
      in.cos_c.v[i] = uniform(-1.0, 1.0);
      in.v.v[i] = uniform(0.0, 1.0);
      in.b1.v[i] = uniform(0.0, 0.5);
      in.b2.v[i] = uniform(0.0, 0.5);
      in.edge_term.v[i] = uniform(0.0, scale);
      in.by_solid_angle[i] = random() % 4 ? -1 : 0;
      const Vec3d normal = glm::normalize(Vec3d(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0)));
      in.normal.x.v[i] = normal.x;
      in.normal.y.v[i] = normal.y;
      in.normal.z.v[i] = normal.z;
      in.area.v[i] = uniform(0.0, scale * scale);
      in.probability.v[i] = uniform(0.01, 1.0);
    }
    fill(in.solid_radiance, 10.0);
    for (double& e : in.emission) e = uniform(0.0, 10.0);
    in.sin_alpha.v[2] = 0.0;  // a zero denominator: q = 1
    // Every other round, the per-triangle inputs from 1 to 4 slots.
    in.slots = round % 2 ? 1 + round / 2 % lanes::Input::kSlots : 0;
    for (double& slot : in.slot.v) slot = in.slots ? double(random() % std::uint64_t(in.slots)) : 0.0;
    const int count = 1 + round % lanes::kLanes;
    if (in.slots > 0) {  // the choices and warp inputs of Kernels::choose, from a random cdf
      double cdf = 0.0;
      for (int s = 0; s < in.slots; ++s) {
        in.low.v[s] = cdf;
        in.high.v[s] = cdf = s + 1 == in.slots ? 1.0 : cdf + uniform(0.0, 1.0 - cdf);
        in.solid_area.v[s] = uniform(0.0, 6.0);
        in.alpha.v[s] = uniform(0.0, 3.0);
      }
      for (int i = 0; i < lanes::kLanes; ++i) {
        in.ux.v[i] = uniform(0.0, 1.0);
        in.uy.v[i] = i % 5 == 0 ? in.high.v[std::size_t(i) % std::size_t(in.slots)] : uniform(0.0, 1.0);  // ends too
      }
      const int padded = (count + 3) / 4 * 4;
      lanes::Input chosen_a = in;
      std::uint32_t triangle_a[lanes::kLanes];
      lanes::baseline_kernels().choose(chosen_a, padded, triangle_a);
      for (const lanes::Kernels* build : wider) {
        lanes::Input chosen_b = in;
        std::uint32_t triangle_b[lanes::kLanes];
        build->choose(chosen_b, padded, triangle_b);
        for (int i = 0; i < padded; ++i) {
          CHECK(triangle_a[i] == triangle_b[i]);
          CHECK(triangle_a[i] < std::uint32_t(in.slots));
          CHECK(chosen_a.slot.v[i] == double(triangle_a[i]));
          CHECK(std::memcmp(&chosen_a.v.v[i], &chosen_b.v.v[i], 8) == 0);
          CHECK(std::memcmp(&chosen_a.angle.v[i], &chosen_b.angle.v[i], 8) == 0);
          CHECK(chosen_a.by_solid_angle[i] == -1);
        }
      }
    }
    lanes::Output a;
    lanes::baseline_kernels().sample(in, count, a);
    for (const lanes::Kernels* build : wider) {
      lanes::Output b;
      build->sample(in, count, b);
      for (int i = 0; i < count; ++i) {
        CHECK(a.valid[i] == b.valid[i]);
        if (!a.valid[i]) continue;
        CHECK(a.front[i] == b.front[i]);
        for (const auto& [x, y] : {std::pair{&a.point, &b.point}, std::pair{&a.direction, &b.direction},
                                   std::pair{&a.normal, &b.normal}, std::pair{&a.radiance_over_pdf, &b.radiance_over_pdf}})
          CHECK((std::memcmp(&x->x.v[i], &y->x.v[i], 8) == 0 && std::memcmp(&x->y.v[i], &y->y.v[i], 8) == 0 &&
                 std::memcmp(&x->z.v[i], &y->z.v[i], 8) == 0));
        for (const auto& [x, y] : {std::pair{&a.b1, &b.b1}, std::pair{&a.b2, &b.b2}, std::pair{&a.error_bound, &b.error_bound},
                                   std::pair{&a.distance, &b.distance}})
          CHECK(std::memcmp(&x->v[i], &y->v[i], 8) == 0);
      }
    }
  }
}

// The lanes' sincos (render/lane_libm.h, which Arvo's warp uses in place of std::sin and std::cos)
// is within 1 ulp of glibc's over the warp's angles and beyond, and within 1e-24 absolute where
// the result is near zero (glibc's own error there is relative to the tiny result; ours to the
// argument's rounding). docs/performance.md shows what this does to images: nothing at 8 bits.
TEST_CASE("lane sincos: within 1 ulp of glibc's sin and cos") {
  namespace lm = rt::lane_math;
  const auto ulps = [](double ours, double reference) {
    if (std::isnan(reference)) return std::isnan(ours) ? 0.0 : 1e300;
    return std::abs(ours - reference) / (std::nextafter(std::abs(reference), 1e300) - std::abs(reference));
  };
  std::mt19937_64 random(2026);
  std::vector<double> angles{0.0, -0.0, 1e-300, -1e-20, 0.5, std::numbers::pi, -std::numbers::pi, 2.0 * std::numbers::pi,
                             std::numbers::pi / 2.0, 3.0 * std::numbers::pi / 2.0, 1e5, -7.5e5, std::nan("")};
  std::uniform_real_distribution<double> warp(-7.0, 7.0);
  while (angles.size() < 400000) angles.push_back(warp(random));
  while (angles.size() % 4) angles.push_back(1.0);
  double worst = 0.0, worst_absolute = 0.0;
  for (std::size_t i = 0; i < angles.size(); i += 4) {
    lm::D4 x, s, c;
    lm::load(x, &angles[i]);
    lm::sincos(x, s, c);
    double sines[4], cosines[4];
    lm::store(sines, s);
    lm::store(cosines, c);
    for (int k = 0; k < 4; ++k) {
      const double angle = angles[i + std::size_t(k)];
      for (const auto& [ours, reference] : {std::pair{sines[k], std::sin(angle)}, std::pair{cosines[k], std::cos(angle)}}) {
        if (std::abs(reference) < 1e-9) {
          worst_absolute = std::max(worst_absolute, std::abs(ours - reference));
          continue;
        }
        worst = std::max(worst, ulps(ours, reference));
        INFO("angle " << angle << ": " << ours << " against glibc's " << reference);
        REQUIRE(ulps(ours, reference) <= 1.0);
      }
    }
  }
  CHECK(worst > 0.0);  // the comparison saw a difference: it is not comparing glibc with itself
  CHECK(worst_absolute <= 1e-24);
}

// The lanes' pow (render/lane_libm.h, the area-light highlights' max(n.h, 0)^sigma): for a whole
// exponent n up to kMaxIntegerPower, binary powering, within (n - 1) 2^-53 relative of the exact
// power (so within n + 1 units of 2^-53 of glibc's, itself within 1 ulp), less than 2^-1022 off
// where the result underflows; for any other exponent within 1 ulp of glibc's where the result is
// normal, within one subnormal step below that, and equal to glibc's on the special cases it
// answers itself or hands to glibc. Both builds of the kernel (SSE2, AVX2) give the same bits.
TEST_CASE("lane pow: whole n within (n - 1) 2^-53 relative, others within 1 ulp of glibc's, same bits in every build") {
  namespace lanes = rt::light_sample_lanes;
  std::mt19937_64 random(2027);
  const auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(random); };
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  // Per chunk of 16: one exponent; the bases n.h in (0, 1], near 1, near 0, and special values.
  const std::vector<double> special_bases{0.0, -0.0, 1.0, 1.0 + 0x1p-52, 0x1p-1022, 0x1p-1060, -0.5, nan, inf, 1.5, 2.0, 1e-300};
  const std::vector<double> special_exponents{0.0, 1.0, 2.0, 0.5, 1e-9, 1e5, 1e40, -3.0, nan, inf, 4096.0, 1024.5,
                                              1024.0, 1023.0, 40.0};
  double worst = 0.0, worst_whole = 0.0;
  int chunks_with_fallback = 0, whole_chunks = 0;
  for (int chunk = 0; chunk < 25000; ++chunk) {
    double y = chunk % 3 == 0 ? std::floor(uniform(0.0, 300.0)) : chunk % 3 == 1 ? std::floor(uniform(300.0, 1025.0))
                                                                                  : uniform(0.0, 300.0);
    if (chunk < int(special_exponents.size())) y = special_exponents[std::size_t(chunk)];
    const bool whole = y >= 0.0 && y <= 1024.0 && y == std::floor(y);
    whole_chunks += whole;
    std::array<double, lanes::kLanes> x, a, b;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double u = uniform(0.0, 1.0);
      x[i] = i % 4 == 0 ? 1.0 - 1e-4 * u : i % 4 == 1 ? 1e-3 * u : u;
    }
    if (chunk % 50 == 0 && !whole) {  // binary powering is not meant for bases outside [0, 1]
      std::copy_n(special_bases.begin(), special_bases.size(), x.begin());
      ++chunks_with_fallback;
    }
    lanes::baseline_kernels().powers(x.data(), y, a.data());
    for (const lanes::Kernels* build : lanes::wider_kernels()) {
      build->powers(x.data(), y, b.data());
      REQUIRE(std::memcmp(a.data(), b.data(), sizeof a) == 0);
    }
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double reference = std::pow(x[i], y);
      INFO("pow(" << x[i] << ", " << y << "): " << a[i] << " against glibc's " << reference);
      if (whole) {
        if (y == 0.0 || x[i] == 0.0 || x[i] == 1.0) {
          REQUIRE(a[i] == reference);
        } else if (reference < 0x1p-1000) {
          REQUIRE(std::abs(a[i] - reference) <= 0x1p-1022);
        } else {
          const double relative = std::abs(a[i] - reference) / reference;
          worst_whole = std::max(worst_whole, relative / (y * 0x1p-53));
          REQUIRE(relative <= (y + 1.0) * 0x1p-53);
        }
      } else if (std::isnan(reference) || std::isinf(reference) || reference == 0.0 || x[i] <= 0.0 || y == 0.0 ||
                 x[i] == 1.0) {
        REQUIRE(std::memcmp(&a[i], &reference, 8) == 0);  // special cases: glibc's bits
      } else if (reference < 0x1p-1022) {
        REQUIRE(std::abs(a[i] - reference) <= 0x1p-1074);
      } else {
        const double ulp = std::nextafter(reference, inf) - reference;
        worst = std::max(worst, std::abs(a[i] - reference) / ulp);
        REQUIRE(std::abs(a[i] - reference) <= ulp);
      }
    }
  }
  CHECK(worst > 0.0);  // the comparisons saw differences: they are not comparing glibc with itself
  CHECK(worst_whole > 0.0);
  CHECK(chunks_with_fallback > 0);
  CHECK(whole_chunks > 10000);
}

// The lanes' atan2 for y >= 0 (render/lane_libm.h, SphericalTriangle's interior angles) is within
// 1 ulp of glibc's, and gives glibc's bits on the special cases it answers itself or hands to
// glibc.
TEST_CASE("lane atan2: within 1 ulp of glibc's atan2 for y >= 0") {
  namespace lm = rt::lane_math;
  std::mt19937_64 random(2028);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<std::pair<double, double>> cases{
      {0.0, 1.0},    {0.0, -1.0}, {0.0, 0.0},          {0.0, -0.0},     {1.0, 0.0},       {1.0, -0.0},
      {1e-310, 1.0}, {inf, 1.0},  {1.0, inf},          {-1.0, 1.0},     {-0.0, -1.0},     {std::nan(""), 1.0},
      {1e200, 1e-200}, {1e-200, -1e200}, {1e-200, 1e200}, {1.0, 1e-310}};
  while (cases.size() < 400000) {
    // |u x v| and u . v of unit vectors, as SphericalTriangle passes them, and smaller ratios.
    const double c = unit(random), scale = cases.size() % 3 == 0 ? 1e-6 : 1.0;
    cases.emplace_back(std::sqrt(std::max(0.0, 1.0 - c * c)) * scale, c);
  }
  double worst = 0.0;
  for (std::size_t i = 0; i < cases.size(); i += 4) {
    double ys[4], xs[4], angles[4];
    for (std::size_t k = 0; k < 4; ++k) std::tie(ys[k], xs[k]) = cases[std::min(i + k, cases.size() - 1)];
    lm::D4 y, x;
    lm::load(y, ys);
    lm::load(x, xs);
    lm::store(angles, lm::atan2(y, x));
    for (std::size_t k = 0; k < 4; ++k) {
      const double reference = std::atan2(ys[k], xs[k]);
      INFO("atan2(" << ys[k] << ", " << xs[k] << "): " << angles[k] << " against glibc's " << reference);
      if (std::isnan(reference) || reference == 0.0 || !(ys[k] > 0.0) || xs[k] == 0.0 || std::isinf(ys[k]) ||
          std::isinf(xs[k])) {
        REQUIRE(std::memcmp(&angles[k], &reference, 8) == 0);  // special cases: glibc's bits
        continue;
      }
      const double ulp = std::nextafter(reference, inf) - reference;
      worst = std::max(worst, std::abs(angles[k] - reference) / ulp);
      REQUIRE(std::abs(angles[k] - reference) <= ulp);
    }
  }
  CHECK(worst > 0.0);  // the comparison saw a difference: it is not comparing glibc with itself
}

// SphericalTriangle::set_up_many's lanes give the constructor's bits (which takes the same path
// with one triangle), for one to six triangles, degenerate ones included, seen from one point or
// each from its own; and every build agrees.
TEST_CASE("SphericalTriangle::set_up_many: the constructor's bits in every lane, in every build") {
  namespace lanes = rt::light_sample_lanes;
  std::mt19937_64 random(2029);
  std::uniform_real_distribution<double> coordinate(-2.0, 2.0);
  const auto point = [&] { return Vec3d(coordinate(random), coordinate(random), coordinate(random)); };
  const auto same = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  int valid = 0, invalid = 0;
  for (int round = 0; round < 2000; ++round) {
    const Vec3d p = point();
    const std::size_t count = 1 + std::size_t(round % 6);  // past four: two groups of lanes
    std::vector<std::array<Vec3d, 3>> corners(count);
    for (auto& t : corners) t = {point(), point(), point()};
    if (round % 7 == 0) corners[0][1] = p;                          // a vertex at the point
    if (round % 11 == 0) corners[count - 1][2] = corners[count - 1][1];  // a side of zero length
    std::vector<rt::SphericalTriangle> many(count);
    rt::SphericalTriangle::set_up_many(p, corners, many);
    for (std::size_t i = 0; i < count; ++i) {
      const rt::SphericalTriangle one(p, corners[i][0], corners[i][1], corners[i][2]);
      REQUIRE(same(one, many[i]));
      (one.valid() ? valid : invalid) += 1;
    }
    // Each triangle from its own point (every other one from p, whose lanes must not change).
    std::vector<Vec3d> points(count);
    for (std::size_t i = 0; i < count; ++i) points[i] = i % 2 == 0 ? p : point();
    if (round % 13 == 0) points[count - 1] = corners[count - 1][0];  // at a vertex
    std::vector<rt::SphericalTriangle> each(count);
    rt::SphericalTriangle::set_up_many(points, corners, each);
    for (std::size_t i = 0; i < count; ++i) {
      const rt::SphericalTriangle one(points[i], corners[i][0], corners[i][1], corners[i][2]);
      REQUIRE(same(one, each[i]));
      if (points[i] == p) REQUIRE(same(each[i], many[i]));
    }
    // The builds of the kernel on the same lanes.
    for (const lanes::Kernels* build : lanes::wider_kernels()) {
      lanes::SphericalInput in;
      for (std::size_t i = 0; i < 4; ++i) {
        const std::size_t k = std::min(i, count - 1);
        const std::array<Vec3d, 3>& t = corners[k];
        const Vec3d& p_k = points[k];
        for (auto [to, from] : {std::pair{&in.point, &p_k}, std::pair{&in.a, &t[0]}, std::pair{&in.b, &t[1]},
                                std::pair{&in.c, &t[2]}}) {
          to->x.v[i] = from->x;
          to->y.v[i] = from->y;
          to->z.v[i] = from->z;
        }
      }
      lanes::SphericalOutput a, b;
      lanes::baseline_kernels().spherical(in, a);
      build->spherical(in, b);
      for (const auto& [x, y] : {std::pair{&a.a, &b.a}, std::pair{&a.b, &b.b}, std::pair{&a.c_perp, &b.c_perp}}) {
        REQUIRE(same(x->x.v, y->x.v));  // the lanes only: LaneArray's alignment pads it
        REQUIRE(same(x->y.v, y->y.v));
        REQUIRE(same(x->z.v, y->z.v));
      }
      for (const auto& [x, y] : {std::pair{&a.alpha, &b.alpha}, std::pair{&a.cos_alpha, &b.cos_alpha},
                                 std::pair{&a.sin_alpha, &b.sin_alpha}, std::pair{&a.cos_c, &b.cos_c},
                                 std::pair{&a.area, &b.area}})
        REQUIRE(same(x->v, y->v));
    }
  }
  CHECK(valid > 1000);
  CHECK(invalid > 100);
}

// The facing kernel (n.l and the highlight of a chunk of samples, shade.cpp's area-light terms)
// gives the scalar formulas' bits, the highlight being the lanes' pow of the scalar n.h, in both
// builds, in the chunk's lanes in use; invalid lanes and lanes facing away get a power of 1.
TEST_CASE("light sample lanes: facing gives the scalar n.l and the pow of the scalar n.h") {
  namespace lanes = rt::light_sample_lanes;
  std::mt19937_64 random(2030);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  const auto unit = [&] { return glm::normalize(Vec3d(coordinate(random), coordinate(random), coordinate(random))); };
  int highlighted = 0;
  lanes::Chunk chunk;
  for (int round = 0; round < 3000; ++round) {
    lanes::Shading shading;
    const Vec3d normal = unit(), to_eye = round % 5 == 0 ? -normal : unit();  // half vector zero at times
    for (int axis = 0; axis < 3; ++axis) {
      shading.normal[axis] = normal[axis];
      shading.to_eye[axis] = to_eye[axis];
    }
    shading.shininess = round % 4 == 0 ? 0.0 : std::floor(coordinate(random) * 100.0 + 101.0);
    shading.highlights = round % 9 != 0;
    chunk.count = round % 3 == 0 ? 1 + int(random() % lanes::kLanes) : lanes::kLanes;
    std::array<Vec3d, lanes::kLanes> directions;
    for (int i = 0; i < lanes::kLanes; ++i) {
      directions[std::size_t(i)] = i % 7 == 3 ? -to_eye : unit();
      chunk.out.direction.x.v[i] = directions[std::size_t(i)].x;
      chunk.out.direction.y.v[i] = directions[std::size_t(i)].y;
      chunk.out.direction.z.v[i] = directions[std::size_t(i)].z;
      chunk.out.valid[i] = random() % 5 ? -1 : 0;
    }
    const auto used = std::size_t(chunk.count);
    std::array<double, lanes::kLanes> expected_n_dot_l, n_dot_h, expected_power;
    for (std::size_t i = 0; i < directions.size(); ++i) {
      expected_n_dot_l[i] = glm::dot(normal, directions[i]);
      const Vec3d half_sum = directions[i] + to_eye;
      const double half_length = glm::length(half_sum);
      n_dot_h[i] = i < used && chunk.out.valid[i] && expected_n_dot_l[i] > 0.0
                       ? (half_length > 0.0 ? std::max(glm::dot(normal, half_sum) / half_length, 0.0) : 0.0)
                       : 1.0;
    }
    lanes::baseline_kernels().powers(n_dot_h.data(), shading.shininess, expected_power.data());
    if (!shading.highlights) expected_power.fill(1.0);
    for (const lanes::Kernels* kernels : every_lanes_build()) {
      lanes::FacingOutput out;
      kernels->facing(shading, chunk, out);
      REQUIRE(std::memcmp(out.n_dot_l.v, expected_n_dot_l.data(), used * sizeof(double)) == 0);
      REQUIRE(std::memcmp(out.power.v, expected_power.data(), used * sizeof(double)) == 0);
    }
    for (std::size_t i = 0; i < used; ++i) highlighted += expected_power[i] != 1.0;
  }
  CHECK(highlighted > 10000);
}

// The emit kernel gives shade.cpp's scalar term, radiance (C_d n.l + C_s power) / (pi N), and
// shadow_ray_to_sample's ray from offset_ray_origin's origin (set_origins' for either side of the
// surface), bit for bit, in every build, with
// robust and fixed offsets, light points on either side and samples at the shading point.
TEST_CASE("light sample lanes: emit gives the scalar terms and shadow_ray_to_sample's rays") {
  namespace lanes = rt::light_sample_lanes;
  std::mt19937_64 random(2031);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0), positive(0.0, 2.0);
  const auto unit = [&] { return glm::normalize(Vec3d(coordinate(random), coordinate(random), coordinate(random))); };
  const auto random_vec = [&] { return Vec3d(positive(random), positive(random), positive(random)); };
  const auto get = [](const auto& lanes3, int i) { return Vec3d(lanes3.x.v[i], lanes3.y.v[i], lanes3.z.v[i]); };
  const auto same = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  int traced = 0, at_point = 0, lit_terms = 0;
  lanes::Chunk chunk;
  for (int round = 0; round < 2000; ++round) {
    const rt::RayOffset policy =
        round % 2 ? rt::RayOffset{} : rt::RayOffset{rt::RayOffset::Mode::fixed, round % 4 ? 1e-4 : 0.5};
    const double scale = std::pow(10.0, 2.0 * coordinate(random));
    rt::SurfacePoint surface;
    surface.point = scale * Vec3d(coordinate(random), coordinate(random), coordinate(random));
    surface.geometric_normal = unit();
    surface.error_bound = 1e-6 * scale * positive(random);
    const Vec3d diffuse = random_vec(), specular = random_vec();
    lanes::Shading shading;
    for (int axis = 0; axis < 3; ++axis) {
      shading.point[axis] = surface.point[axis];
      shading.geometric_normal[axis] = surface.geometric_normal[axis];
      shading.diffuse[axis] = diffuse[axis];
      shading.specular[axis] = specular[axis];
    }
    shading.error_bound = surface.error_bound;
    shading.scale = 1.0 / (std::numbers::pi * double(1 + random() % 64));
    shading.highlights = round % 3 != 0;
    shading.fixed_offset = policy.mode == rt::RayOffset::Mode::fixed;
    shading.epsilon = policy.epsilon;
    const bool lit = round % 7 != 0;
    chunk.count = round % 3 == 0 ? 1 + int(random() % lanes::kLanes) : lanes::kLanes;
    lanes::FacingOutput facing;
    std::array<rt::LightSample, lanes::kLanes> samples;
    for (int i = 0; i < lanes::kLanes; ++i) {
      rt::LightSample& sample = samples[std::size_t(i)];
      sample.light_point.point = i % 11 == 5 ? surface.point : surface.point + scale * positive(random) * unit();
      sample.light_point.geometric_normal = unit();
      sample.light_point.error_bound = 1e-6 * scale * positive(random);
      const Vec3d offset = sample.light_point.point - surface.point;
      sample.direction = glm::length(offset) > 0.0 ? glm::normalize(offset) : unit();
      sample.radiance_over_pdf = random_vec();
      const auto set = [i](lanes::Vec3& to, const Vec3d& v) {
        to.x.v[i] = v.x;
        to.y.v[i] = v.y;
        to.z.v[i] = v.z;
      };
      set(chunk.out.point, sample.light_point.point);
      set(chunk.out.normal, sample.light_point.geometric_normal);
      chunk.out.error_bound.v[i] = sample.light_point.error_bound;
      set(chunk.out.direction, sample.direction);
      set(chunk.out.radiance_over_pdf, sample.radiance_over_pdf);
      facing.n_dot_l.v[i] = coordinate(random);
      facing.power.v[i] = positive(random);
    }
    for (const lanes::Kernels* kernels : every_lanes_build()) {
      kernels->set_origins(shading);
      for (int side = 0; side < 2; ++side) {
        const Vec3f expected = rt::offset_ray_origin(policy, surface, side == 0 ? surface.geometric_normal : -surface.geometric_normal);
        REQUIRE(same(Vec3f(shading.origin[side][0], shading.origin[side][1], shading.origin[side][2]), expected));
      }
      lanes::EmitOutput out;
      kernels->emit(shading, chunk, facing, lit, out);
      for (int i = 0; i < chunk.count; ++i) {
        const rt::LightSample& sample = samples[std::size_t(i)];
        const double n_dot_l = facing.n_dot_l.v[i];
        Vec3d term(0.0);
        if (lit && n_dot_l > 0.0) {
          const Vec3d highlight = shading.highlights ? specular * facing.power.v[i] : Vec3d(0.0);
          term = sample.radiance_over_pdf * (diffuse * n_dot_l + highlight) * shading.scale;
        }
        REQUIRE(same(get(out.term, i), term));
        const rt::Ray ray =
            rt::shadow_ray_to_sample(policy, rt::offset_ray_origin(policy, surface, sample.direction), sample);
        REQUIRE(same(Vec3f(out.origin.x[i], out.origin.y[i], out.origin.z[i]), ray.origin));
        REQUIRE(same(out.tfar[i], ray.tfar));
        if (ray.tfar > 0.0f) REQUIRE(same(Vec3f(out.direction.x[i], out.direction.y[i], out.direction.z[i]), ray.direction));
        traced += ray.tfar > 0.0f;
        at_point += ray.tfar <= 0.0f;
        lit_terms += term != Vec3d(0.0);
      }
    }
  }
  CHECK(traced > 20000);
  CHECK(at_point > 100);
  CHECK(lit_terms > 10000);
}

TEST_CASE("sample_triangle_uniform: barycentrics on the triangle, uniform (mean at the centroid)") {
  constexpr int n = 256;
  Vec3d mean(0.0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Vec3d b = rt::sample_triangle_uniform({(i + 0.5) / n, (j + 0.5) / n});
      REQUIRE(std::min({b.x, b.y, b.z}) >= -1e-15);
      REQUIRE(b.x + b.y + b.z == Approx(1.0).margin(1e-15));
      mean += b / double(n * n);
    }
  CHECK(mean.x == Approx(1.0 / 3.0).margin(1e-4));
  CHECK(mean.y == Approx(1.0 / 3.0).margin(1e-4));
}

TEST_CASE("SphericalTriangle: Girard's area is Van Oosterom's solid angle, samples hit the triangle, uniformly") {
  struct Case {
    Vec3d p, a, b, c;
  };
  const std::vector<Case> cases{
      {Vec3d(0.0), Vec3d(1, 0, 1), Vec3d(0, 1, 1), Vec3d(-1, -1, 1)},         // large, around the axis
      {Vec3d(0.1, 0.2, 0.0), Vec3d(-0.5, -0.5, 0.2), Vec3d(0.5, -0.5, 0.2), Vec3d(0, 0.5, 0.2)},  // close
      {Vec3d(0.0), Vec3d(10, 0, 3), Vec3d(10.1, 0, 3), Vec3d(10, 0.1, 3.05)},  // small and oblique
  };
  for (const Case& c : cases) {
    const rt::SphericalTriangle spherical(c.p, c.a, c.b, c.c);
    REQUIRE(spherical.valid());
    CHECK(spherical.solid_angle() == Approx(rt::triangle_solid_angle(c.p, c.a, c.b, c.c)).epsilon(1e-9));
    // Uniform in solid angle: the mean of n.w over the samples times the solid angle is the
    // cosine-weighted solid angle, which Lambert's formula gives exactly.
    const Vec3d normal = glm::normalize(glm::cross(c.b - c.a, c.c - c.a));
    const Vec3d up = glm::dot(normal, c.a - c.p) > 0.0 ? normal : -normal;  // towards the triangle
    constexpr int n = 128;
    double sum = 0.0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const Vec3d w = spherical.sample({(i + 0.5) / n, (j + 0.5) / n});
        const auto b = rt::barycentrics_along(c.p, w, c.a, c.b, c.c);
        REQUIRE(b);
        const Vec3d hit = b->x * c.a + b->y * c.b + b->z * c.c;
        CHECK(glm::dot(glm::normalize(hit - c.p), w) > 1.0 - 1e-9);  // w really points at the triangle
        sum += glm::dot(up, w);
      }
    const double estimate = spherical.solid_angle() * sum / (n * n);
    CHECK(estimate == Approx(lambert_cosine_solid_angle(c.p, up, {c.a, c.b, c.c})).epsilon(1e-3));
  }
  CHECK_FALSE(rt::SphericalTriangle(Vec3d(0.5, 0.0, 0.0), Vec3d(0.0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)).valid());
}

TEST_CASE("an emissive quad lights a diffuse floor with C_d / pi * L_e * Lambert's cosine-weighted solid angle") {
  // A 0.6 x 0.4 quad at height 0.5 facing down, radiance (2, 1, 0.5); the floor point is off to
  // one side so the emitter is seen obliquely.
  const std::vector<Vec3f> quad{Vec3f(-0.3f, -0.2f, 0.5f), Vec3f(-0.3f, 0.2f, 0.5f), Vec3f(0.3f, 0.2f, 0.5f),
                                Vec3f(0.3f, -0.2f, 0.5f)};
  const Vec3d radiance(2.0, 1.0, 0.5), albedo(0.8, 0.6, 0.4);
  const Shader shader(floor_and_emitter(quad, radiance, diffuse_material(albedo)));
  const Vec3d point(0.4, 0.1, 0.0);
  std::vector<Vec3d> corners;
  for (const Vec3f& v : quad) corners.emplace_back(v);
  const Vec3d expected = albedo / kPi * radiance * lambert_cosine_solid_angle(point, Vec3d(0, 0, 1), corners);
  for (rt::LightSampling sampling : {rt::LightSampling::area, rt::LightSampling::solid_angle, rt::LightSampling::automatic}) {
    CAPTURE(rt::to_string(sampling));
    rt::EffectsOptions options;
    options.light_samples = 4096;
    options.light_sampling = sampling;
    rt::RayCounts counts;
    const Color c = shader.shade(Vec3f(0.4f, 0.1f, 2.0f), Vec3f(0, 0, -1), options, counts);
    CHECK(c.r == Approx(expected.r).epsilon(2e-3));
    CHECK(c.g == Approx(expected.g).epsilon(2e-3));
    CHECK(c.b == Approx(expected.b).epsilon(2e-3));
    CHECK(counts.area_light == 4096);  // nothing in between, every sample traced
  }
  // Seen from above, the quad shows its back: no emission, and its black material is not lit.
  rt::RayCounts counts;
  rt::EffectsOptions options;
  CHECK(shader.shade(Vec3f(0.0f, 0.0f, 2.0f), Vec3f(0, 0, -1), options, counts) == Color(0.0f));
  CHECK(counts.skipped[int(rt::SkipRule::unlit_material)] == std::uint64_t(options.light_samples));
  // A floor point outside the quad's shadow but below the quad's plane is lit; one above it (on a
  // raised floor) is behind the emitter and gets no sample.
  rt::Scene raised = shader.scene;
  raised.nodes[0].models[0].mesh = std::make_shared<const rt::TriangleMesh>(
      rt_test::make_flat_mesh({{Vec3f(-50, -50, 0.7f), Vec3f(50, -50, 0.7f), Vec3f(0, 50, 0.7f)}}));
  const Shader above_lamp(raised);
  counts = {};
  CHECK(above_lamp.shade(Vec3f(2.0f, 0.0f, 2.0f), Vec3f(0, 0, -1), options, counts) == Color(0.0f));
  CHECK(counts.skipped[int(rt::SkipRule::emitter_behind)] == std::uint64_t(options.light_samples));
  CHECK(counts.area_light == 0);
}

TEST_CASE("a small emitter facing the point shades like the seed's point light of colour L_e A / pi") {
  // A 2e-3-wide square at (0, 0, 1) facing down, over a Blinn-Phong floor; the point light is at its
  // centre with quadratic attenuation, so both give L (C_d n.l + C_s max(n.h, 0)^s) / d^2.
  const float h = 1e-3f;
  const std::vector<Vec3f> square{Vec3f(-h, -h, 1), Vec3f(-h, h, 1), Vec3f(h, h, 1), Vec3f(h, -h, 1)};
  const Vec3d radiance(3e5, 2e5, 1e5);
  const rt::Material floor = diffuse_material(Vec3d(0.5, 0.4, 0.3), Vec3d(0.3), 20.0f);
  const Shader with_emitter(floor_and_emitter(square, radiance, floor));
  rt::Scene point_lit = floor_and_emitter(square, Vec3d(0.0), floor);
  point_lit.materials[1].emits_light = false;
  rt::Light light;
  light.position = rt::Vec4d(0.0, 0.0, 1.0, 1.0);
  light.color = Color(radiance * double(4 * h * h) / kPi);
  light.attenuation = Vec3d(0.0, 0.0, 1.0);
  point_lit.lights = {light};
  const Shader with_point(point_lit);
  rt::EffectsOptions options;
  options.light_samples = 64;
  for (const Vec3f& eye : {Vec3f(0.3f, 0.0f, 1.0f), Vec3f(-0.2f, 0.4f, 0.6f)}) {
    // Shade the floor right below the light (n.l = 1, cos(theta') = 1) from two eyes.
    rt::RayCounts counts;
    const Vec3f direction = Vec3f(0.0f) - eye;
    const Color area = with_emitter.shade(eye, direction, options, counts);
    const Color point = with_point.shade(eye, direction, options, counts);
    CHECK(area.r == Approx(point.r).epsilon(1e-4));
    CHECK(area.g == Approx(point.g).epsilon(1e-4));
    CHECK(area.b == Approx(point.b).epsilon(1e-4));
  }
}

TEST_CASE("area lights: pruning changes no pixel, threads and regions change no pixel, the budget adds up") {
  const std::vector<Vec3f> quad{Vec3f(-0.3f, -0.2f, 0.5f), Vec3f(-0.3f, 0.2f, 0.5f), Vec3f(0.3f, 0.2f, 0.5f),
                                Vec3f(0.3f, -0.2f, 0.5f)};
  rt::Scene scene = floor_and_emitter(quad, Vec3d(4.0), diffuse_material(Vec3d(0.7), Vec3d(0.2), 8.0f));
  // A blocker between the quad and part of the floor, for penumbrae.
  scene.nodes[0].models.push_back(
      {std::make_shared<const rt::TriangleMesh>(rt_test::make_flat_mesh(
           {{Vec3f(-0.1f, -0.1f, 0.25f), Vec3f(0.1f, -0.1f, 0.25f), Vec3f(0.0f, 0.1f, 0.25f)}})),
       0});
  scene.settings.width = 48;
  scene.settings.height = 40;
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
  rt::RenderOptions options;
  options.effects.light_samples = 9;
  const rt::RenderResult pruned = rt::render_image(scene, flat, *accel, options);
  options.effects.prune = false;
  const rt::RenderResult full = rt::render_image(scene, flat, *accel, options);
  CHECK(pruned.image.pixels == full.image.pixels);
  CHECK(full.rays.area_light > pruned.rays.area_light);

  std::uint64_t hits = 0;
  for (std::uint64_t h : pruned.rays.hits_per_depth) hits += h;
  std::uint64_t area_skips = 0;
  for (rt::SkipRule rule : {rt::SkipRule::emitter_off, rt::SkipRule::unlit_material, rt::SkipRule::emitter_behind,
                            rt::SkipRule::emitter_below_horizon, rt::SkipRule::sample_zero,
                            rt::SkipRule::sample_on_surface})
    area_skips += pruned.rays.skipped[int(rule)];
  CHECK(pruned.rays.area_light + area_skips == hits * 9);
  CHECK(pruned.rays.shadow == 0);

  options.effects.prune = true;
  options.threads = 1;
  options.tile_size = 7;
  CHECK(rt::render_image(scene, flat, *accel, options).image.pixels == pruned.image.pixels);
  options.region = rt::PixelRegion{5, 3, 30, 27};
  const rt::RenderResult crop = rt::render_image(scene, flat, *accel, options);
  for (int y = 3; y < 27; ++y)
    for (int x = 5; x < 30; ++x) REQUIRE(crop.image.at(x - 5, y - 3) == pruned.image.at(x, y));
  // The camera blocks' deferred shadow packets sum as find_color does, pixel by pixel.
  options.region.reset();
  const std::vector<std::string> trace = rt::trace_pixel(scene, flat, *accel, options, 20, 25);
  CHECK(std::any_of(trace.begin(), trace.end(), [](const std::string& line) { return line.find("area light 0 sample") != std::string::npos; }));
}

// A whole shininess takes binary powering for the area-light highlights (lane_libm.h), any other
// fdlibm's pow: an image lit through the first differs from one through the second, at the next
// float32 shininess up (40 + 2^-18, which itself moves n.h^40 by about 4e-6 relative), by far less
// than the 8-bit quantum 2^-8, and the same rays are traced.
TEST_CASE("area-light highlights by binary powering move the image by far less than the 8-bit quantum") {
  const std::vector<Vec3f> quad{Vec3f(-0.3f, -0.2f, 0.5f), Vec3f(-0.3f, 0.2f, 0.5f), Vec3f(0.3f, 0.2f, 0.5f),
                                Vec3f(0.3f, -0.2f, 0.5f)};
  const auto render = [&](float shininess, Vec3d specular) {
    rt::Scene scene = floor_and_emitter(quad, Vec3d(4.0), diffuse_material(Vec3d(0.5), specular, shininess));
    scene.settings.width = 64;
    scene.settings.height = 48;
    const rt::FlatScene flat = rt::flatten_scene(scene);
    const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
    rt::RenderOptions options;
    options.effects.light_samples = 16;
    return rt::render_image(scene, flat, *accel, options);
  };
  const rt::RenderResult whole = render(40.0f, Vec3d(0.5));
  const rt::RenderResult other = render(std::nextafter(40.0f, 41.0f), Vec3d(0.5));
  const rt::RenderResult matte = render(40.0f, Vec3d(0.0));
  CHECK(whole.rays.area_light == other.rays.area_light);
  double largest = 0.0, highlight = 0.0;
  for (std::size_t i = 0; i < whole.image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      largest = std::max(largest, std::abs(double(whole.image.pixels[i][c]) - double(other.image.pixels[i][c])));
      highlight = std::max(highlight, double(whole.image.pixels[i][c]) - double(matte.image.pixels[i][c]));
    }
  CHECK(highlight > 0.05);  // the highlights are there to be compared
  INFO("largest difference " << largest);
  CHECK(largest < 0x1p-8 * 1e-3);
}

TEST_CASE("emission is one-sided for emitters and two-sided self-emission otherwise") {
  const std::vector<Vec3f> quad{Vec3f(-1, -1, 1), Vec3f(-1, 1, 1), Vec3f(1, 1, 1), Vec3f(1, -1, 1)};  // faces -z
  const Shader shader(floor_and_emitter(quad, Vec3d(0.25, 0.5, 1.0), diffuse_material(Vec3d(0.0))));
  rt::EffectsOptions options;
  rt::RayCounts counts;
  CHECK(shader.shade(Vec3f(0.1f, 0.1f, 0.5f), Vec3f(0, 0, 1), options, counts) == Color(0.25f, 0.5f, 1.0f));
  CHECK(shader.shade(Vec3f(0.1f, 0.1f, 1.5f), Vec3f(0, 0, -1), options, counts) == Color(0.0f));
  rt::Scene self_emitting = shader.scene;
  self_emitting.materials[1].emits_light = false;  // the seed's emission: seen from both sides, lights nothing
  const Shader seed(self_emitting);
  CHECK(seed.shade(Vec3f(0.1f, 0.1f, 1.5f), Vec3f(0, 0, -1), options, counts) == Color(0.25f, 0.5f, 1.0f));
  CHECK(seed.shade(Vec3f(0.3f, 0.3f, 0.9f), Vec3f(0, 0, -1), options, counts) == Color(0.0f));  // floor unlit
}

TEST_CASE("collect_area_lights: one emitter per emissive material, planar quads, spheres refused") {
  const std::vector<Vec3f> quad{Vec3f(-1, -1, 1), Vec3f(-1, 1, 1), Vec3f(1, 1, 1), Vec3f(1, -1, 1)};
  rt::Scene scene = floor_and_emitter(quad, Vec3d(1.0, 2.0, 3.0), diffuse_material(Vec3d(0.5)));
  const rt::AreaLights lights = rt::collect_area_lights(scene, rt::flatten_scene(scene));
  REQUIRE(lights.emitters.size() == 1);
  const rt::Emitter& e = lights.emitters[0];
  CHECK(e.triangles.size() == 2);
  CHECK(e.area == Approx(4.0));
  CHECK(e.power.b == Approx(kPi * 4.0 * 3.0));
  CHECK(e.planar);
  CHECK(e.plane_normal == Vec3d(0, 0, -1));
  CHECK(e.cdf.back() == 1.0);
  CHECK(rt::in_front_of_emitter(e, Vec3d(0, 0, 0.5)));
  CHECK_FALSE(rt::in_front_of_emitter(e, Vec3d(0, 0, 1.0)));
  CHECK(rt::emitter_below_horizon(e, Vec3d(0, 0, 2), Vec3d(0, 0, 1)));
  CHECK_FALSE(rt::emitter_below_horizon(e, Vec3d(0, 0, 0), Vec3d(0, 0, 1)));

  rt::Node sphere_node;
  sphere_node.models.push_back({nullptr, 1, rt::Sphere{}});
  scene.nodes.push_back(sphere_node);
  scene.nodes[0].children.push_back(1);
  CHECK_THROWS_WITH(rt::collect_area_lights(scene, rt::flatten_scene(scene)),
                    Catch::Matchers::ContainsSubstring("'lamp' emits light and is used by a sphere"));
}

TEST_CASE("OBJ: Ke makes an area light and replaces the headlight, negative Ke is an error naming the line") {
  rt_test::TempDir dir;
  rt_test::write_file(dir.path() / "box.mtl", "newmtl white\nKd 0.8 0.8 0.8\nnewmtl lamp\nKd 0 0 0\nKe 5 4 3\n");
  rt_test::write_file(dir.path() / "box.obj",
                      "mtllib box.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n"
                      "v -0.2 1 -0.2\nv 0.2 1 -0.2\nv 0.2 1 0.2\nv -0.2 1 0.2\n"
                      "usemtl white\nf 1 4 3 2\nusemtl lamp\nf 5 6 7 8\n");
  rt::LoadReport report;
  const rt::Scene scene = rt::load_scene((dir.path() / "box.obj").string(), {}, &report);
  CHECK(scene.lights.empty());
  CHECK_FALSE(report.default_lights_added);
  REQUIRE(scene.materials.size() == 2);
  CHECK(scene.materials[1].emits_light);
  CHECK_FALSE(scene.materials[0].emits_light);
  const rt::AreaLights lights = rt::collect_area_lights(scene, rt::flatten_scene(scene));
  REQUIRE(lights.emitters.size() == 1);
  CHECK(lights.emitters[0].plane_normal.y == Approx(-1.0));  // 5 6 7 8 winds clockwise seen from above

  // An emission texture that cannot be read: a warning, and Ke alone.
  rt_test::write_file(dir.path() / "box.mtl", "newmtl white\nKd 0.8 0.8 0.8\nnewmtl lamp\nKe 5 4 3\nmap_Ke glow.png\n");
  rt::LoadReport glow_report;
  const rt::Scene glow = rt::load_scene((dir.path() / "box.obj").string(), {}, &glow_report);
  CHECK(glow.materials[1].emits_light);
  CHECK(glow.materials[1].emission_texture.empty());
  REQUIRE(glow_report.warnings.size() == 1);
  CHECK_THAT(glow_report.warnings[0], Catch::Matchers::ContainsSubstring("map_Ke 'glow.png'") || Catch::Matchers::ContainsSubstring("glow.png"));
  CHECK_THAT(glow_report.warnings[0], Catch::Matchers::ContainsSubstring("using Ke alone"));

  rt_test::write_file(dir.path() / "box.mtl", "newmtl white\nKd 0.8 0.8 0.8\nnewmtl lamp\nKe 5 -4 3\n");
  CHECK_THROWS_WITH(rt::load_scene((dir.path() / "box.obj").string(), {}, &report),
                    Catch::Matchers::ContainsSubstring("box.mtl:4:") && Catch::Matchers::ContainsSubstring("'Ke': '-4' is negative"));
}

TEST_CASE("native format: the emitter key makes an area light, a non-boolean is an error naming the key") {
  rt_test::TempDir dir;
  const std::string scene_text = R"({
    "camera": {"eye": [0, -3, 3], "target": [0, 0, 0], "fovy": 40},
    "materials": {"floor": {"diffuse": 0.5}, "lamp": {"emission": [4, 4, 4], "emitter": EMITTER}},
    "geometries": {"quad": {"type": "mesh", "positions": [[-1, -1, 1], [-1, 1, 1], [1, 1, 1], [1, -1, 1]],
                            "triangles": [[0, 1, 2], [0, 2, 3]]},
                   "ground": {"type": "mesh", "positions": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]],
                              "triangles": [[0, 1, 2], [0, 2, 3]]}},
    "nodes": [{"models": [{"geometry": "quad", "material": "lamp"}, {"geometry": "ground", "material": "floor"}]}]
  })";
  const auto with = [&](const std::string& value) {
    std::string text = scene_text;
    text.replace(text.find("EMITTER"), 7, value);
    rt_test::write_file(dir.path() / "s.json", text);
    return (dir.path() / "s.json").string();
  };
  const rt::Scene scene = rt::load_scene(with("true"));
  CHECK(scene.materials[1].emits_light);
  CHECK(rt::collect_area_lights(scene, rt::flatten_scene(scene)).emitters.size() == 1);
  CHECK_FALSE(rt::load_scene(with("false")).materials[1].emits_light);
  CHECK_THROWS_WITH(rt::load_scene(with("1")), Catch::Matchers::ContainsSubstring("/materials/lamp/emitter: expected true or false"));
}

TEST_CASE("a lamp of thousands of triangles is sampled by power: a tessellated sphere lights like the sphere") {
  // A Lambertian sphere of radius R and radiance L seen from a point at distance d, wholly above its
  // horizon, gives irradiance pi L (R/d)^2; a diffuse floor of albedo C_d then has radiance
  // C_d L (R/d)^2. The inscribed UV sphere of 64 x 32 subtends about 0.3% less.
  constexpr double radius = 0.2, distance = 1.0;
  rt::Scene scene = floor_and_emitter({Vec3f(0, 0, 5), Vec3f(0.1f, 0, 5), Vec3f(0, 0.1f, 5)}, Vec3d(0.0),
                                      diffuse_material(Vec3d(0.5)));
  scene.materials[1] = emitter_material(Vec3d(3.0, 2.0, 1.0));
  scene.nodes[0].models.pop_back();  // the placeholder emitter
  rt::Node lamp;
  lamp.parent_from_node = glm::translate(rt::Mat4d(1.0), Vec3d(0.0, 0.0, distance));
  lamp.models.push_back({std::make_shared<const rt::TriangleMesh>(rt::make_sphere_mesh(radius, 64, 32)), 1});
  scene.nodes.push_back(lamp);
  scene.nodes[0].children.push_back(1);
  const Shader shader(scene);
  rt::EffectsOptions options;
  options.light_samples = 4096;
  rt::RayCounts counts;
  const Color c = shader.shade(Vec3f(0.3f, 0.0f, 0.5f), Vec3f(-0.3f, 0.0f, -0.5f), options, counts);
  const double expected = 0.5 * (radius / distance) * (radius / distance);
  CHECK(c.r == Approx(expected * 3.0).epsilon(0.006));
  CHECK(c.g == Approx(expected * 2.0).epsilon(0.006));
  CHECK(counts.area_light + counts.skipped[int(rt::SkipRule::sample_zero)] == 4096);  // N samples, not per triangle

  // Its emitter list is sized before it is allocated.
  const rt::FlatScene flat = rt::flatten_scene(scene);
  rt::set_memory_limit(64 * 1024);
  CHECK_THROWS_WITH(rt::collect_area_lights(scene, flat), Catch::Matchers::ContainsSubstring("emissive triangles' area lights"));
  rt::set_memory_limit(0);
}

TEST_CASE("a textured emitter's samples go where its texture is bright, and its light stays the texture's") {
  // A quad of two triangles whose texture coordinates fall on a white texel (first) and a black one
  // (second): the second emits nothing, so the floor sees the first triangle's light alone.
  rt_test::TempDir dir;
  rt::Image texture(2, 1);
  texture.at(0, 0) = Color(1.0f);
  texture.at(1, 0) = Color(0.0f);
  const std::string path = (dir.path() / "glow.png").string();
  rt::write_image(texture, path);
  const std::vector<Vec3f> quad{Vec3f(-0.3f, -0.2f, 0.5f), Vec3f(-0.3f, 0.2f, 0.5f), Vec3f(0.3f, 0.2f, 0.5f),
                                Vec3f(0.3f, -0.2f, 0.5f)};
  rt::Scene scene = floor_and_emitter(quad, Vec3d(2.0), diffuse_material(Vec3d(0.5)));
  rt::TriangleMesh lamp = *scene.nodes[0].models[1].mesh;
  lamp.texcoords.assign(lamp.positions.size(), rt::Vec2f(0.1f, 0.5f));
  for (std::size_t v = 3; v < 6; ++v) lamp.texcoords[v] = rt::Vec2f(0.9f, 0.5f);  // the second triangle
  scene.nodes[0].models[1].mesh = std::make_shared<const rt::TriangleMesh>(lamp);
  scene.materials[1].emission_texture.path = path;
  scene.materials[1].emission_texture.wrap_s = rt::TextureWrap::clamp_to_edge;
  const rt::TextureSampler sampler(scene);
  Shader shader(scene);
  shader.textures = &sampler;

  const rt::AreaLights lights = rt::collect_area_lights(scene, shader.flat, &sampler);
  REQUIRE(lights.emitters.size() == 1);
  CHECK(lights.emitters[0].texture_weighted);
  CHECK(lights.emitters[0].cdf[0] == Approx(1.01 / 1.02));  // equal areas; white 1 + 1% floor against 0 + 1%
  CHECK_FALSE(rt::collect_area_lights(scene, shader.flat).emitters[0].texture_weighted);

  const Vec3d point(0.4, 0.1, 0.0);
  const std::vector<Vec3d> white{Vec3d(quad[0]), Vec3d(quad[1]), Vec3d(quad[2])};
  const double expected = 0.5 / kPi * 2.0 * lambert_cosine_solid_angle(point, Vec3d(0, 0, 1), white);
  rt::EffectsOptions options;
  options.light_samples = 4096;
  rt::RayCounts counts;
  const Color c = shader.shade(Vec3f(0.4f, 0.1f, 2.0f), Vec3f(0, 0, -1), options, counts);
  CHECK(c.r == Approx(expected).epsilon(3e-3));
  CHECK(counts.skipped[int(rt::SkipRule::sample_zero)] < 4096 / 50);  // few samples wasted on black
}
