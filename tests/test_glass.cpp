// Glass in the renderer (issue 20): the shader's refracted rays against closed forms of geometric
// optics, and the robustness of their origins across scales. The rays are the ones find_color
// actually traces, recorded by a wrapper around the accelerator.

#include "catch.h"

#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/core/error.h"
#include "rt/io/load_scene.h"
#include "rt/render/shade.h"
#include "test_util.h"

namespace {

using rt::Vec3d;
using rt::Vec3f;

// Records every closest-hit query (ray and answer) in call order; single-threaded use.
class RecordingAccel final : public rt::Accel {
 public:
  explicit RecordingAccel(const rt::Accel& inner) : inner_(inner) {}
  rt::Hit intersect(const rt::Ray& ray) const override {
    const rt::Hit hit = inner_.intersect(ray);
    queries.push_back({ray, hit});
    return hit;
  }
  bool occluded(const rt::Ray& ray) const override { return inner_.occluded(ray); }
  std::string_view name() const override { return inner_.name(); }

  struct Query {
    rt::Ray ray;
    rt::Hit hit;
  };
  mutable std::vector<Query> queries;

 private:
  const rt::Accel& inner_;
};

// A scene of one glass object (`geometry` a native-format geometry, under `transform` keys) of
// index `ior`, no lights, black background, recursion to `max_depth`.
std::string glass_scene(const std::string& geometry, const std::string& transform, double ior, int max_depth) {
  return fmt::format(R"({{
    "max_depth": {},
    "camera": {{ "eye": [0, 0, 10], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 30 }},
    "materials": {{ "glass": {{ "transmission": 1, "ior": {} }} }},
    "nodes": [ {{ {} "models": [ {{ "geometry": {}, "material": "glass" }} ] }} ]
  }})", max_depth, ior, transform, geometry);
}

struct Traced {
  rt::Scene scene;
  rt::FlatScene flat;
  std::unique_ptr<rt::Accel> accel;
  std::unique_ptr<RecordingAccel> recorder;
  rt::EffectsPlan plan;

  Traced(const std::string& json, int sphere_tessellation = 0)
      : scene(rt::parse_scene_json(json, "glass.json")), flat(flatten(scene, sphere_tessellation)) {
    accel = rt::build_accel(rt::AccelKind::embree, flat);
    recorder = std::make_unique<RecordingAccel>(*accel);
    plan = rt::plan_effects(scene, flat, rt::RayOffset{}, rt::EffectsOptions{});
  }
  static rt::FlatScene flatten(const rt::Scene& scene, int sphere_tessellation) {
    rt::FlattenOptions options;
    options.sphere_tessellation = sphere_tessellation;
    return rt::flatten_scene(scene, options);
  }
  // The closest-hit queries of one find_color call for the ray (origin, direction).
  std::vector<RecordingAccel::Query> trace(const Vec3d& origin, const Vec3d& direction) {
    recorder->queries.clear();
    rt::Ray ray;
    ray.origin = Vec3f(origin);
    ray.direction = Vec3f(glm::normalize(direction));
    rt::RayCounts counts;
    rt::find_color(rt::ShadingContext{scene, flat, *recorder, plan}, ray, 1, counts);
    return recorder->queries;
  }
};

// Whether triangles a and b lie in one plane facing one way (unit normals within 1e-4).
bool coplanar(const rt::FlatScene& flat, std::uint32_t a, std::uint32_t b) {
  const auto normal = [&](std::uint32_t t) {
    const rt::Vec3u tri = flat.triangles[t];
    const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
    return glm::normalize(glm::cross(p1 - p0, p2 - p0));
  };
  return glm::dot(normal(a), normal(b)) > 1.0 - 1e-4;
}

}  // namespace

