// rt-perf intersect: ray sets, agreement, the reference's time budget, Embree memory and the
// scaling sizes.

#include "catch.h"

#include <cmath>
#include <cstring>
#include <memory>

#include "intersect.h"
#include "rt/accel/embree_accel.h"
#include "rt/io/load_scene.h"
#include "rt/scene/shapes.h"

namespace {

bool same_rays(const std::vector<rt::Ray>& a, const std::vector<rt::Ray>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(rt::Ray)) == 0);
}

rt::FlatScene sphere_mesh_scene(std::size_t target) {
  rt::perf::ScalingSize size;
  size.target = target;
  size.slices = std::max(3, static_cast<int>(std::lround(std::sqrt(double(target)))));
  size.stacks = std::max(2, static_cast<int>(std::lround(double(target) / (2.0 * size.slices))) + 1);
  return rt::flatten_scene(rt::perf::make_scaling_scene(size));
}

}  // namespace

TEST_CASE("intersect: ray sets have the requested sizes and are deterministic", "[perf]") {
  const rt::Scene scene = rt::make_default_scene();
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const rt::Bounds3d bounds = rt::flat_bounds(flat);
  REQUIRE(bounds.lo.x < bounds.hi.x);

  const std::vector<rt::Ray> camera = rt::perf::make_camera_rays(scene, 32, 24);
  CHECK(camera.size() == 32u * 24u);
  CHECK(same_rays(camera, rt::perf::make_camera_rays(scene, 32, 24)));

  const std::vector<rt::Ray> a = rt::perf::make_incoherent_rays(bounds, 1000, 42);
  const std::vector<rt::Ray> b = rt::perf::make_incoherent_rays(bounds, 1000, 42);
  const std::vector<rt::Ray> c = rt::perf::make_incoherent_rays(bounds, 1000, 43);
  CHECK(a.size() == 1000);
  CHECK(same_rays(a, b));
  CHECK_FALSE(same_rays(a, c));
  for (const rt::Ray& ray : a) {
    for (int k = 0; k < 3; ++k) {
      CHECK(ray.origin[k] >= float(bounds.lo[k]) - 1e-5f);
      CHECK(ray.origin[k] <= float(bounds.hi[k]) + 1e-5f);
    }
    CHECK(std::abs(glm::length(rt::Vec3d(ray.direction)) - 1.0) < 1e-6);
  }

  const rt::EmbreeAccel embree(flat, rt::AccelOptions{});
  const std::vector<rt::Ray> shadow = rt::perf::make_shadow_rays(scene, flat, embree, camera);
  std::size_t hits = 0;
  for (const rt::Ray& ray : camera) hits += embree.intersect(ray).found() ? 1 : 0;
  REQUIRE(hits > 0);
  CHECK(shadow.size() > 0);
  CHECK(shadow.size() <= hits * scene.lights.size());
  CHECK(same_rays(shadow, rt::perf::make_shadow_rays(scene, flat, embree, camera)));

  CHECK(rt::perf::spread_indices(10, 20).size() == 10);
  const std::vector<std::size_t> spread = rt::perf::spread_indices(1000, 7);
  REQUIRE(spread.size() == 7);
  CHECK(spread.front() == 0);
  CHECK(std::is_sorted(spread.begin(), spread.end()));
  CHECK(spread.back() < 1000);
}

TEST_CASE("intersect: Embree and the reference agree on the default scene's camera and shadow rays", "[perf]") {
  const rt::Scene scene = rt::make_default_scene();
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const rt::EmbreeAccel embree(flat, rt::AccelOptions{});
  const std::unique_ptr<rt::Accel> reference = rt::build_accel(rt::AccelKind::reference, flat);
  const std::vector<rt::Ray> camera = rt::perf::make_camera_rays(scene, 32, 24);

  std::vector<rt::Hit> embree_hits, reference_hits;
  const rt::perf::Timing timing = rt::perf::time_intersect(embree, camera, 2, embree_hits);
  CHECK(timing.seconds.size() == 2);
  CHECK(timing.rays == camera.size());
  CHECK(timing.median_mrays_per_second() > 0.0);
  rt::perf::time_intersect(*reference, camera, 1, reference_hits);
  const rt::perf::Agreement agreement = rt::perf::compare_hits(embree_hits, reference_hits);
  CHECK(agreement.rays == camera.size());
  CHECK(agreement.same_hit == camera.size());
  CHECK(agreement.t_mismatches == 0);

  const std::vector<rt::Ray> shadow = rt::perf::make_shadow_rays(scene, flat, embree, camera);
  std::vector<std::uint8_t> embree_occluded, reference_occluded;
  rt::perf::time_occluded(embree, shadow, 1, embree_occluded);
  rt::perf::time_occluded(*reference, shadow, 1, reference_occluded);
  const rt::perf::Agreement shadows = rt::perf::compare_occlusion(embree_occluded, reference_occluded);
  CHECK(shadows.same_hit == shadow.size());

  // compare_hits counts what differs.
  std::vector<rt::Hit> altered = reference_hits;
  std::size_t changed_t = 0, changed_primitive = 0, tied = 0;
  for (rt::Hit& hit : altered) {
    if (!hit.found()) continue;
    if (changed_t < 3) {
      hit.t *= 1.001f;
      ++changed_t;
    } else if (changed_primitive < 2) {
      hit = rt::Hit{};
      ++changed_primitive;
    } else if (tied < 4) {
      hit.primitive += 1;  // another triangle at the same t: a tie, not a disagreement in t
      ++tied;
    }
  }
  const rt::perf::Agreement counted = rt::perf::compare_hits(embree_hits, altered);
  CHECK(counted.same_hit == camera.size() - changed_primitive - tied);
  CHECK(counted.t_mismatches == changed_t);
  CHECK(counted.ties == tied);
}

