// The default intersection kernel's two builds (src/accel/triangle_clusters.h: baseline x86-64
// and AVX2, one chosen at run time). The numerics suite checks whichever build this CPU runs for
// watertightness; these cases tie the other build to it bit for bit, and check on both that rays
// aimed exactly at a fan's shared vertex and along its shared edges (the lanes that take the exact
// double-precision fallback) never slip through.

#include "catch.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "accel/triangle_clusters.h"
#include "rt/flatten/flatten.h"

namespace {

using rt::ClusterHits;
using rt::IntersectCluster;
using rt::kClusterWidth;
using rt::TriangleCluster;
using rt::Vec3f;

// The lanes `kernel` reports and their hits, as bits, for comparing builds.
struct Answer {
  unsigned found = 0;
  std::vector<std::uint32_t> bits;  // t, b1, b2 of each found lane, in lane order
  bool operator==(const Answer&) const = default;
};

Answer ask(IntersectCluster kernel, const rt::ShearedRay& ray, const TriangleCluster& cluster, float tnear,
           float tfar) {
  ClusterHits hits;
  Answer answer;
  answer.found = kernel(ray, cluster, tnear, tfar, hits);
  for (unsigned l = 0; l < kClusterWidth; ++l) {
    if ((answer.found >> l & 1u) == 0) continue;
    for (const float value : {hits.t[l], hits.b1[l], hits.b2[l]}) answer.bits.push_back(std::bit_cast<std::uint32_t>(value));
  }
  return answer;
}

// Eight triangles around a shared centre vertex, a closed disc, at `centre` in the plane spanned by
// `u` and `v` (world space, float32), with the ring radius `radius`. Positions: centre, then the ring.
rt::FlatScene make_fan(const Vec3f& centre, const Vec3f& u, const Vec3f& v, float radius, std::mt19937_64& random) {
  rt::FlatScene flat;
  flat.positions.push_back(centre);
  std::uniform_real_distribution<float> jitter(0.8f, 1.2f);
  for (unsigned i = 0; i < kClusterWidth; ++i) {
    const float angle = 2.0f * 3.14159265f * float(i) / float(kClusterWidth);
    const float r = radius * jitter(random);
    flat.positions.push_back(centre + r * std::cos(angle) * u + r * std::sin(angle) * v);
  }
  for (unsigned i = 0; i < kClusterWidth; ++i) {
    flat.triangles.push_back({0u, 1u + i, 1u + (i + 1) % kClusterWidth});
    flat.material_ids.push_back(0);
  }
  return flat;
}

TEST_CASE("cluster kernel: both builds give the same bits and let no vertex-aimed ray through a fan",
          "[accel][watertight]") {
  const IntersectCluster baseline = &rt::cluster_kernel::baseline::intersect_cluster;
  const IntersectCluster avx2 = rt::avx2_intersect_cluster();
  if (!avx2) WARN("this CPU has no AVX2: only the baseline build is checked");
  std::mt19937_64 random(1919);
  const auto uniform = [&](float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(random); };
  const auto random_unit = [&] {
    for (;;) {
      const Vec3f d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      const float length = glm::length(d);
      if (length > 0.1f && length <= 1.0f) return d / length;
    }
  };
  std::uint32_t ids[kClusterWidth];
  for (unsigned i = 0; i < kClusterWidth; ++i) ids[i] = i;
  int compared = 0, vertex_rays = 0, edge_rays = 0, hits_found = 0;
  for (int round = 0; round < 400; ++round) {
    // Near the origin, far from it (float32 spacing 2^-7 at 1e5), in a coordinate plane (z = 0,
    // where the shear's z terms vanish) and at small scale.
    const float offset = round % 4 == 0 ? 1e5f : round % 4 == 1 ? 0.0f : round % 4 == 2 ? 3.0f : 1e-3f;
    const float radius = round % 4 == 0 ? 10.0f : round % 4 == 3 ? 1e-3f : 1.0f;
    Vec3f centre = Vec3f(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)) * offset;
    Vec3f u = random_unit(), v;
    if (round % 8 == 2) {
      centre.z = 0.0f;
      u = Vec3f(1, 0, 0);
      v = Vec3f(0, 1, 0);
    } else {
      v = glm::normalize(glm::cross(u, random_unit()));
      u = glm::normalize(glm::cross(v, u));
    }
    const rt::FlatScene flat = make_fan(centre, u, v, radius, random);
    const TriangleCluster cluster = rt::make_cluster(flat, ids, kClusterWidth);
    const Vec3f normal = glm::normalize(glm::cross(u, v));
    for (int r = 0; r < 24; ++r) {
      // From either side of the disc, 1 to 20 radii away; aimed at the shared vertex, at a shared
      // edge's midpoint or at a ring vertex (exact zeros: the fallback), or at random.
      const float side = r % 2 == 0 ? 1.0f : -1.0f;
      const Vec3f origin = centre + radius * (side * uniform(1, 20) * normal + uniform(-3, 3) * u + uniform(-3, 3) * v);
      const unsigned spoke = 1u + unsigned(r) % kClusterWidth;
      const int kind = r % 4;
      const Vec3f target = kind == 0   ? flat.positions[0]
                           : kind == 1 ? 0.5f * (flat.positions[0] + flat.positions[spoke])
                           : kind == 2 ? flat.positions[spoke]
                                       : centre + radius * (uniform(-2, 2) * u + uniform(-2, 2) * v);
      rt::ShearedRay ray;
      rt::shear_ray(origin, target - origin, ray);
      const float tfar = r % 6 == 5 ? 0.5f : std::numeric_limits<float>::infinity();  // some end short of the disc
      const Answer base = ask(baseline, ray, cluster, 0.0f, tfar);
      if (avx2) {
        CHECK(ask(avx2, ray, cluster, 0.0f, tfar) == base);
        ++compared;
      }
      hits_found += base.found != 0;
      // The centre and the spoke midpoints are interior to the disc: a ray aimed at them must hit
      // some triangle, whatever rounding did to its direction.
      if (kind <= 1 && tfar > 1.0f) {
        CHECK(base.found != 0);
        (kind == 0 ? vertex_rays : edge_rays) += 1;
      }
    }
  }
  CHECK(vertex_rays > 1000);
  CHECK(edge_rays > 1000);
  CHECK(hits_found > 4000);
  if (avx2) CHECK(compared == 400 * 24);
}

