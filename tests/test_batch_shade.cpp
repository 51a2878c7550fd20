// The batch shader (src/render/batch_shade.h) changes no bit: every scene in scenes/, the shared
// corpora and a scene built to reach each of its rules are rendered with RenderOptions::
// batch_shading on and off, and the float images and every ray count must be identical.

#include "catch.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <random>
#include <span>
#include <string>

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>

#include "render/batch_lanes.h"
#include "render/batch_shade.h"
#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_scene.h"
#include "rt/render/camera.h"
#include "rt/render/ray_offset.h"
#include "rt/render/render.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

bool bit_identical(const rt::Image& a, const rt::Image& b) {
  return a.width == b.width && a.height == b.height &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(rt::Color)) == 0;
}

// Every count of the ray budget but the timing ticks.
void check_same_counts(const rt::RayCounts& a, const rt::RayCounts& b) {
  CHECK(a.camera == b.camera);
  CHECK(a.shadow == b.shadow);
  CHECK(a.reflection == b.reflection);
  CHECK(a.refraction == b.refraction);
  CHECK(a.see_through == b.see_through);
  CHECK(a.area_light == b.area_light);
  CHECK(a.area_light_per_emitter == b.area_light_per_emitter);
  CHECK(a.shadow_per_light == b.shadow_per_light);
  CHECK(a.reflection_per_depth == b.reflection_per_depth);
  CHECK(a.hits_per_depth == b.hits_per_depth);
  CHECK(a.skipped == b.skipped);
}

struct Variant {
  const char* name;
  rt::EffectsOptions effects;
  rt::RayOffset offset;
};

std::vector<Variant> variants() {
  rt::EffectsOptions unpruned;
  unpruned.prune = false;
  rt::EffectsOptions approximate;
  approximate.min_throughput = 0.2;
  approximate.min_light_contribution = 0.02;
  return {{"pruned", {}, {}},
          {"unpruned", unpruned, {}},
          {"approximations", approximate, {}},
          {"fixed offsets", {}, {rt::RayOffset::Mode::fixed, 1e-4}}};
}

// Renders `scene` (Embree, its surface test) with batch shading on and off under each variant;
// requires identical images and counts, and with `expect_batched` that the batch shader is on.
void check_batching_is_exact(const rt::Scene& scene, const std::string& label, bool expect_batched = false) {
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const rt::SceneSurfaceTest surface_test(scene, flat);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat, rt::with_surface_test({}, surface_test));
  for (const Variant& variant : variants()) {
    INFO(label << ", " << variant.name);
    rt::RenderOptions options;
    options.effects = variant.effects;
    options.ray_offset = variant.offset;
    const rt::RenderResult batched = rt::render_image(scene, flat, *accel, options);
    options.batch_shading = false;
    const rt::RenderResult scalar = rt::render_image(scene, flat, *accel, options);
    CHECK(bit_identical(batched.image, scalar.image));
    check_same_counts(batched.rays, scalar.rays);
    if (expect_batched) {
      const rt::ShadingContext context{scene, flat, *accel, batched.plan, variant.offset};
      CHECK(rt::BatchShader(context).enabled());
    }
  }
}

using rt_test::at_width;
using rt_test::files_with;
using rt_test::shared_dir;

rt::Light point_light(rt::Vec3d position, float color, rt::Vec3d attenuation = {1.0, 0.0, 0.0}) {
  rt::Light light;
  light.position = rt::Vec4d(position, 1.0);
  light.color = rt::Color(color);
  light.attenuation = attenuation;
  return light;
}

rt::Material phong(float diffuse, float specular, float shininess) {
  rt::Material m;
  m.ambient = rt::Color(0.05f);
  m.diffuse = rt::Color(diffuse, diffuse * 0.8f, diffuse * 0.6f);
  m.specular = rt::Color(specular);
  m.shininess = shininess;
  return m;
}

