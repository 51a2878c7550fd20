#pragma once
// The watertight float32 ray/triangle test of Woop, Benthin and Wald, "Watertight Ray/Triangle
// Intersection" (JCGT 2(1), 2013), run on clusters of up to eight triangles at once (one SIMD lane
// per triangle). EmbreeKernel::watertight makes each cluster one Embree user primitive. Private to
// the accel module.

#include <cstdint>
#include <vector>

#include "rt/accel/accel.h"
#include "rt/core/math.h"
#include "rt/flatten/flatten.h"

namespace rt {

inline constexpr unsigned kClusterWidth = 8;

// Up to kClusterWidth triangles, world space, float32 (FlatScene's vertices, unchanged), laid out
// lane by lane: vertex k's coordinate on axis a of the triangle in lane l is v[k][a][l]. Lanes at
// and past `count` repeat lane 0 and are never reported.
struct alignas(32) TriangleCluster {
  float v[3][3][kClusterWidth];
  std::uint32_t triangle[kClusterWidth];  // FlatScene triangle number of each lane
  std::uint32_t count = 0;
  Vec3f lower{0.0f}, upper{0.0f};  // bounds of the cluster's vertices
};

// Packs `triangles` (FlatScene numbers, at most kClusterWidth) of `flat` into one cluster.
TriangleCluster make_cluster(const FlatScene& flat, const std::uint32_t* triangles, unsigned count);

// Whether the reference's watertight test rejects triangle `triangle` of `flat` for every ray
// (zero area in double precision: repeated or collinear vertices). Such triangles are left out of
// the clusters, as intersect_triangle_watertight rejects them first.
bool is_degenerate(const FlatScene& flat, std::uint32_t triangle);

// A ray set up for the test, world space, float32: the axis permutation that makes the direction's
// largest component z, the origin's coordinates in that order, and the shear that maps the
// direction onto +z.
struct ShearedRay {
  int kx = 0, ky = 1, kz = 2;
  float ox = 0.0f, oy = 0.0f, oz = 0.0f;  // origin[kx], origin[ky], origin[kz]
  float sx = 0.0f, sy = 0.0f, sz = 0.0f;
  bool valid = false;  // false for a zero or non-finite direction, which hits nothing
};
// Sets `ray` up for `origin` and `direction` (world space, float32). Written in place: a returned
// copy is read back wider than it was written, which stalls store forwarding in the packet loops.
void shear_ray(const Vec3f& origin, const Vec3f& direction, ShearedRay& ray);

// Per lane of a cluster: ray parameter and barycentrics of vertices 1 and 2 of a hit.
struct ClusterHits {
  float t[kClusterWidth], b1[kClusterWidth], b2[kClusterWidth];
};

// The lanes of `cluster` whose triangle `ray` hits with tnear <= t <= tfar, as a bit mask (bit l:
// lane l), their hits in `hits` (other lanes of `hits` are left undefined). Watertight: along an
// edge or through a vertex shared by triangles of one mesh, at least one of them is hit (zeros are
// on the boundary, so both may be), whatever cluster each is in. An edge function that rounds to
// zero in float32 is recomputed exactly in double (the products of two floats are exact there), so
// every sign is exact.
using IntersectCluster = unsigned (*)(const ShearedRay& ray, const TriangleCluster& cluster, float tnear,
                                      float tfar, ClusterHits& hits);

// Two builds of that test, baseline x86-64 and AVX2 (triangle_clusters_avx2.cpp). Both compute
// every lane with the same float32 operations in the same order, without contraction, so they
// give the same bits, and a vertex shared by two triangles is sheared to the same coordinates
// whichever lane or cluster holds it.
namespace cluster_kernel {
namespace baseline {
unsigned intersect_cluster(const ShearedRay& ray, const TriangleCluster& cluster, float tnear, float tfar,
                           ClusterHits& hits);
}
namespace avx2 {
unsigned intersect_cluster(const ShearedRay& ray, const TriangleCluster& cluster, float tnear, float tfar,
                           ClusterHits& hits);
}
}  // namespace cluster_kernel

// The AVX2 build, or nullptr when the CPU lacks AVX2.
IntersectCluster avx2_intersect_cluster();
// The AVX2 build where the CPU has it, else the baseline.
IntersectCluster best_intersect_cluster();

}  // namespace rt
