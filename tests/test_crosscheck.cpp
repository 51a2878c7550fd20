// The Embree backend against the double-precision watertight reference on many random rays, over
// several meshes (also far from the origin and at small scale), for Embree robust (the default,
// asserted), Embree with robust mode off (printed) and Embree with the watertight kernel (which
// runs the reference's own test inside Embree's BVH, so it must return bit-identical hits).
//
// Criteria per ray: same hit or miss, same triangle, t within 1e-5 relative, barycentrics within
// 1e-4. A ray whose hit lies within 1e-6 (in barycentric terms) of a triangle edge, for either
// backend's hit, is ambiguous: two float32 and float64 solvers may legitimately disagree about
// which side of a shared edge (or whether at all) such a ray hits.
//
// One more class is counted apart, as "ill-conditioned", and reported: both backends hit the same
// triangle, and t, u and v differ by more than the criteria above but stay inside first-order
// bounds of the float32 error of Embree's answer. For Embree's robust Pluecker test
// (u = U / (U + V + W), U = D . ((v2 - v0) x (v2 + v0)), v_i = p_i - o in float32;
// t = T / den, T = Ng . v0, den = Ng . D):
//   |du|, |dv| <= 36 u_f |d| L (c + L) / |N . d| + 5 u_f,
//   |dt| / t   <= 16 u_f (1 + c / (t |d|)) / cos(n, d),      u_f = 2^-24,
// with L the longest edge, c = max |p_i - o| and N = (p1 - p0) x (p2 - p0). The barycentric bound
// adds up, to first order, the rounding of v_i (4 u |d| c L: only the part of v_i across the ray
// counts), of the edge and sum vectors (2 u |d| L (L + c)), of the cross product
// (4 sqrt(2) u |d| L c) and the dot product (6 u |d| L c) in each of U, V, W, bounds U + V + W by the
// sum (their signs agree for a hit) and divides by |U + V + W| = 2 |N . d|, plus the rounding of the
// division. The t bound: T and den are three-term dot products (3 u each) of float32 vectors, T
// over v0 whose rounding is u c, and |T| = |Ng| t |d| cos, |den| = |Ng| |d| cos; 16 also covers the
// float32 normal and the division. Both bounds cover Moller-Trumbore (robust off) too, whose
// terms are a subset. They grow without limit as the ray grazes the triangle (cos -> 0); such rays
// occur a few times per million here and are a property of float32, not of either backend's
// correctness. Everything else must agree.

#include "catch.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "numerics_util.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace {

using rt::Vec3d;
using rt::Vec3f;

constexpr double kEdgeEpsilon = 1e-6;
constexpr double kTRelative = 1e-5;
constexpr double kBarycentricTolerance = 1e-4;

struct Counts {
  std::size_t rays = 0, hits = 0, agreements = 0, ambiguous = 0, ill_conditioned = 0, failures = 0;
  std::size_t identical = 0;  // same Hit, bit for bit (t, u, v, triangle), and same occluded()
  std::vector<std::string> examples;  // the first few failures and ill-conditioned rays, described
  Counts& operator+=(const Counts& o) {
    rays += o.rays;
    identical += o.identical;
    hits += o.hits;
    agreements += o.agreements;
    ambiguous += o.ambiguous;
    ill_conditioned += o.ill_conditioned;
    failures += o.failures;
    examples.insert(examples.end(), o.examples.begin(), o.examples.end());
    return *this;
  }
};

std::string describe(const Counts& c) {
  std::ostringstream out;
  out << c.rays << " rays (" << c.hits << " hits), " << c.agreements << " agreements, " << c.ambiguous
      << " ambiguous, " << c.ill_conditioned << " ill-conditioned, " << c.failures << " failures, " << c.identical
      << " bit-identical";
  return out.str();
}

double edge_distance(const rt::Hit& hit) {
  return std::min({double(hit.u), double(hit.v), 1.0 - double(hit.u) - double(hit.v)});
}