TEST_CASE("a glass ball focuses a paraxial beam at n R / (2 (n - 1)) from its centre", "[glass]") {
  // Ball-lens effective focal length (e.g. Hecht, Optics, 5th ed., §6.2 thick lenses): for a ray
  // parallel to the axis at height h << R, the ray leaving the ball crosses the axis there.
  const double radius = 2.0;
  for (const double n : {1.33, 1.5, 1.8}) {
    // max_depth 3 from depth 1: the refraction in (depth 2) and out (depth 3), nothing after.
    Traced traced(glass_scene(fmt::format(R"({{ "type": "sphere", "radius": {} }})", radius), "", n, 3));
    for (const double h : {0.002, 0.004}) {
      const auto queries = traced.trace(Vec3d(h, 0.0, 10.0), Vec3d(0.0, 0.0, -1.0));
      // The ray leaving through the back: it starts on the far side (z < 0) heading away (-z).
      const RecordingAccel::Query* out = nullptr;
      for (const auto& q : queries)
        if (q.ray.origin.z < 0.0f && q.ray.direction.z < 0.0f) {
          REQUIRE(out == nullptr);  // exactly one such ray
          out = &q;
        }
      REQUIRE(out != nullptr);
      CHECK_FALSE(out->hit.found());
      const Vec3d o(out->ray.origin), d(out->ray.direction);
      CHECK(glm::length(o) > radius);  // started outside the surface it left
      const double crossing = o.z - o.x / d.x * d.z;
      const double focal = n * radius / (2.0 * (n - 1.0));
      INFO("n " << n << ", h " << h << ": crosses the axis at z = " << crossing << ", f = " << focal);
      CHECK(-crossing == Approx(focal).epsilon(5e-4));
    }
  }
}

TEST_CASE("a parallel slab shifts a ray sideways by d sin(t) (1 - cos(t) / sqrt(n^2 - sin^2 t)) and keeps its direction",
          "[glass]") {
  // A closed box of thickness d along z (a cube scaled 4 x 4 x d), centred on the origin.
  const double d = 0.5, n = 1.5;
  Traced traced(glass_scene(R"({ "type": "cube" })", fmt::format(R"("scale": [4, 4, {}],)", d), n, 3));
  for (const double degrees : {0.0, 15.0, 40.0, 65.0}) {
    const double theta = degrees * std::numbers::pi / 180.0;
    const Vec3d direction(std::sin(theta), 0.0, -std::cos(theta));
    const Vec3d origin = Vec3d(0.0, 0.0, d / 2.0) - 4.0 * direction;  // aimed at the front face's centre
    const auto queries = traced.trace(origin, direction);
    const RecordingAccel::Query *in = nullptr, *out = nullptr;
    for (const auto& q : queries)
      if (q.ray.direction.z < 0.0f && std::abs(q.ray.origin.z) < 0.75 * d) (q.ray.origin.z > 0.0f ? in : out) = &q;
    REQUIRE(in != nullptr);
    REQUIRE(out != nullptr);
    // The robust offsets start each ray a step off its surface along the normal, which moves its
    // line sideways by at most that step: the closed form holds to within the two steps.
    const double steps = std::abs(in->ray.origin.z - d / 2.0) + std::abs(out->ray.origin.z + d / 2.0);
    CHECK(steps < 1e-4 * d);
    const Vec3d exit_direction(out->ray.direction);
    CHECK(glm::length(exit_direction - direction) < 1e-6);
    // The distance between the incident line and the exit line (parallel).
    const double shift = glm::length(glm::cross(Vec3d(out->ray.origin) - origin, direction));
    const double s = std::sin(theta);
    const double expected = d * s * (1.0 - std::cos(theta) / std::sqrt(n * n - s * s));
    INFO(degrees << " degrees: shift " << shift << ", expected " << expected << ", offset steps " << steps);
    CHECK(shift == Approx(expected).margin(steps + 1e-6 * d));
  }
}

