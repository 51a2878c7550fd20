// The effects plan: exact pruning never changes the image (every scene in scenes/ and the shared
// corpora, rendered with and without pruning), the ray budget adds up, the plan's predictions hold
// (no lights, no specular, a light at the eye, a convex scene), and the opt-in approximations stay
// within their documented error bounds.

#include "catch.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <numeric>
#include <optional>
#include <set>
#include <string>

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_scene.h"
#include "rt/render/render.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

using rt::SkipRule;

std::uint64_t skipped(const rt::RayCounts& rays, SkipRule rule) { return rays.skipped[static_cast<int>(rule)]; }

// Sum of values[0 .. end).
std::uint64_t sum(const std::vector<std::uint64_t>& values, std::size_t end = std::numeric_limits<std::size_t>::max()) {
  const auto stop = values.begin() + static_cast<std::ptrdiff_t>(std::min(end, values.size()));
  return std::accumulate(values.begin(), stop, std::uint64_t{0});
}

// Every hit decides once per light (shadow ray or one skip rule) and, below max_depth, once about
// its reflection (ray or one skip rule); every camera pixel casts one ray.
void check_budget_adds_up(const rt::RenderResult& result, const rt::Scene& scene, std::uint64_t spp = 1) {
  const rt::RayCounts& rays = result.rays;
  const std::uint64_t hits = sum(rays.hits_per_depth);
  CHECK(rays.camera == std::uint64_t(scene.settings.width) * std::uint64_t(scene.settings.height) * spp);
  CHECK(rays.shadow == sum(rays.shadow_per_light));
  CHECK(rays.reflection == sum(rays.reflection_per_depth));
  CHECK(rays.shadow + skipped(rays, SkipRule::light_off) + skipped(rays, SkipRule::zero_contribution) +
            skipped(rays, SkipRule::light_at_eye) + skipped(rays, SkipRule::convex_facing) +
            skipped(rays, SkipRule::light_on_surface) + skipped(rays, SkipRule::dim_light) ==
        hits * scene.lights.size());
  CHECK(rays.reflection + skipped(rays, SkipRule::black_reflection) + skipped(rays, SkipRule::low_throughput) ==
        sum(rays.hits_per_depth, std::size_t(scene.settings.max_depth)));
  CHECK(sum(rays.reflection_per_depth, std::size_t(result.plan.useful_depth) + 1) == rays.reflection);
}

bool bit_identical(const rt::Image& a, const rt::Image& b) {
  return a.width == b.width && a.height == b.height &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(rt::Color)) == 0;
}

struct Renderer {
  rt::Scene scene;
  rt::FlatScene flat;
  std::unique_ptr<rt::Accel> accel;

  explicit Renderer(rt::Scene s) : scene(std::move(s)), flat(rt::flatten_scene(scene)) {
    accel = rt::build_accel(rt::AccelKind::embree, flat);
  }
  rt::RenderResult render(const rt::EffectsOptions& effects) const {
    rt::RenderOptions options;
    options.effects = effects;
    return rt::render_image(scene, flat, *accel, options);
  }
};

rt::EffectsOptions no_prune() {
  rt::EffectsOptions options;
  options.prune = false;
  return options;
}

// Renders `scene` with and without pruning; requires bit-identical float images and a consistent
// budget; returns one table row (rays and render seconds both ways).
std::string check_pruning_is_exact(rt::Scene scene, const std::string& label) {
  INFO(label);
  const Renderer renderer(std::move(scene));
  const rt::RenderResult pruned = renderer.render({});
  const rt::RenderResult full = renderer.render(no_prune());
  CHECK(bit_identical(pruned.image, full.image));
  CHECK(pruned.rays.total() <= full.rays.total());
  CHECK(full.rays.skipped_total() == full.rays.skipped[int(SkipRule::light_on_surface)]);
  check_budget_adds_up(pruned, renderer.scene);
  check_budget_adds_up(full, renderer.scene);
  return fmt::format("{:<34} {:>9}x{:<5} {:>12} {:>12} {:>6.3f} {:>8.3f} {:>8.3f}", label, renderer.scene.settings.width,
                     renderer.scene.settings.height, pruned.rays.total(), full.rays.total(),
                     double(pruned.rays.total()) / double(full.rays.total()), pruned.seconds, full.seconds);
}