// First-order bounds of the float32 error of Embree's t, u, v for `ray` on `triangle` (see the top).
struct Conditioning {
  double cosine, u_error, v_error, t_relative_error;
};
Conditioning conditioning(const rt::FlatScene& flat, std::uint32_t triangle, const rt::Ray& ray, double t) {
  const rt::Vec3u tri = flat.triangles[triangle];
  const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
  const Vec3d d(ray.direction), o(ray.origin);
  const Vec3d n = glm::cross(p1 - p0, p2 - p0);
  const double n_dot_d = std::abs(glm::dot(n, d));
  const double roundoff = std::ldexp(1.0, -24);
  const double longest = std::max({glm::length(p1 - p0), glm::length(p2 - p0), glm::length(p2 - p1)});
  const double reach = std::max({glm::length(p0 - o), glm::length(p1 - o), glm::length(p2 - o)});
  const double bound = 36.0 * roundoff * glm::length(d) * longest * (reach + longest) / n_dot_d + 5.0 * roundoff;
  const double cosine = n_dot_d / (glm::length(n) * glm::length(d));
  const double t_bound = 16.0 * roundoff * (1.0 + reach / (t * glm::length(d))) / cosine;
  return {cosine, bound, bound, t_bound};
}

std::string describe(const rt::Ray& ray, const rt::Hit& embree, const rt::Hit& reference, const rt::FlatScene& flat) {
  std::ostringstream out;
  out.precision(9);
  if (reference.found()) {
    const Conditioning k = conditioning(flat, reference.primitive, ray, reference.t);
    out << "[cos(n, d) " << k.cosine << ", float32 error bounds: u and v " << k.u_error << ", t relative "
        << k.t_relative_error << "] ";
  }
  out << "ray o=(" << ray.origin.x << ", " << ray.origin.y << ", " << ray.origin.z << ") d=(" << ray.direction.x
      << ", " << ray.direction.y << ", " << ray.direction.z << "): embree tri " << embree.primitive << " t " << embree.t
      << " uv " << embree.u << " " << embree.v << "; reference tri " << reference.primitive << " t " << reference.t
      << " uv " << reference.u << " " << reference.v;
  return out.str();
}

// Flattens a root with `children` (nodes 1..n) followed by `extra` nodes that the children may
// reference as their own children (nodes n+1..).
rt::FlatScene flatten_models(std::vector<rt::Node> children, std::vector<rt::Node> extra = {}) {
  rt::Scene scene = rt_test::make_scene({});
  scene.materials.resize(1);
  for (rt::Node& child : children) {
    scene.nodes[0].children.push_back(static_cast<std::uint32_t>(scene.nodes.size()));
    scene.nodes.push_back(std::move(child));
  }
  for (rt::Node& node : extra) scene.nodes.push_back(std::move(node));
  return rt::flatten_scene(scene);
}

rt::Node node_with(rt::TriangleMesh mesh, const rt::Mat4d& transform = rt::Mat4d(1.0)) {
  rt::Node node;
  node.parent_from_node = transform;
  node.models.push_back({std::make_shared<const rt::TriangleMesh>(std::move(mesh)), 0});
  return node;
}

rt::FlatScene sphere_scene() { return flatten_models({node_with(rt::make_sphere_mesh(1.0, 32, 16))}); }  // 960

rt::FlatScene cube_scene() { return flatten_models({node_with(rt::make_cube_mesh())}); }  // 12

rt::FlatScene soup_scene() {
  // 600 random, mutually intersecting triangles in [-1.3, 1.3]^3.
  std::mt19937 rng(20240611u);
  std::uniform_real_distribution<float> centre(-1.0f, 1.0f), offset(-0.3f, 0.3f);
  std::vector<std::array<Vec3f, 3>> corners;
  while (corners.size() < 600) {
    const Vec3f c(centre(rng), centre(rng), centre(rng));
    std::array<Vec3f, 3> tri;
    for (Vec3f& p : tri) p = c + Vec3f(offset(rng), offset(rng), offset(rng));
    if (glm::length(glm::cross(tri[1] - tri[0], tri[2] - tri[0])) > 1e-3f) corners.push_back(tri);
  }
  return flatten_models({node_with(rt_test::make_flat_mesh(corners))});
}

