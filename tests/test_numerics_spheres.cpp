// Numerical robustness of the analytic spheres (ellipsoids under a transform), which every backend
// intersects with the same double-precision intersect_sphere:
//
//  * Exact answers: rays against unit spheres and ellipsoids with known intersections.
//  * Cross-check: Embree (native and watertight kernels) against the reference on random rays at
//    random ellipsoids: bit-identical hits (same function, so only Embree's traversal could differ).
//  * Reintersection: rays spawned from sphere hits with offset_ray_origin. Leaving outwards a
//    convex surface, a ray must never meet the sphere again; leaving inwards it must meet it (it
//    starts inside: no escape) beyond the origin. Ellipsoids at coordinates up to 1e5 and sizes
//    1e-3 .. 1e3; the fixed offset is printed for comparison.
//
// Regenerate the tables with  build/release/tests/rt_tests "[spheres]"

#include "catch.h"

#include <cmath>
#include <iostream>
#include <memory>
#include <numbers>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "numerics_util.h"
#include "rt/accel/accel.h"
#include "rt/accel/reference_accel.h"
#include "rt/flatten/flatten.h"
#include "rt/render/ray_offset.h"
#include "test_util.h"

namespace {

using rt::Mat4d;
using rt::Vec3d;
using rt::Vec3f;
using namespace rt_numerics;

// A scene of sphere models, one node each, flattened.
rt::FlatScene flat_spheres(const std::vector<Mat4d>& transforms) {
  rt::Scene scene = rt_test::make_scene({});
  scene.materials.resize(1);
  for (const Mat4d& transform : transforms) {
    rt::Node node;
    node.parent_from_node = transform;
    node.models.push_back(rt::Model{nullptr, 0, rt::Sphere{}});
    scene.nodes.push_back(node);
    scene.nodes[scene.root].children.push_back(static_cast<std::uint32_t>(scene.nodes.size() - 1));
  }
  return rt::flatten_scene(scene);
}

// A random ellipsoid: semi-axes size * [0.3, 1] each, random rotation, centre `offset` + jitter.
Mat4d random_ellipsoid(std::mt19937& rng, const Vec3d& offset, double size) {
  std::uniform_real_distribution<double> axis(0.3, 1.0), angle(0.0, 2.0 * std::numbers::pi);
  Mat4d m = glm::translate(Mat4d(1.0), offset + size * random_in_ball(rng, 2.0));
  m = glm::rotate(m, angle(rng), random_unit_vector(rng));
  return glm::scale(m, size * Vec3d(axis(rng), axis(rng), axis(rng)));
}

const Placement kPlacements[] = {
    {"origin, size 1", Vec3d(0.0), 1.0},
    {"origin, size 1e-3", Vec3d(0.0), 1e-3},
    {"origin, size 1e3", Vec3d(0.0), 1e3},
    {"offset (1e3, 1e3, 1e3), size 1", Vec3d(1e3), 1.0},
    {"offset (1e5, 1e5, 1e5), size 10", Vec3d(1e5), 10.0},
    {"offset (148376, 1234, -223423), size 10", Vec3d(148376.0, 1234.0, -223423.0), 10.0},
};

}  // namespace