// Each rule of the batch shader reached: point lights with attenuation, a spot, a directional and
// a black light, a light at the eye, a two-sided plane seen from behind, spheres and an emitter-free
// glass-free mix of reflecting and matte materials, reflections four deep.
rt::Scene rules_scene() {
  const rt::Vec3f a(-2, 0, -2), b(2, 0, -2), c(2, 0, 2), d(-2, 0, 2);
  rt::TriangleMesh floor = rt_test::make_flat_mesh({{a, c, b}, {a, d, c}});
  // A wall facing away from the camera (its normal points to -z): seen from behind.
  rt::TriangleMesh wall = rt_test::make_flat_mesh({{rt::Vec3f(-1, 0, -1), rt::Vec3f(-1, 2, -1), rt::Vec3f(1, 0, -1)}});
  rt::Scene scene = rt_test::make_scene({{floor, 0}, {wall, 1}, {rt::make_sphere_mesh(0.4, 24, 12), 2}});
  scene.nodes[0].models.push_back(rt::Model{nullptr, 3, rt::Sphere{rt::Vec3d(0.9, 0.5, 0.3), 0.35}});
  scene.materials = {phong(0.7f, 0.3f, 40.0f), phong(0.5f, 0.0f, 1.0f), phong(0.2f, 0.8f, 200.0f), phong(0.6f, 0.2f, 20.0f)};
  scene.materials[1].back_face = rt::BackFace::flipped;
  scene.materials[1].reflective = rt::Color(0.0f);
  scene.camera.eye = rt::Vec3d(0.3, 1.2, 3.0);
  scene.camera.target = rt::Vec3d(0.0, 0.4, 0.0);
  scene.lights.push_back(point_light({1.5, 3.0, 2.0}, 0.8f, {1.0, 0.1, 0.02}));
  rt::Light spot = point_light({-1.0, 2.5, 1.0}, 0.6f);
  spot.spot_direction = glm::normalize(rt::Vec3d(1.0, -2.5, -1.0));
  spot.spot_cos_inner = 0.95;
  spot.spot_cos_outer = 0.85;
  scene.lights.push_back(spot);
  rt::Light sun;
  sun.position = rt::Vec4d(glm::normalize(rt::Vec3d(-0.5, 1.0, 0.3)), 0.0);
  sun.color = rt::Color(0.3f);
  scene.lights.push_back(sun);
  scene.lights.push_back(point_light({0.0, 1.0, 0.0}, 0.0f));  // black: off
  scene.lights.push_back(point_light(scene.camera.eye, 0.2f));  // at the eye
  scene.settings.width = 96;
  scene.settings.height = 72;
  scene.settings.max_depth = 4;
  scene.settings.background = rt::Color(0.1f, 0.2f, 0.3f);
  return scene;
}

}  // namespace

TEST_CASE("batch shading changes no bit: a scene reaching each of its rules", "[batch]") {
  check_batching_is_exact(rules_scene(), "rules scene", true);
}

// The rules scene lit by area lights as well: a quad emitter above it facing down and a triangle
// emitter facing away (behind every hit), so that the area-light terms of batched hits (recorded
// at camera hits, traced at once in the reflection waves) take each emitter-level rule.
TEST_CASE("batch shading changes no bit: area lights with point lights, reflections four deep", "[batch]") {
  rt::Scene scene = rules_scene();
  const auto emitter = [&](const std::vector<std::array<rt::Vec3f, 3>>& triangles, float radiance) {
    rt::Material m;
    m.emission = rt::Color(radiance, radiance * 0.9f, radiance * 0.7f);
    m.emits_light = true;
    scene.materials.push_back(m);
    scene.nodes[0].models.push_back(rt::Model{std::make_shared<rt::TriangleMesh>(rt_test::make_flat_mesh(triangles)),
                                              static_cast<std::uint32_t>(scene.materials.size() - 1), {}});
  };
  const rt::Vec3f a(-0.5f, 2.5f, -0.5f), b(0.5f, 2.5f, -0.5f), c(0.5f, 2.5f, 0.5f), d(-0.5f, 2.5f, 0.5f);
  emitter({{a, b, c}, {a, c, d}}, 6.0f);  // facing down (-y)
  emitter({{rt::Vec3f(-2, 1, -3), rt::Vec3f(-2, 2, -3), rt::Vec3f(-1, 1, -3)}}, 3.0f);  // facing -z, away
  check_batching_is_exact(scene, "rules scene with area lights", true);
  // The cases are reached: samples traced, and both emitter-level rules taken.
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat, {});
  const rt::RayCounts rays = rt::render_image(scene, flat, *accel, {}).rays;
  CHECK(rays.area_light > 0);
  CHECK(rays.skipped[static_cast<int>(rt::SkipRule::emitter_behind)] > 0);
  CHECK(rays.skipped[static_cast<int>(rt::SkipRule::emitter_below_horizon)] > 0);
}