TEST_CASE("intersect: the reference budget keeps, reduces or skips", "[perf]") {
  // 1 ms per ray, 5 runs: 1000 rays cost 5 s.
  const rt::perf::ReferencePlan fits = rt::perf::plan_reference(1e-3, 1000, 5, 20.0);
  CHECK(fits.rays == 1000);
  CHECK_FALSE(fits.reduced);
  CHECK_FALSE(fits.skipped);
  CHECK(fits.estimated_seconds == Approx(5.0));

  const rt::perf::ReferencePlan reduced = rt::perf::plan_reference(1e-3, 10000, 5, 20.0);
  CHECK(reduced.reduced);
  CHECK_FALSE(reduced.skipped);
  CHECK(reduced.rays == 4000);
  CHECK(reduced.estimated_seconds == Approx(50.0));

  const rt::perf::ReferencePlan skipped = rt::perf::plan_reference(1.0, 10000, 5, 20.0);
  CHECK(skipped.skipped);
  CHECK(skipped.rays == 0);
  CHECK(skipped.estimated_seconds == Approx(50000.0));

  // A small set is traced whole or not at all.
  CHECK(rt::perf::plan_reference(1.0, 10, 1, 20.0).rays == 10);
  CHECK(rt::perf::plan_reference(1.0, 50, 1, 20.0).skipped);
}

TEST_CASE("intersect: Embree's memory is counted and grows with the triangle count", "[perf]") {
  const rt::FlatScene small = sphere_mesh_scene(1000);
  const rt::FlatScene large = sphere_mesh_scene(100000);
  REQUIRE(large.triangle_count() > 50 * small.triangle_count());
  const rt::EmbreeAccel small_accel(small, rt::AccelOptions{});
  const rt::EmbreeAccel large_accel(large, rt::AccelOptions{});
  CHECK(small_accel.memory_bytes() > 0);
  CHECK(large_accel.memory_bytes() > small_accel.memory_bytes());
  // A BVH over 100,000 triangles takes some megabytes.
  CHECK(large_accel.memory_bytes() > 1000000);
}

TEST_CASE("intersect: scaling sizes cover 1e2 to the maximum by decades", "[perf]") {
  const std::vector<rt::perf::ScalingSize> sizes = rt::perf::scaling_sizes(1e7);
  REQUIRE(sizes.size() == 6);
  double target = 100.0;
  for (const rt::perf::ScalingSize& size : sizes) {
    CHECK(size.target == static_cast<std::size_t>(target));
    CHECK(size.triangles == 2 * std::size_t(size.slices) * std::size_t(size.stacks - 1));
    CHECK(double(size.triangles) >= target / 2.0);
    CHECK(double(size.triangles) <= target * 2.0);
    target *= 10.0;
  }
  const std::vector<rt::perf::ScalingSize> uneven = rt::perf::scaling_sizes(5e4);
  REQUIRE(uneven.size() == 4);
  CHECK(uneven.back().target == 50000);
  CHECK(rt::perf::scaling_sizes(100).size() == 1);
  CHECK_THROWS(rt::perf::scaling_sizes(99));

  // The flattened mesh keeps the triangle count (no zero-area triangles at these sizes).
  for (const rt::perf::ScalingSize& size : rt::perf::scaling_sizes(1e4)) {
    const rt::FlatScene flat = rt::flatten_scene(rt::perf::make_scaling_scene(size));
    CHECK(flat.triangle_count() == size.triangles);
  }
}