TEST_CASE("intersect_sphere: exact answers for spheres and ellipsoids", "[spheres][numerics]") {
  rt::FlatSphere unit;
  double t = 0;
  // From outside along -z: enters at t = 4 (direction length 1), or 2 with a direction of length 2.
  REQUIRE(rt::intersect_sphere({0, 0, 5}, {0, 0, -1}, 0, 1e30, unit, t));
  CHECK(t == 4.0);
  REQUIRE(rt::intersect_sphere({0, 0, 5}, {0, 0, -2}, 0, 1e30, unit, t));
  CHECK(t == 2.0);
  // From inside: the exit. Behind the origin or beyond tfar: nothing.
  REQUIRE(rt::intersect_sphere({0, 0, 0.5}, {0, 0, -1}, 0, 1e30, unit, t));
  CHECK(t == 1.5);
  CHECK_FALSE(rt::intersect_sphere({0, 0, 5}, {0, 0, 1}, 0, 1e30, unit, t));
  CHECK_FALSE(rt::intersect_sphere({0, 0, 5}, {0, 0, -1}, 0, 3.9, unit, t));
  // tnear past the entry: the exit.
  REQUIRE(rt::intersect_sphere({0, 0, 5}, {0, 0, -1}, 4.5, 1e30, unit, t));
  CHECK(t == 6.0);
  // A miss beside the sphere; a zero direction; a tangent ray touches at t = 5.
  CHECK_FALSE(rt::intersect_sphere({1.5, 0, 5}, {0, 0, -1}, 0, 1e30, unit, t));
  CHECK_FALSE(rt::intersect_sphere({0, 0, 5}, {0, 0, 0}, 0, 1e30, unit, t));
  REQUIRE(rt::intersect_sphere({1, 0, 5}, {0, 0, -1}, 0, 1e30, unit, t));
  CHECK(t == Approx(5.0).epsilon(1e-12));

  // An ellipsoid with semi-axes (1, 2, 3) about (10, 0, 0): x-ray from far away enters at x = 9.
  const rt::FlatScene flat =
      flat_spheres({glm::scale(glm::translate(Mat4d(1.0), Vec3d(10, 0, 0)), Vec3d(1, 2, 3))});
  REQUIRE(flat.spheres.size() == 1);
  const rt::FlatSphere& ellipsoid = flat.spheres[0];
  REQUIRE(rt::intersect_sphere({0, 0, 0}, {1, 0, 0}, 0, 1e30, ellipsoid, t));
  CHECK(t == Approx(9.0).epsilon(1e-15));
  REQUIRE(rt::intersect_sphere({10, 0, -10}, {0, 0, 1}, 0, 1e30, ellipsoid, t));
  CHECK(t == Approx(7.0).epsilon(1e-15));
  // Its normal at the +z pole is +z, at a general point the gradient of the quadric.
  const rt::SurfacePoint pole = rt::make_sphere_surface_point(ellipsoid, {10, 0, -10}, {0, 0, 1}, t);
  CHECK(glm::length(pole.point - Vec3d(10, 0, -3)) < 1e-12);
  CHECK(glm::length(pole.geometric_normal - Vec3d(0, 0, -1)) < 1e-12);
  const Vec3d p(10 + std::cos(0.3), 2 * std::sin(0.3) * std::cos(0.7), 3 * std::sin(0.3) * std::sin(0.7));
  const Vec3d origin = p + Vec3d(0.5, 1.0, 2.0);
  REQUIRE(rt::intersect_sphere(origin, p - origin, 0, 1e30, ellipsoid, t));
  const rt::SurfacePoint s = rt::make_sphere_surface_point(ellipsoid, origin, p - origin, t);
  const Vec3d q = s.point - Vec3d(10, 0, 0);
  CHECK(glm::length(s.point - p) < 1e-12);
  CHECK(glm::length(s.geometric_normal - glm::normalize(Vec3d(q.x, q.y / 4, q.z / 9))) < 1e-12);
}

TEST_CASE("Embree and the reference return bit-identical sphere hits", "[spheres][crosscheck][numerics]") {
  std::cout << "\n### Spheres: Embree against the reference (random ellipsoids, random rays)\n\n"
            << "| placement | ellipsoids | rays | reference hits | Embree native: identical | Embree watertight: identical |\n"
            << "|---|---|---|---|---|---|\n";
  std::uint32_t seed = 500u;
  for (const Placement& placement : kPlacements) {
    std::mt19937 rng(++seed);
    std::vector<Mat4d> transforms;
    for (int i = 0; i < 40; ++i) transforms.push_back(random_ellipsoid(rng, placement.offset, placement.scale));
    const rt::FlatScene flat = flat_spheres(transforms);
    rt::AccelOptions watertight;
    watertight.embree_kernel = rt::EmbreeKernel::exact;
    const auto reference = rt::build_accel(rt::AccelKind::reference, flat);
    const auto native = rt::build_accel(rt::AccelKind::embree, flat);
    const auto exact = rt::build_accel(rt::AccelKind::embree, flat, watertight);
    std::size_t rays = 0, hits = 0, same_native = 0, same_exact = 0;
    auto same = [](const rt::Hit& a, const rt::Hit& b) { return a.t == b.t && a.primitive == b.primitive; };
    for (int i = 0; i < 5000; ++i) {
      rt::Ray ray;
      ray.origin = Vec3f(placement.offset + placement.scale * random_in_ball(rng, 6.0));
      const Vec3d target = placement.offset + placement.scale * random_in_ball(rng, 2.5);
      ray.direction = Vec3f(target - Vec3d(ray.origin));
      const rt::Hit r = reference->intersect(ray);
      ++rays;
      hits += r.found();
      same_native += same(native->intersect(ray), r) && native->occluded(ray) == reference->occluded(ray);
      same_exact += same(exact->intersect(ray), r) && exact->occluded(ray) == reference->occluded(ray);
    }
    std::cout << "| " << placement.name << " | " << flat.spheres.size() << " | " << rays << " | " << hits << " | "
              << same_native << " | " << same_exact << " |\n";
    INFO(placement.name);
    CHECK(hits > rays / 4);
    CHECK(same_native == rays);
    CHECK(same_exact == rays);
  }
  std::cout << std::endl;
}