rt::FlatScene transformed_scene() {
  // Cubes and spheres under translation, rotation, non-uniform scale, a mirror and nesting.
  auto rotate = [](double degrees, Vec3d axis) {
    return glm::rotate(rt::Mat4d(1.0), degrees * std::numbers::pi / 180.0, glm::normalize(axis));
  };
  auto translate = [](Vec3d t) { return glm::translate(rt::Mat4d(1.0), t); };
  auto scale = [](Vec3d s) { return glm::scale(rt::Mat4d(1.0), s); };
  std::vector<rt::Node> nodes;
  nodes.push_back(node_with(rt::make_cube_mesh(), translate({0, -1, 0}) * scale({6, 0.2, 6})));
  nodes.push_back(node_with(rt::make_sphere_mesh(0.7, 16, 8), translate({-1.2, 0.2, 0.3})));
  nodes.push_back(node_with(rt::make_sphere_mesh(0.5, 16, 8),
                            translate({1.0, 0.5, -0.5}) * rotate(35, {1, 1, 0}) * scale({1.5, 0.6, 1.0})));
  nodes.push_back(node_with(rt::make_cube_mesh(), translate({0.3, 0.1, 1.2}) * rotate(-20, {0, 1, 0.3}) *
                                                      scale({-0.8, 0.5, 0.6})));  // mirrored
  // A parent with a cube and a child sphere: world_from_sphere = parent * child.
  nodes.push_back(node_with(rt::make_cube_mesh(), translate({0.0, 1.2, -1.0}) * rotate(45, {0, 0, 1})));
  nodes.back().children.push_back(static_cast<std::uint32_t>(nodes.size() + 1));  // the node appended next
  rt::Node child = node_with(rt::make_sphere_mesh(1.0, 12, 6), translate({0.9, 0.0, 0.0}) * scale({0.3, 0.3, 0.6}));
  return flatten_models(std::move(nodes), {std::move(child)});
}

// Casts `ray_count` random rays at `flat` from outside its bounding sphere (radius R): origins
// at distance 1.5R..3R from the centre, 90% aimed at a uniform point of the bounding box, 10%
// in a uniform random direction; direction lengths vary in [0.5, 2]. Classifies Embree robust
// (result[0]), Embree with robust mode off (result[1]) and Embree with the watertight kernel
// (result[2]) against the reference. Rays are drawn in 8 independently seeded chunks run in parallel.
constexpr int kEmbreeConfigs = 3;
const char* const kEmbreeConfigNames[kEmbreeConfigs] = {"robust", "robust off", "watertight kernel"};
using ConfigCounts = std::array<Counts, kEmbreeConfigs>;