using rt_test::at_width;
using rt_test::files_with;
using rt_test::shared_dir;

const char* kTableHeader = "scene                               resolution        rays pruned   rays full  ratio  pruned s   full s";

// A sphere (the unit sphere at the origin unless moved) with one material, lit by `lights`.
rt::Scene sphere_scene(const rt::Material& material, std::vector<rt::Light> lights) {
  rt::Scene scene;
  scene.nodes.resize(1);
  scene.nodes[0].models.push_back(rt::Model{nullptr, 0, rt::Sphere{}});
  scene.materials = {material};
  scene.lights = std::move(lights);
  scene.camera.eye = rt::Vec3d(0.0, 0.0, 4.0);
  scene.settings.width = 64;
  scene.settings.height = 48;
  return scene;
}

rt::Material diffuse_only(float value) {
  rt::Material m;
  m.diffuse = rt::Color(value);
  return m;
}

rt::Light directional(rt::Vec3d towards) {
  rt::Light light;
  light.position = rt::Vec4d(towards, 0.0);
  return light;
}

double max_abs_difference(const rt::Image& a, const rt::Image& b) {
  double largest = 0.0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i)
    largest = std::max({largest, double(std::abs(a.pixels[i].r - b.pixels[i].r)),
                        double(std::abs(a.pixels[i].g - b.pixels[i].g)), double(std::abs(a.pixels[i].b - b.pixels[i].b))});
  return largest;
}

}  // namespace

TEST_CASE("pruning never changes the image: every scene in scenes/", "[effects]") {
  std::cout << "\nPruned vs --no-prune, Embree, bit-identical float images required\n" << kTableHeader << "\n";
  std::cout << check_pruning_is_exact(rt::make_default_scene(), "built-in default") << "\n";
  for (const fs::path& file : files_with(fs::path(RT_SOURCE_DIR) / "scenes", {".json"}))
    std::cout << check_pruning_is_exact(rt::load_scene(file.string()), "scenes/" + file.filename().string()) << "\n";
}

TEST_CASE("pruning never changes the image: the CSE167x corpus", "[effects][corpus]") {
  const auto dir = shared_dir(fs::path("data") / "cse167x" / "scenes");
  if (!dir) return;
  const std::vector<fs::path> files = files_with(*dir, {".test"});
  REQUIRE(files.size() >= 10);
  std::cout << "\n" << kTableHeader << "\n";
  for (const fs::path& file : files)
    std::cout << check_pruning_is_exact(rt::load_scene(file.string()), file.filename().string()) << "\n";
}

TEST_CASE("pruning never changes the image: glTF and OBJ models at 160 pixels wide", "[effects][corpus]") {
  const std::vector<fs::path> files = rt_test::shared_model_files();
  if (files.empty()) return;
  std::cout << "\n" << kTableHeader << "\n";
  for (const fs::path& file : files)
    std::cout << check_pruning_is_exact(at_width(rt::load_scene(file.string()), 160), file.filename().string()) << "\n";
}

TEST_CASE("every skip rule has a name and a slot in the ray budget", "[effects]") {
  std::set<std::string> names;
  for (int r = 0; r < rt::kSkipRuleCount; ++r) names.insert(rt::to_string(static_cast<SkipRule>(r)));
  CHECK(names.size() == std::size_t(rt::kSkipRuleCount));
  CHECK(names.count("?") == 0);
  // No rule past the count: a rule appended without a slot writes past RayCounts::skipped.
  CHECK(rt::to_string(static_cast<SkipRule>(rt::kSkipRuleCount)) == "?");
}