TEST_CASE("refracted and reflected rays never re-hit their surface nor leak through closed glass, 1e-3 to 1e5",
          "[glass][numerics]") {
  std::mt19937_64 rng(20);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const auto random_unit = [&] {
    for (;;) {
      const Vec3d v(uniform(rng), uniform(rng), uniform(rng));
      if (const double l = glm::length(v); l > 0.1 && l <= 1.0) return v / l;
    }
  };
  for (const double scale : {1e-3, 1.0, 1e3, 1e5}) {
    // The object's centre sits away from the origin, as in real scenes.
    const Vec3d centre = scale * Vec3d(3.0, -2.0, 5.0);
    const std::string at = fmt::format(R"("translate": [{}, {}, {}], "scale": {},)", centre.x, centre.y, centre.z, scale);
    struct Shape {
      const char* name;
      std::string geometry;
      int tessellation;
    };
    for (const Shape& shape : {Shape{"sphere", R"({ "type": "sphere", "radius": 1 })", 0},
                               Shape{"tessellated sphere", R"({ "type": "sphere", "radius": 1 })", 48},
                               Shape{"cube", R"({ "type": "cube" })", 0}}) {
      // max_depth 2 from depth 1: one secondary level, the rays from the first hit.
      Traced traced(glass_scene(shape.geometry, at, 1.5, 2), shape.tessellation);
      int entering = 0, self_hits = 0, leaks = 0, outer_reflection_hits = 0;
      for (int i = 0; i < 2000; ++i) {
        const Vec3d target = centre + 0.45 * scale * random_unit();
        const Vec3d origin = target + 4.0 * scale * random_unit();
        const auto queries = traced.trace(origin, target - origin);
        REQUIRE(!queries.empty());
        if (!queries[0].hit.found()) continue;
        // queries: the primary, then its reflection, then (unless TIR) its refraction.
        REQUIRE(queries.size() >= 2);
        if (queries[1].hit.found()) ++outer_reflection_hits;  // a convex body: the reflection must escape
        if (queries.size() < 3) continue;
        ++entering;
        const RecordingAccel::Query& inside = queries[2];
        if (!inside.hit.found())
          ++leaks;
        else if (traced.flat.is_sphere(inside.hit.primitive) ? inside.hit.t < scale  // chords inside are >= 1.49 R
                                                             : coplanar(traced.flat, queries[0].hit.primitive,
                                                                        inside.hit.primitive))
          ++self_hits;  // on a convex body the way out is never the plane the ray came in through
      }
      INFO(shape.name << " at scale " << scale << ": " << entering << " rays entered");
      CHECK(entering > 1500);
      CHECK(leaks == 0);
      CHECK(self_hits == 0);
      CHECK(outer_reflection_hits == 0);
    }
  }
}