ConfigCounts crosscheck(const rt::FlatScene& flat, std::size_t ray_count, std::uint32_t seed) {
  rt::AccelOptions robust_off, watertight;
  robust_off.embree_robust = false;
  watertight.embree_kernel = rt::EmbreeKernel::exact;
  const std::unique_ptr<rt::Accel> embrees[kEmbreeConfigs] = {
      rt::build_accel(rt::AccelKind::embree, flat), rt::build_accel(rt::AccelKind::embree, flat, robust_off),
      rt::build_accel(rt::AccelKind::embree, flat, watertight)};
  const std::unique_ptr<rt::Accel> reference = rt::build_accel(rt::AccelKind::reference, flat);

  Vec3d lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const Vec3f& p : flat.positions) {
    lo = glm::min(lo, Vec3d(p));
    hi = glm::max(hi, Vec3d(p));
  }
  const Vec3d centre = 0.5 * (lo + hi);
  const double radius = 0.5 * glm::length(hi - lo);

  struct Pair {
    ConfigCounts c;
    Pair& operator+=(const Pair& o) {
      for (int k = 0; k < kEmbreeConfigs; ++k) c[k] += o.c[k];
      return *this;
    }
  };
  const std::size_t chunks = 8;
  const Pair total = rt_numerics::parallel_chunks<Pair>(chunks, [&](std::size_t chunk) {
    std::mt19937 rng(seed * 16u + static_cast<std::uint32_t>(chunk));
    std::uniform_real_distribution<double> unit(0.0, 1.0), symmetric(-1.0, 1.0);
    auto random_unit_vector = [&] {
      for (;;) {
        const Vec3d v(symmetric(rng), symmetric(rng), symmetric(rng));
        const double length = glm::length(v);
        if (length > 1e-3 && length <= 1.0) return v / length;
      }
    };
    Pair pair;
    const std::size_t n = ray_count / chunks + (chunk < ray_count % chunks ? 1 : 0);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3d origin = centre + radius * (1.5 + 1.5 * unit(rng)) * random_unit_vector();
      Vec3d direction;
      if (unit(rng) < 0.9) {
        const Vec3d target = lo + Vec3d(unit(rng), unit(rng), unit(rng)) * (hi - lo);
        direction = glm::normalize(target - origin);
      } else {
        direction = random_unit_vector();
      }
      rt::Ray ray;
      ray.origin = Vec3f(origin);
      ray.direction = Vec3f(direction * (0.5 + 1.5 * unit(rng)));

      const rt::Hit r = reference->intersect(ray);
      const bool r_occluded = reference->occluded(ray);
      for (int k = 0; k < kEmbreeConfigs; ++k) {
        Counts& counts = pair.c[k];
        const rt::Accel& embree = *embrees[k];
        const rt::Hit e = embree.intersect(ray);
        const bool e_occluded = embree.occluded(ray);
        ++counts.rays;
        if (r.found()) ++counts.hits;
        if (e.t == r.t && e.u == r.u && e.v == r.v && e.primitive == r.primitive && e_occluded == r_occluded)
          ++counts.identical;

        bool agree = e.found() == r.found() && e_occluded == e.found() && r_occluded == r.found();
        if (agree && r.found()) {
          agree = e.primitive == r.primitive &&
                  std::abs(double(e.t) - double(r.t)) <= kTRelative * std::abs(double(r.t)) &&
                  std::abs(double(e.u) - double(r.u)) <= kBarycentricTolerance &&
                  std::abs(double(e.v) - double(r.v)) <= kBarycentricTolerance;
        }
        if (agree) {
          ++counts.agreements;
        } else if ((e.found() && edge_distance(e) < kEdgeEpsilon) || (r.found() && edge_distance(r) < kEdgeEpsilon)) {
          ++counts.ambiguous;
        } else if (e.found() && r.found() && e.primitive == r.primitive &&
                   [&] {
                     const Conditioning bound = conditioning(flat, r.primitive, ray, r.t);
                     const double t_tolerance = std::max(kTRelative, bound.t_relative_error) * std::abs(double(r.t));
                     return std::abs(double(e.t) - double(r.t)) <= t_tolerance &&
                            std::abs(double(e.u) - double(r.u)) <= bound.u_error &&
                            std::abs(double(e.v) - double(r.v)) <= bound.v_error;
                   }()) {
          ++counts.ill_conditioned;
          if (counts.examples.size() < 5) counts.examples.push_back("ill-conditioned: " + describe(ray, e, r, flat));
        } else {
          ++counts.failures;
          if (counts.examples.size() < 5) counts.examples.push_back("FAILURE: " + describe(ray, e, r, flat));
        }
      }
    }
    return pair;
  });
  return total.c;
}