TEST_CASE("batch shading changes no bit: one convex mesh (the convex rule)", "[batch]") {
  rt::Scene scene = rt_test::make_scene({{rt::make_cube_mesh(), 0}});
  scene.materials = {phong(0.7f, 0.3f, 40.0f)};
  scene.camera.eye = rt::Vec3d(2.0, 1.5, 3.0);
  scene.camera.target = rt::Vec3d(0.0);
  scene.lights = {point_light({2.0, 3.0, 1.0}, 1.0f)};
  scene.settings.width = 64;
  scene.settings.height = 48;
  check_batching_is_exact(scene, "convex cube", true);
}

TEST_CASE("batch shading changes no bit: every scene in scenes/", "[batch]") {
  check_batching_is_exact(rt::make_default_scene(), "built-in default", true);
  for (const fs::path& file : files_with(fs::path(RT_SOURCE_DIR) / "scenes", {".json"}))
    check_batching_is_exact(at_width(rt::load_scene(file.string()), 160), "scenes/" + file.filename().string());
}

TEST_CASE("batch shading changes no bit: the CSE167x corpus", "[batch][corpus]") {
  const auto dir = shared_dir(fs::path("data") / "cse167x" / "scenes");
  if (!dir) return;
  for (const fs::path& file : files_with(*dir, {".test"}))
    check_batching_is_exact(at_width(rt::load_scene(file.string()), 160), file.filename().string());
}

TEST_CASE("batch shading changes no bit: glTF and OBJ models at 120 pixels wide", "[batch][corpus]") {
  const std::vector<fs::path> files = rt_test::shared_model_files();
  for (const fs::path& file : files)
    check_batching_is_exact(at_width(rt::load_scene(file.string()), 120), file.filename().string());
}

// A triangle whose vertex normals cancel: +z, -z, +z, so the interpolated normal is exactly zero
// where b1 = 1/2, down the middle pixel column. There the shading normal is the geometric one
// (shading_normal, as in pbrt-v4), so those pixels equal a flat-shaded triangle's, in both shading
// paths. Normalising zero used to give a NaN reflection ray, on which Embree aborted the process.
TEST_CASE("vertex normals that cancel shade with the geometric normal", "[batch]") {
  const auto scene_with = [](bool cancelling) {
    rt::TriangleMesh mesh =
        rt_test::make_flat_mesh({{rt::Vec3f(-1, -1, 0), rt::Vec3f(1, -1, 0), rt::Vec3f(-1, 1, 0)}});
    if (cancelling) mesh.normals[1] = rt::Vec3f(0, 0, -1);
    rt::Scene scene = rt_test::make_scene({{mesh, 0}});
    scene.materials = {phong(0.5f, 0.5f, 20.0f)};
    scene.lights = {point_light({0.5, 0.5, 4.0}, 1.0f)};
    scene.settings.width = scene.settings.height = 65;
    scene.settings.max_depth = 3;
    return scene;
  };
  const rt::Scene cancelling = scene_with(true), flat_shaded = scene_with(false);
  check_batching_is_exact(cancelling, "cancelling normals", true);
  const rt::FlatScene flat = rt::flatten_scene(cancelling);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat, {});
  const rt::Image image = rt::render_image(cancelling, flat, *accel, {}).image;
  const rt::Image expected = rt_test::render_as_rt_does(flat_shaded);
  const rt::CameraFrame frame = rt::make_camera_frame(cancelling.camera, 65, 65, cancelling.source);
  int zero_normals = 0;
  for (int y = 0; y < 65; ++y)
    for (int x = 0; x < 65; ++x) {
      const rt::Color& c = image.at(x, y);
      CHECK((std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b)));
      const rt::Hit hit = accel->intersect(rt::ray_through_pixel(frame, x, y));
      if (!hit.found()) continue;
      const double b1 = hit.u, b2 = hit.v, b0 = 1.0 - b1 - b2;
      const rt::Vec3u tri = flat.triangles[hit.primitive];
      const rt::Vec3d normal = b0 * rt::Vec3d(flat.normals[tri.x]) + b1 * rt::Vec3d(flat.normals[tri.y]) +
                               b2 * rt::Vec3d(flat.normals[tri.z]);
      if (normal != rt::Vec3d(0.0)) continue;
      ++zero_normals;
      INFO("pixel " << x << ", " << y);
      CHECK(c == expected.at(x, y));
    }
  CHECK(zero_normals > 0);  // the case is reached
}