// Random triangles, long and thin ones included, and random rays: the two builds must agree on
// every lane, found or not, whatever the cluster's lane count.
TEST_CASE("cluster kernel: both builds give the same bits on random clusters", "[accel][watertight]") {
  const IntersectCluster avx2 = rt::avx2_intersect_cluster();
  if (!avx2) {
    SUCCEED("this CPU has no AVX2: only the baseline build runs here");
    return;
  }
  const IntersectCluster baseline = &rt::cluster_kernel::baseline::intersect_cluster;
  std::mt19937_64 random(2024);
  const auto uniform = [&](float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(random); };
  int with_hits = 0;
  for (int round = 0; round < 2000; ++round) {
    const float scale = round % 3 == 0 ? 1e4f : round % 3 == 1 ? 1e-2f : 1.0f;
    rt::FlatScene flat;
    for (int i = 0; i < 3 * int(kClusterWidth); ++i)
      flat.positions.emplace_back(uniform(-1, 1) * scale, uniform(-1, 1) * scale, uniform(-1, 1) * scale);
    std::uint32_t ids[kClusterWidth];
    for (unsigned i = 0; i < kClusterWidth; ++i) {
      flat.triangles.push_back({3 * i, 3 * i + 1, 3 * i + 2});
      flat.material_ids.push_back(0);
      ids[i] = i;
    }
    const unsigned count = 1u + unsigned(round) % kClusterWidth;
    const TriangleCluster cluster = rt::make_cluster(flat, ids, count);
    const Vec3f origin(uniform(-2, 2) * scale, uniform(-2, 2) * scale, uniform(-2, 2) * scale);
    const Vec3f target = flat.positions[random() % flat.positions.size()];
    const Vec3f direction = round % 2 == 0 ? target - origin : Vec3f(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    rt::ShearedRay ray;
    rt::shear_ray(origin, direction, ray);
    const Answer base = ask(baseline, ray, cluster, 0.0f, std::numeric_limits<float>::infinity());
    CHECK(ask(avx2, ray, cluster, 0.0f, std::numeric_limits<float>::infinity()) == base);
    CHECK(base.found >> count == 0u);  // lanes past the count are never reported
    with_hits += base.found != 0;
  }
  CHECK(with_hits > 200);
}

}  // namespace