// The meshes: the original four, plus the closed meshes of the watertightness test where float32
// matters most (far from the origin, and at millimetre scale).
ConfigCounts run_all(std::size_t rays_per_mesh, const char* run) {
  struct Case {
    const char* name;
    rt::FlatScene flat;
    std::uint32_t seed;
  };
  const Case cases[] = {
      {"UV sphere", sphere_scene(), 1u},
      {"cube", cube_scene(), 2u},
      {"triangle soup", soup_scene(), 3u},
      {"transformed scene", transformed_scene(), 4u},
      {"jittered UV sphere, radius 10 at (1e5, 1e5, 1e5)",
       rt_numerics::place(rt_numerics::jittered_uv_sphere(40, 20, 1.0, 1.5, 31337u), Vec3d(1e5), 10.0), 5u},
      {"icosphere, scale 1e-3 at the origin", rt_numerics::place(rt_numerics::icosphere(3), Vec3d(0.0), 1e-3), 6u},
      {"cube grid, scale 10 at (148376, 1234, -223423)",
       rt_numerics::place(rt_numerics::cube_grid(12), Vec3d(148376.0, 1234.0, -223423.0), 10.0), 7u}};
  std::cout << "\n### Cross-check against the reference (" << run << ")\n\n"
            << "| mesh | triangles | Embree | rays | reference hits | agreements | near an edge (< 1e-6) "
               "| ill-conditioned (within the float32 bound) | unexplained | bit-identical to the reference |\n"
            << "|---|---|---|---|---|---|---|---|---|---|\n";
  ConfigCounts total;
  auto print_row = [](const std::string& mesh, const std::string& triangles, int k, const Counts& n) {
    std::cout << "| " << mesh << " | " << triangles << " | " << kEmbreeConfigNames[k] << " | " << n.rays << " | "
              << n.hits << " | " << n.agreements << " | " << n.ambiguous << " | " << n.ill_conditioned << " | "
              << n.failures << " | " << n.identical << " |\n";
  };
  for (const Case& c : cases) {
    const ConfigCounts counts = crosscheck(c.flat, rays_per_mesh, c.seed);
    for (int k = 0; k < kEmbreeConfigs; ++k) {
      print_row(c.name, std::to_string(c.flat.triangle_count()), k, counts[k]);
      total[k] += counts[k];
    }
    CHECK(counts[0].hits > counts[0].rays / 4);  // the rays do test hits, not only misses
  }
  for (int k = 0; k < kEmbreeConfigs; ++k) print_row("**total**", "", k, total[k]);
  std::cout << std::endl;
  for (int k = 0; k < kEmbreeConfigs; ++k)
    for (const std::string& example : total[k].examples)
      std::cout << "  " << kEmbreeConfigNames[k] << ": " << example << "\n";
  WARN("crosscheck total (Embree robust): " << describe(total[0]));
  return total;
}

void check_total(const Counts& total, std::size_t rays) {
  REQUIRE(total.rays == rays);
  CHECK(total.agreements + total.ambiguous + total.ill_conditioned + total.failures == total.rays);
  CHECK(total.ambiguous < total.rays / 1000);  // ambiguity is rare, not a catch-all
  CHECK(total.ill_conditioned < total.rays / 100'000);
  REQUIRE(total.failures == 0);
}

}  // namespace

TEST_CASE("Embree agrees with the reference on 105k random rays", "[crosscheck][numerics]") {
  const ConfigCounts total = run_all(15'000, "default suite");
  check_total(total[0], 105'000);
  CHECK(total[2].identical == total[2].rays);  // the watertight kernel is the reference's test
}

TEST_CASE("Embree agrees with the reference on 1.05M random rays", "[crosscheck][numerics][.slow]") {
  const ConfigCounts total = run_all(150'000, "slow run");
  check_total(total[0], 1'050'000);
  CHECK(total[2].identical == total[2].rays);
}