// The lanes themselves against the scalar functions they mirror: for random hits on random
// triangles (near the origin, far from it, axis-aligned ones whose points have zero and exactly
// representable coordinates), every surface point, reflection origin, shadow origin and shadow
// tfar must be make_surface_point's, offset_ray_origin's and shadow_ray_tfar's bit for bit. The
// images above could miss a wrong last bit of an origin; this cannot.
TEST_CASE("batch shading lanes equal the scalar ray offsets bit for bit", "[batch]") {
  std::mt19937_64 random(20261204);
  const auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(random); };
  std::vector<std::array<rt::Vec3f, 3>> corners;
  for (const double scale : {1.0, 1e-3, 1e4}) {
    const rt::Vec3d centre(uniform(-1, 1) * scale, uniform(-1, 1) * scale, uniform(-1, 1) * scale);
    for (int t = 0; t < 64; ++t) {
      std::array<rt::Vec3f, 3> c;
      for (rt::Vec3f& p : c)
        p = rt::Vec3f(centre + scale * rt::Vec3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)));
      corners.push_back(c);
    }
  }
  for (int t = 0; t < 16; ++t) {  // in the plane z = 0, at integer corners
    const float a = float(t % 4), b = float(t / 4);
    corners.push_back({rt::Vec3f(a, b, 0), rt::Vec3f(a + 1, b, 0), rt::Vec3f(a, b + 1, 0)});
  }
  rt::TriangleMesh mesh = rt_test::make_flat_mesh(corners);
  for (rt::Vec3f& n : mesh.normals) n = glm::normalize(rt::Vec3f(uniform(-1, 1), uniform(-1, 1), uniform(0.1, 1)));
  rt::Scene scene = rt_test::make_scene({{mesh, 0}});
  scene.materials = {phong(0.7f, 0.3f, 40.0f)};
  scene.materials[0].back_face = rt::BackFace::flipped;
  scene.lights = {point_light({0.5, 2.0, 1.5}, 1.0f, {1.0, 0.3, 0.1}), point_light({-3e4, 1e4, 2e4}, 0.5f)};
  rt::Light sun;
  sun.position = rt::Vec4d(glm::normalize(rt::Vec3d(0.3, 1.0, -0.2)), 0.0);
  sun.color = rt::Color(0.3f);
  scene.lights.push_back(sun);
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat, {});

  for (const rt::RayOffset& policy : {rt::RayOffset{}, rt::RayOffset{rt::RayOffset::Mode::fixed, 1e-4}}) {
    INFO(rt::to_string(policy));
    const rt::EffectsPlan plan = rt::plan_effects(scene, flat, policy, {});
    const rt::ShadingContext context{scene, flat, *accel, plan, policy};
    const rt::BatchShader shader(context);
    REQUIRE(shader.enabled());
    rt::BatchShader::Workspace work;
    int compared = 0;
    for (int block = 0; block < 200; ++block) {
      const int count = 1 + block % rt::BatchShader::kLanes;  // every lane count, tails included
      std::vector<rt::Ray> rays(static_cast<std::size_t>(count));
      std::vector<rt::Hit> hits(static_cast<std::size_t>(count));
      for (int i = 0; i < count; ++i) {
        rt::Hit& hit = hits[std::size_t(i)];
        hit.primitive = std::uint32_t(random() % flat.triangle_count());
        hit.u = float(uniform(0, 1));
        hit.v = float(uniform(0, 1 - double(hit.u)));
        hit.t = 1.0f;
        rays[std::size_t(i)].direction = rt::Vec3f(uniform(-1, 1), uniform(-1, 1), uniform(-1, -0.1));
      }
      const std::array<bool, rt::BatchShader::kLanes> unbatched{};
      shader.prepare(rays, hits, std::span(unbatched.data(), std::size_t(count)), work);
      const rt::BatchShader::Lanes& lanes = work.lanes;
      REQUIRE(lanes.count == count);
      const auto v3 = [](const auto& v, int i) { return rt::Vec3d(v.x.v[i], v.y.v[i], v.z.v[i]); };
      const auto f3 = [](const auto& v, int i) { return rt::Vec3f(v.x[i], v.y[i], v.z[i]); };
      const auto same = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof a) == 0; };
      for (int i = 0; i < count; ++i) {
        const rt::Vec3u tri = flat.triangles[hits[std::size_t(i)].primitive];
        const rt::SurfacePoint surface =
            rt::make_surface_point(rt::Vec3d(flat.positions[tri.x]), rt::Vec3d(flat.positions[tri.y]),
                                   rt::Vec3d(flat.positions[tri.z]), hits[std::size_t(i)].u, hits[std::size_t(i)].v);
        CHECK(same(v3(lanes.point, i), surface.point));
        CHECK(same(v3(lanes.geometric_normal, i), surface.geometric_normal));
        CHECK(same(lanes.error_bound.v[i], surface.error_bound));
        CHECK(same(f3(lanes.reflection_origin, i), rt::offset_ray_origin(policy, surface, v3(lanes.reflected, i))));
        for (std::size_t j = 0; j < scene.lights.size(); ++j) {
          const rt::BatchShader::Lanes::Light& light = lanes.lights[j];
          const rt::Vec3f origin = rt::offset_ray_origin(policy, surface, v3(light.to_light, i));
          CHECK(same(f3(light.shadow_origin, i), origin));
          if (!scene.lights[j].is_directional())
            CHECK(same(light.shadow_distance.v[i],
                       rt::shadow_ray_tfar(policy, rt::Vec3d(origin), rt::Vec3d(scene.lights[j].position))));
        }
        ++compared;
      }
    }
    CHECK(compared > 1000);
  }
}