TEST_CASE("the plan's predictions hold in the ray counts", "[effects]") {
  SECTION("no lights: no shadow rays") {
    rt::Scene scene = sphere_scene(diffuse_only(0.5f), {});
    const rt::RenderResult result = Renderer(scene).render({});
    CHECK(result.rays.shadow == 0);
    CHECK_FALSE(result.plan.shadows);
    check_budget_adds_up(result, scene);
  }
  SECTION("no specular colour: no reflection rays, whatever the max depth") {
    rt::Scene scene = rt::make_default_scene();
    for (rt::Material& m : scene.materials) m.specular = rt::Color(0.0f), m.reflective.reset();
    scene.settings.width = 80;
    scene.settings.height = 60;
    const rt::RenderResult result = Renderer(scene).render({});
    CHECK_FALSE(result.plan.reflections);
    CHECK(result.plan.useful_depth == 0);
    CHECK(result.rays.reflection == 0);
    CHECK(skipped(result.rays, SkipRule::black_reflection) > 0);
    check_budget_adds_up(result, scene);
  }
  SECTION("the only light sits at the eye: no shadow rays") {
    rt::Scene scene = rt::make_default_scene();
    for (rt::Material& m : scene.materials) m.specular = rt::Color(0.0f), m.reflective.reset();
    scene.lights.assign(1, rt::Light{});  // a white point light at the eye
    scene.lights[0].position = rt::Vec4d(scene.camera.eye, 1.0);
    scene.settings.width = 80;
    scene.settings.height = 60;
    const Renderer renderer(scene);
    const rt::RenderResult result = renderer.render({});
    CHECK(result.plan.lights[0].at_eye);
    CHECK(result.rays.shadow == 0);
    CHECK(skipped(result.rays, SkipRule::light_at_eye) > 0);
    check_budget_adds_up(result, scene);
    // ... and without pruning they are traced, and none is blocked: the same image.
    const rt::RenderResult full = renderer.render(no_prune());
    CHECK(full.rays.shadow == sum(full.rays.hits_per_depth));
    CHECK(bit_identical(result.image, full.image));
  }
  SECTION("with fixed ray offsets the convex rule is off") {
    const rt::Scene scene = sphere_scene(diffuse_only(0.7f), {directional({1, 1, 1})});
    const rt::FlatScene flat = rt::flatten_scene(scene);
    CHECK(rt::plan_effects(scene, flat, rt::RayOffset{}, {}).convex);
    CHECK_FALSE(rt::plan_effects(scene, flat, rt::parse_ray_offset("fixed:1e-4"), {}).convex);
  }
  SECTION("a black light and a scene of black materials contribute nothing") {
    rt::Scene scene = sphere_scene(diffuse_only(0.5f), {directional({0, 0, 1}), directional({0, 1, 0})});
    scene.lights[1].color = rt::Color(0.0f);
    const rt::RenderResult result = Renderer(scene).render({});
    CHECK(result.plan.lights[0].contributes);
    CHECK_FALSE(result.plan.lights[1].contributes);
    CHECK(skipped(result.rays, SkipRule::light_off) == sum(result.rays.hits_per_depth));
    scene.materials[0] = rt::Material{};
    scene.materials[0].emission = rt::Color(0.25f);
    const rt::RenderResult dark = Renderer(scene).render({});
    CHECK_FALSE(dark.plan.lights[0].contributes);
    CHECK(dark.rays.shadow == 0);
  }
}