TEST_CASE("glass from the native format: the keys, and errors naming the JSON path", "[glass]") {
  const auto parse = [](const std::string& material) {
    return rt::parse_scene_json(
        fmt::format(R"({{ "camera": {{ "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 40 }},
                          "materials": {{ "m": {} }}, "nodes": [] }})", material), "s.json");
  };
  const rt::Material glass = parse(R"({ "transmission": [1, 0.9, 0.8], "ior": 1.7, "thin": true,
                                        "attenuation_color": 0.5, "attenuation_distance": 3 })").materials.at(0);
  CHECK(glass.is_dielectric());
  CHECK(glass.transmission == rt::Color(1.0f, 0.9f, 0.8f));
  CHECK(glass.ior == 1.7f);
  CHECK(glass.thin_walled);
  CHECK(glass.attenuation_color == rt::Color(0.5f));
  CHECK(glass.attenuation_distance == 3.0f);
  CHECK_FALSE(glass.transmission_mix);
  CHECK_FALSE(parse(R"({ "diffuse": 0.5 })").materials.at(0).is_dielectric());
  const auto error = [&](const std::string& material) {
    try {
      parse(material);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK_THAT(error(R"({ "ior": 1.5 })"), Catch::Matchers::ContainsSubstring("give a non-black \"transmission\" too"));
  CHECK_THAT(error(R"({ "transmission": 1, "ior": 0.5 })"), Catch::Matchers::ContainsSubstring("/materials/m/ior: ior 0.5 is outside [1, 10]"));
  CHECK_THAT(error(R"({ "transmission": 1, "thin": 1 })"), Catch::Matchers::ContainsSubstring("/materials/m/thin"));
  CHECK_THAT(error(R"({ "transmission": 1, "attenuation_color": 2 })"), Catch::Matchers::ContainsSubstring("must be <= 1"));
  CHECK_THAT(error(R"({ "transmission": 1, "attenuation_distance": 0 })"), Catch::Matchers::ContainsSubstring("must be > 0"));
}

TEST_CASE("glass from MTL: illum 4, 6 and 7 refract with Ni and Tf, illum 3 and 5 stay mirrors", "[glass][obj]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "g.mtl", R"(newmtl seven
Ks 0.3 0.3 0.3
Tf 0.5 0.6 0.7
Ni 1.7
illum 7
newmtl four
illum 4
newmtl six
Ni 0
illum 6
newmtl five
Ks 0.9 0.9 0.9
illum 5
)");
  std::string obj = "mtllib g.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
  for (const char* name : {"seven", "four", "six", "five"}) obj += fmt::format("usemtl {}\nf 1 2 3\n", name);
  rt_test::write_file(dir / "g.obj", obj);
  const rt::Scene scene = rt::load_scene(dir / "g.obj");
  const auto material = [&](const std::string& name) -> const rt::Material& { return rt_test::material_named(scene, name); };
  CHECK(material("seven").transmission == rt::Color(0.5f, 0.6f, 0.7f));
  CHECK(material("seven").ior == 1.7f);
  CHECK(*material("seven").reflective == rt::Color(0.0f));  // Fresnel, not Ks, weights the reflection
  CHECK(material("seven").specular == rt::Color(0.3f));   // the highlight stays
  CHECK(material("four").transmission == rt::Color(1.0f));  // no Tf: clear
  CHECK(material("six").ior == 1.5f);                       // Ni 0: "unset"
  CHECK_FALSE(material("five").is_dielectric());
  CHECK(*material("five").reflective == rt::Color(0.9f));
}

TEST_CASE("rt render --stats and --explain count refraction rays per depth, and pruning leaves glass unchanged",
          "[glass][cli]") {
  rt_test::TempDir dir;
  const std::string scene = std::string(RT_SOURCE_DIR) + "/scenes/glass-ball.json";
  const rt_test::RtRun run =
      rt_test::run_rt_in(dir, "render '" + scene + "' --width 64 --height 48 -q -o pruned.ppm --stats stats.json --explain");
  REQUIRE(run.status == 0);
  const nlohmann::json stats = nlohmann::json::parse(rt_test::read_file(dir / "stats.json"));
  const std::uint64_t refraction = stats.at("rays").at("refraction");
  CHECK(refraction > 0);
  std::uint64_t per_depth = 0, reflection_per_depth = 0;
  for (const auto& row : stats.at("ray_budget").at("reflection")) {
    per_depth += row.at("refraction").get<std::uint64_t>();
    reflection_per_depth += row.at("reflection").get<std::uint64_t>();
    CHECK(row.at("rays").get<std::uint64_t>() ==
          row.at("reflection").get<std::uint64_t>() + row.at("refraction").get<std::uint64_t>() +
              row.at("see_through").get<std::uint64_t>());
  }
  CHECK(per_depth == refraction);
  CHECK(reflection_per_depth == stats.at("rays").at("reflection").get<std::uint64_t>());
  CHECK(stats.at("rays").at("total").get<std::uint64_t>() ==
        stats.at("rays").at("camera").get<std::uint64_t>() + stats.at("rays").at("shadow").get<std::uint64_t>() +
            stats.at("rays").at("reflection").get<std::uint64_t>() + refraction);
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("refraction  on: 1 of 3 materials are glass") &&
                          Catch::Matchers::ContainsSubstring("of them refracted"));
  // Every ray pruned (black weights, zero terms) would have added exactly 0.
  REQUIRE(rt_test::run_rt_in(dir, "render '" + scene + "' --width 64 --height 48 -q -o full.ppm --no-prune").status == 0);
  CHECK(rt_test::read_file(dir / "pruned.ppm") == rt_test::read_file(dir / "full.ppm"));
}