// The builds of the lane arithmetic (render/batch_lanes.h: baseline SSE2, AVX2 and AVX-512,
// whichever this CPU runs) on the same random lanes, degenerate triangles, lights at a point and
// spot cones included, every count of lanes (AVX-512 takes eight, then four at a time): every
// output must be the same bits. The test above checks whichever build this CPU runs against the
// scalar functions; this one ties the others to the baseline.
TEST_CASE("batch shading lanes: the AVX2 and AVX-512 builds compute the baseline build's bits", "[batch]") {
  namespace bl = rt::batch_lanes;
  const std::vector<const bl::Kernels*> wider = bl::wider_kernels();
  if (wider.empty()) {
    SUCCEED("this CPU has no AVX2: only the baseline build runs here");
    return;
  }
  const bl::Kernels& baseline = bl::baseline_kernels();
  std::mt19937_64 random(4242);
  const auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(random); };
  constexpr int kLanes = rt::BatchShader::kLanes;
  const auto fill = [&](rt::Vec3Lanes<kLanes>& v, double scale) {
    for (int i = 0; i < kLanes; ++i) {
      v.x.v[i] = double(float(uniform(-scale, scale)));
      v.y.v[i] = double(float(uniform(-scale, scale)));
      v.z.v[i] = double(float(uniform(-scale, scale)));
    }
  };
  for (const bl::Kernels* wide : wider)
    for (int round = 0; round < 64; ++round) {
      const double scale = round % 3 == 0 ? 1e4 : round % 3 == 1 ? 1e-3 : 1.0;
      bl::Gathered in;
      for (rt::Vec3Lanes<kLanes>* v : {&in.p0, &in.p1, &in.p2, &in.n0, &in.n1, &in.n2, &in.d}) fill(*v, scale);
      for (int i = 0; i < kLanes; ++i) {
        in.b1.v[i] = double(float(uniform(0, 0.5)));
        in.b2.v[i] = double(float(uniform(0, 0.5)));
        in.flip[i] = random() % 2 ? -1 : 0;
      }
      in.p1.x.v[3] = in.p0.x.v[3], in.p1.y.v[3] = in.p0.y.v[3], in.p1.z.v[3] = in.p0.z.v[3];  // zero area
      const rt::batch_lanes::OriginPolicy policy{round % 2 == 1, 1e-4};
      rt::BatchShader::Lanes a, b;
      a.count = b.count = 1 + round % kLanes;
      a.reflections = b.reflections = a.highlights = b.highlights = true;
      for (rt::BatchShader::Lanes* lanes : {&a, &b}) {
        fill(lanes->ambient, 1.0);
        fill(lanes->diffuse, 1.0);
        fill(lanes->specular, 1.0);
        for (int i = 0; i < kLanes; ++i) lanes->highlight[i] = i % 3 ? -1 : 0;
      }
      b.ambient = a.ambient, b.diffuse = a.diffuse, b.specular = a.specular;
      baseline.surfaces(in, policy, a);
      wide->surfaces(in, policy, b);
      const int n = a.count;  // lanes past it may be left unwritten
      const auto same_lanes = [n](const auto& x, const auto& y) {
        return std::memcmp(&x.v, &y.v, sizeof(double) * std::size_t(n)) == 0;
      };
      const auto same_vectors = [&](const rt::Vec3Lanes<kLanes>& x, const rt::Vec3Lanes<kLanes>& y) {
        return same_lanes(x.x, y.x) && same_lanes(x.y, y.y) && same_lanes(x.z, y.z);
      };
      const auto same_origins = [n](const rt::Vec3fLanes<kLanes>& x, const rt::Vec3fLanes<kLanes>& y) {
        const std::size_t bytes = sizeof(float) * std::size_t(n);
        return std::memcmp(x.x, y.x, bytes) == 0 && std::memcmp(x.y, y.y, bytes) == 0 && std::memcmp(x.z, y.z, bytes) == 0;
      };
      CHECK(same_vectors(a.point, b.point));
      CHECK(same_vectors(a.geometric_normal, b.geometric_normal));
      CHECK(same_lanes(a.error_bound, b.error_bound));
      CHECK(same_vectors(a.direction, b.direction));
      CHECK(same_vectors(a.normal, b.normal));
      CHECK(same_vectors(a.reflected, b.reflected));
      CHECK(same_origins(a.reflection_origin, b.reflection_origin));

      bl::LightLanes light;
      light.directional = round % 4 == 3;
      light.spot = round % 4 == 1;
      const double position[3] = {a.point.x.v[0], uniform(-2, 2) * scale, uniform(-2, 2) * scale};
      for (int c = 0; c < 3; ++c) {
        light.position[c] = round % 8 == 2 ? (c == 0 ? a.point.x.v[0] : c == 1 ? a.point.y.v[0] : a.point.z.v[0])
                                           : position[c];  // round 2, 10, ...: at lane 0's point
        light.to_light[c] = c == 1 ? 1.0 : 0.0;
        light.color[c] = 0.5 + 0.1 * c;
        light.attenuation[c] = c == 0 ? 1.0 : 0.1 * c;
        light.spot_direction[c] = c == 1 ? -1.0 : 0.0;
      }
      light.spot_cos_outer = 0.8;
      light.cone_width = 0.1;
      light.extent = scale * 2;
      a.lights.resize(1);
      b.lights.resize(1);
      rt::Vec3Lanes<kLanes> intensity_a, intensity_b;
      rt::LaneArray<kLanes> ndl_a, ndl_b, ndh_a, ndh_b, power;
      baseline.light(light, policy, a, a.lights[0], intensity_a, ndl_a, ndh_a);
      wide->light(light, policy, b, b.lights[0], intensity_b, ndl_b, ndh_b);
      CHECK(same_vectors(intensity_a, intensity_b));
      CHECK(same_lanes(ndl_a, ndl_b));
      CHECK(same_lanes(ndh_a, ndh_b));
      CHECK(same_vectors(a.lights[0].to_light, b.lights[0].to_light));
      CHECK(same_lanes(a.lights[0].geometric_cosine, b.lights[0].geometric_cosine));
      CHECK(same_lanes(a.lights[0].shadow_distance, b.lights[0].shadow_distance));
      CHECK(std::memcmp(a.lights[0].on_point, b.lights[0].on_point, sizeof(std::int64_t) * std::size_t(n)) == 0);
      CHECK(same_origins(a.lights[0].shadow_origin, b.lights[0].shadow_origin));
      for (int i = 0; i < kLanes; ++i) power.v[i] = uniform(0, 1);
      baseline.terms(a, intensity_a, ndl_a, power, a.lights[0]);
      wide->terms(b, intensity_a, ndl_a, power, b.lights[0]);
      CHECK(same_vectors(a.lights[0].term, b.lights[0].term));
    }
}