TEST_CASE("rays spawned from sphere hits never re-hit the sphere they leave", "[spheres][numerics]") {
  std::cout << "\n### Spheres: rays spawned from hits on random ellipsoids\n\n"
            << "| placement | ray offset | spawned outwards | re-hits (should be 0) | spawned inwards | escapes (should "
               "be 0) | hits short of the far side (t < chord / 2) |\n"
            << "|---|---|---|---|---|---|---|\n";
  std::uint32_t seed = 900u;
  std::size_t robust_total = 0;
  for (const Placement& placement : kPlacements) {
    for (const char* offset : {"robust", "fixed:1e-4"}) {
      const rt::RayOffset policy = rt::parse_ray_offset(offset);
      std::mt19937 rng(++seed);
      std::size_t outwards = 0, rehits = 0, inwards = 0, escapes = 0, near_hits = 0;
      for (int e = 0; e < 50; ++e) {
        const Mat4d transform = random_ellipsoid(rng, placement.offset, placement.scale);
        const Vec3d centre(transform[3]);
        const rt::FlatScene flat = flat_spheres({transform});
        const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
        for (int h = 0; h < 10; ++h) {
          rt::Ray primary;
          primary.origin = Vec3f(centre + placement.scale * 5.0 * random_unit_vector(rng));
          primary.direction = Vec3f(centre + placement.scale * random_in_ball(rng, 0.2) - Vec3d(primary.origin));
          const rt::Hit hit = accel->intersect(primary);
          if (!hit.found()) continue;
          const rt::SurfacePoint surface = rt::make_sphere_surface_point(
              flat.spheres[0], Vec3d(primary.origin), Vec3d(primary.direction), hit.t);
          for (int r = 0; r < 400; ++r) {
            const Vec3d direction = random_unit_vector(rng);
            rt::Ray spawned;
            spawned.origin = rt::offset_ray_origin(policy, surface, direction);
            spawned.direction = Vec3f(direction);
            const rt::Hit again = accel->intersect(spawned);
            if (glm::dot(direction, surface.geometric_normal) > 0.0) {
              ++outwards;
              rehits += again.found() || accel->occluded(spawned);
            } else {
              ++inwards;
              escapes += !again.found();
              // The exit expected from the surface point itself, in the unit sphere's space: the
              // chord t = -2 p.d / d.d. A hit well short of it is the surface the ray left.
              const rt::FlatSphere& sphere = flat.spheres[0];
              const Vec3d p(sphere.object_from_world * rt::Vec4d(surface.point, 1.0));
              const Vec3d d = rt::Mat3d(sphere.object_from_world) * Vec3d(spawned.direction);
              const double chord = -2.0 * glm::dot(p, d) / glm::dot(d, d);
              near_hits += again.found() && double(again.t) < 0.5 * chord;
            }
          }
        }
      }
      std::cout << "| " << placement.name << " | " << offset << " | " << outwards << " | " << rehits << " | "
                << inwards << " | " << escapes << " | " << near_hits << " |\n";
      if (policy.mode == rt::RayOffset::Mode::robust) {
        INFO(placement.name);
        CHECK(outwards > 80'000);
        CHECK(rehits == 0);
        CHECK(escapes == 0);
        CHECK(near_hits == 0);
        robust_total += outwards + inwards;
      }
    }
  }
  std::cout << std::endl;
  CHECK(robust_total >= 1'000'000);
}