TEST_CASE("a lone sphere or convex mesh needs no shadow ray where it faces the light", "[effects]") {
  SECTION("sphere: facing points are lit for certain, the others have a zero term") {
    const rt::Scene scene = sphere_scene(diffuse_only(0.7f), {directional({1, 1, 1})});
    const Renderer renderer(scene);
    const rt::RenderResult result = renderer.render({});
    REQUIRE(result.plan.convex);
    CHECK(result.rays.shadow == 0);
    CHECK(skipped(result.rays, SkipRule::convex_facing) > 0);
    CHECK(skipped(result.rays, SkipRule::zero_contribution) > 0);
    CHECK(bit_identical(result.image, renderer.render(no_prune()).image));
  }
  SECTION("an ellipsoid under a mirroring transform is still convex") {
    rt::Scene scene = sphere_scene(diffuse_only(0.7f), {directional({1, 1, 1})});
    scene.nodes[0].parent_from_node = glm::scale(rt::Mat4d(1.0), rt::Vec3d(-1.5, 0.5, 1.0));
    const Renderer renderer(scene);
    const rt::RenderResult result = renderer.render({});
    REQUIRE(result.plan.convex);
    CHECK(result.rays.shadow == 0);
    CHECK(bit_identical(result.image, renderer.render(no_prune()).image));
  }
  SECTION("a box mesh with outward normals is convex; turned inside out it is not") {
    rt::Scene scene;
    scene.nodes.resize(1);
    const auto box = std::make_shared<const rt::TriangleMesh>(rt::make_cube_mesh());
    scene.nodes[0].models.push_back(rt::Model{box, 0});
    scene.materials = {diffuse_only(0.6f)};
    scene.materials[0].ambient = rt::Color(0.1f);  // a term behind the surface too: those rays are traced
    scene.lights = {directional({0.3, 1.0, 0.6})};
    scene.camera.eye = rt::Vec3d(3.0, 2.5, 4.0);
    scene.settings.width = 64;
    scene.settings.height = 48;
    CHECK(rt::is_convex_for_certain(rt::flatten_scene(scene)));
    const Renderer renderer(scene);
    const rt::RenderResult result = renderer.render({});
    REQUIRE(result.plan.convex);
    CHECK(skipped(result.rays, SkipRule::convex_facing) > 0);
    CHECK(bit_identical(result.image, renderer.render(no_prune()).image));

    rt::TriangleMesh inside_out = *box;
    for (rt::Vec3u& t : inside_out.triangles) std::swap(t.y, t.z);
    scene.nodes[0].models[0].mesh = std::make_shared<const rt::TriangleMesh>(inside_out);
    CHECK_FALSE(rt::is_convex_for_certain(rt::flatten_scene(scene)));
  }
  SECTION("two spheres, or a concave mesh, are not") {
    rt::Scene scene = sphere_scene(diffuse_only(0.7f), {directional({1, 1, 1})});
    scene.nodes[0].models.push_back(rt::Model{nullptr, 0, rt::Sphere{rt::Vec3d(2.0, 0.0, 0.0), 0.5}});
    CHECK_FALSE(Renderer(scene).render({}).plan.convex);
    // An L-shaped pair of quads (an inner corner) is concave.
    const auto corner = rt_test::make_flat_mesh({{rt::Vec3f(0, 0, 0), rt::Vec3f(1, 0, 0), rt::Vec3f(0, 0, -1)},
                                                 {rt::Vec3f(0, 0, -1), rt::Vec3f(0, 1, -1), rt::Vec3f(0, 0, 0)}});
    rt::FlatScene flat = rt::flatten_scene(rt_test::make_scene({{corner, 0}}));
    CHECK_FALSE(rt::is_convex_for_certain(flat));
  }
}

TEST_CASE("the opt-in approximations stay within their documented bounds", "[effects]") {
  std::uint64_t saved = 0;
  for (const char* name : {"default.json", "hall-of-mirrors.json", "cornell-box.json"}) {
    INFO(name);
    rt::Scene scene = at_width(rt::load_scene((fs::path(RT_SOURCE_DIR) / "scenes" / name).string()), 200);
    const Renderer renderer(scene);
    const rt::RenderResult exact = renderer.render({});
    for (const auto& [throughput, light] : {std::pair{0.05, 0.0}, std::pair{0.0, 0.02}, std::pair{0.02, 0.01}}) {
      rt::EffectsOptions options;
      options.min_throughput = throughput;
      options.min_light_contribution = light;
      const rt::RenderResult approx = renderer.render(options);
      const double bound = approx.plan.approximation_error_bound();
      const double error = max_abs_difference(exact.image, approx.image);
      INFO("min throughput " << throughput << ", min light " << light << ": error " << error << ", bound " << bound);
      REQUIRE(std::isfinite(bound));
      CHECK(bound > 0.0);
      // The bound is on float64 radiance; the images are float32, so allow their rounding.
      CHECK(error <= bound * (1.0 + 1e-6) + 1e-6);
      CHECK(approx.rays.total() <= exact.rays.total());
      saved += exact.rays.total() - approx.rays.total();
      check_budget_adds_up(approx, renderer.scene);
      std::cout << fmt::format("{:<22} min_throughput {:<5} min_light {:<5} rays {:>8} of {:>8}  max error {:.5f}  bound {:.5f}\n",
                               name, throughput, light, approx.rays.total(), exact.rays.total(), error, bound);
    }
  }
  CHECK(saved > 0);  // and they do save rays
}