// The gather of a hit's vertices, normals, direction and barycentrics (Kernels::gather): both
// builds give the widened float32 values themselves, lane by lane, lanes past the count copying
// lane 0, also for triangles that use the arrays' last vertex (read without the 16-byte load).
TEST_CASE("batch shading lanes: the gather of both builds widens each lane's vertices exactly", "[batch]") {
  namespace bl = rt::batch_lanes;
  constexpr int kLanes = rt::BatchShader::kLanes;
  std::mt19937 random(99);
  const auto uniform = [&](float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(random); };
  const std::uint32_t vertex_count = 7;
  std::vector<rt::Vec3f> positions(vertex_count), normals(vertex_count);
  for (std::uint32_t v = 0; v < vertex_count; ++v) {
    positions[v] = rt::Vec3f(uniform(-1e3f, 1e3f), uniform(-1, 1), uniform(-1e-3f, 1e-3f));
    normals[v] = rt::Vec3f(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
  }
  const bl::VertexArrays vertices{positions.data(), normals.data(), vertex_count};
  std::vector<const bl::Kernels*> builds{&bl::baseline_kernels()};
  for (const bl::Kernels* build : bl::wider_kernels()) builds.push_back(build);
  int last_vertex_lanes = 0;
  for (int round = 0; round < 50; ++round) {
    const int count = 1 + round % kLanes;
    std::array<rt::Vec3u, kLanes> triangles{};
    std::array<rt::Ray, kLanes> rays;
    std::array<rt::Hit, kLanes> hits;
    for (int i = 0; i < count; ++i) {
      triangles[std::size_t(i)] = rt::Vec3u(random() % vertex_count, random() % vertex_count, random() % vertex_count);
      rays[std::size_t(i)].direction = rt::Vec3f(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      hits[std::size_t(i)].u = uniform(0, 0.5f);
      hits[std::size_t(i)].v = uniform(0, 0.5f);
    }
    for (const bl::Kernels* build : builds) {
      bl::Gathered in;
      build->gather(vertices, triangles.data(), rays.data(), hits.data(), count, in);
      for (int i = 0; i < (count + 3) / 4 * 4; ++i) {
        const int from = i < count ? i : 0;
        const rt::Vec3u tri = triangles[std::size_t(from)];
        const auto lane3 = [i](const rt::Vec3Lanes<kLanes>& v) { return rt::Vec3d(v.x.v[i], v.y.v[i], v.z.v[i]); };
        CHECK(lane3(in.p0) == rt::Vec3d(positions[tri.x]));
        CHECK(lane3(in.p1) == rt::Vec3d(positions[tri.y]));
        CHECK(lane3(in.p2) == rt::Vec3d(positions[tri.z]));
        CHECK(lane3(in.n0) == rt::Vec3d(normals[tri.x]));
        CHECK(lane3(in.n1) == rt::Vec3d(normals[tri.y]));
        CHECK(lane3(in.n2) == rt::Vec3d(normals[tri.z]));
        CHECK(lane3(in.d) == rt::Vec3d(rays[std::size_t(from)].direction));
        CHECK(in.b1.v[i] == double(hits[std::size_t(from)].u));
        CHECK(in.b2.v[i] == double(hits[std::size_t(from)].v));
        last_vertex_lanes += tri.x == vertex_count - 1 || tri.y == vertex_count - 1 || tri.z == vertex_count - 1;
      }
    }
  }
  CHECK(last_vertex_lanes > 50);
}
