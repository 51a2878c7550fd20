// Built twice: as itself (baseline x86-64, SSE2) and included by triangle_clusters_avx2.cpp with
// RT_TRIANGLE_CLUSTERS_AVX2 and -mavx2 (src/CMakeLists.txt). The kernel's helpers have internal
// linkage, so the AVX2 build defines no function another object could link in place of its own.

#include "triangle_clusters.h"

#include <immintrin.h>

#include <cmath>
#include <cstring>

namespace rt {

namespace cluster_kernel {
#ifdef RT_TRIANGLE_CLUSTERS_AVX2
namespace avx2 {
#else
namespace baseline {
#endif

namespace {

// Eight float32 lanes (GCC/Clang vector extension: one AVX register, or two SSE ones).
using Lanes = float __attribute__((vector_size(32)));
using Mask = int __attribute__((vector_size(32)));

// x in every lane, its sign of zero kept (x - +0 is x for every x; Lanes{} + x would turn -0 into +0,
// unlike the scalar arithmetic of shear_lane). Vectors go by reference only: returned by value, a
// 32-byte vector has a different ABI in the baseline build (-Wpsabi).
[[gnu::always_inline]] inline void broadcast(Lanes& out, float x) { out = x - Lanes{}; }

[[gnu::always_inline]] inline void load(Lanes& out, const float* p) { std::memcpy(&out, p, sizeof out); }

[[gnu::always_inline]] inline void store(float (&p)[kClusterWidth], const Lanes& in) {
  static_assert(sizeof p == sizeof in);
  std::memcpy(p, &in, sizeof in);
}

// Bit l set where lane l of `m` (all ones or zero, as comparisons give) is set: the sign bits, one
// movmskps (two without AVX). Through a copy: GCC 12 at -O1 under ASan miscompiled subscripts of a
// vector bound to a reference.
[[gnu::always_inline]] inline unsigned bits(const Mask& m) {
#ifdef RT_TRIANGLE_CLUSTERS_AVX2
  __m256 v;
  std::memcpy(&v, &m, sizeof v);
  return unsigned(_mm256_movemask_ps(v));
#else
  __m128 v[2];
  static_assert(sizeof v == sizeof m);
  std::memcpy(v, &m, sizeof v);
  return unsigned(_mm_movemask_ps(v[0])) | (unsigned(_mm_movemask_ps(v[1])) << 4);
#endif
}

// Lane l of `cluster` sheared as intersect_cluster's vectors do it, with the same float32
// operations in the same order: q[k] = (x, y, z) of vertex k, z already scaled by sz.
void shear_lane(const ShearedRay& ray, const TriangleCluster& cluster, unsigned l, float (&q)[3][3]) {
  for (int k = 0; k < 3; ++k) {
    const float z = cluster.v[k][ray.kz][l] - ray.oz;
    q[k][0] = (cluster.v[k][ray.kx][l] - ray.ox) + ray.sx * z;
    q[k][1] = (cluster.v[k][ray.ky][l] - ray.oy) + ray.sy * z;
    q[k][2] = ray.sz * z;
  }
}

// One lane again, in double from the same float32 sheared coordinates (x, y, and z already scaled
// by sz): every product of two floats is exact in double, so each edge function is the exact value
// rounded once and its sign is exact. Returns whether the lane is hit.
bool intersect_lane_exactly(const float (&q)[3][3], float tnear, float tfar, float& t, float& b1, float& b2) {
  const auto edge = [&](int i, int j) {
    return double(q[i][0]) * double(q[j][1]) - double(q[i][1]) * double(q[j][0]);
  };
  const double e0 = edge(1, 2), e1 = edge(2, 0), e2 = edge(0, 1);
  if ((e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0)) return false;
  const double det = e0 + e1 + e2;
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double inv_det = 1.0 / det;
  const double td = (e0 * double(q[0][2]) + e1 * double(q[1][2]) + e2 * double(q[2][2])) * inv_det;
  if (!(td >= double(tnear) && td <= double(tfar))) return false;
  t = float(td);
  b1 = float(e1 * inv_det);
  b2 = float(e2 * inv_det);
  return true;
}

// Step 3's exact recomputation, for the lanes of `lanes` (where some edge function rounded to
// zero): `found` with the bits of those that are hit added. Each lane is sheared again in scalar float32 rather than
// read back from intersect_cluster's vectors, which would keep them on the stack in every call;
// out of line and a tail call, so that the common path needs no stack frame for it.
[[gnu::noinline]] unsigned intersect_lanes_exactly(const ShearedRay& ray, const TriangleCluster& cluster,
                                                   unsigned lanes, float tnear, float tfar, ClusterHits& hits,
                                                   unsigned found) {
  for (; lanes != 0; lanes &= lanes - 1) {
    const unsigned l = unsigned(__builtin_ctz(lanes));
    float q[3][3];
    shear_lane(ray, cluster, l, q);
    if (intersect_lane_exactly(q, tnear, tfar, hits.t[l], hits.b1[l], hits.b2[l])) found |= 1u << l;
  }
  return found;
}

}  // namespace

unsigned intersect_cluster(const ShearedRay& ray, const TriangleCluster& cluster, float tnear, float tfar,
                           ClusterHits& hits) {
  if (!ray.valid) return 0;
  Lanes ox, oy, oz, sx, sy, sz;
  broadcast(ox, ray.ox);
  broadcast(oy, ray.oy);
  broadcast(oz, ray.oz);
  broadcast(sx, ray.sx);
  broadcast(sy, ray.sy);
  broadcast(sz, ray.sz);
  // Step 1 and 2 of the reference: vertex minus origin (float32, once per vertex), permuted, sheared.
  Lanes qx[3], qy[3], qz[3];
  for (int k = 0; k < 3; ++k) {
    Lanes vx, vy, vz;
    load(vx, cluster.v[k][ray.kx]);
    load(vy, cluster.v[k][ray.ky]);
    load(vz, cluster.v[k][ray.kz]);
    const Lanes z = vz - oz;
    qx[k] = (vx - ox) + sx * z;
    qy[k] = (vy - oy) + sy * z;
    qz[k] = sz * z;
  }
  // Step 3: edge functions, each from its edge's two vertices only.
  const Lanes e0 = qx[1] * qy[2] - qy[1] * qx[2];
  const Lanes e1 = qx[2] * qy[0] - qy[2] * qx[0];
  const Lanes e2 = qx[0] * qy[1] - qy[0] * qx[1];
  const Lanes zero{};
  const Mask negative = (e0 < zero) | (e1 < zero) | (e2 < zero);
  const Mask positive = (e0 > zero) | (e1 > zero) | (e2 > zero);
  const Mask rounded_to_zero = (e0 == zero) | (e1 == zero) | (e2 == zero);
  const unsigned in_use = (1u << cluster.count) - 1u;
  const unsigned inside = bits(~(negative & positive) & ~rounded_to_zero) & in_use;
  const unsigned exact = bits(rounded_to_zero) & in_use;
  if ((inside | exact) == 0) return 0;  // most clusters a ray reaches: no division needed
  unsigned found = 0;
  if (inside != 0) {
    // Steps 4 and 5: t and the barycentrics, for the lanes whose edge functions agree.
    const Lanes det = e0 + e1 + e2;
    const Lanes inv_det = (Lanes{} + 1.0f) / det;
    const Lanes t = (e0 * qz[0] + e1 * qz[1] + e2 * qz[2]) * inv_det;
    // det finite and non-zero, and not so small that 1 / det overflows (x - x is NaN for inf and NaN).
    const Mask finite = ((det - det) == zero) & ((inv_det - inv_det) == zero);
    const Mask accepted = (det != zero) & finite & (t >= (Lanes{} + tnear)) & (t <= (Lanes{} + tfar));
    found = inside & bits(accepted);
    // Every lane is written; the caller reads the found ones, and the exact ones below are not
    // among `inside`.
    store(hits.t, t);
    store(hits.b1, e1 * inv_det);
    store(hits.b2, e2 * inv_det);
  }
  return exact != 0 ? intersect_lanes_exactly(ray, cluster, exact, tnear, tfar, hits, found) : found;
}

}  // namespace (baseline or avx2)
}  // namespace cluster_kernel

#ifndef RT_TRIANGLE_CLUSTERS_AVX2

TriangleCluster make_cluster(const FlatScene& flat, const std::uint32_t* triangles, unsigned count) {
  TriangleCluster cluster;
  cluster.count = count;
  cluster.lower = Vec3f(kInfinity);
  cluster.upper = Vec3f(-kInfinity);
  for (unsigned l = 0; l < kClusterWidth; ++l) {
    const std::uint32_t triangle = triangles[l < count ? l : 0];
    cluster.triangle[l] = triangle;
    const Vec3u tri = flat.triangles[triangle];
    const Vec3f p[3] = {flat.positions[tri.x], flat.positions[tri.y], flat.positions[tri.z]};
    for (int k = 0; k < 3; ++k) {
      for (int a = 0; a < 3; ++a) cluster.v[k][a][l] = p[k][a];
      cluster.lower = glm::min(cluster.lower, p[k]);
      cluster.upper = glm::max(cluster.upper, p[k]);
    }
  }
  return cluster;
}

bool is_degenerate(const FlatScene& flat, std::uint32_t triangle) {
  const Vec3u tri = flat.triangles[triangle];
  const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
  return glm::cross(p1 - p0, p2 - p0) == Vec3d(0.0);
}

void shear_ray(const Vec3f& origin, const Vec3f& direction, ShearedRay& ray) {
  const Vec3f a = glm::abs(direction);
  ray.kz = a.x > a.y ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2);
  ray.kx = (ray.kz + 1) % 3;
  ray.ky = (ray.kx + 1) % 3;
  ray.ox = origin[ray.kx];
  ray.oy = origin[ray.ky];
  ray.oz = origin[ray.kz];
  const float dz = direction[ray.kz];
  ray.valid = dz != 0.0f && std::isfinite(dz) && std::isfinite(direction[ray.kx]) && std::isfinite(direction[ray.ky]);
  if (!ray.valid) return;
  // As intersect_triangle_watertight (reference_accel.cpp), in float32.
  ray.sx = -direction[ray.kx] / dz;
  ray.sy = -direction[ray.ky] / dz;
  ray.sz = 1.0f / dz;
}

IntersectCluster avx2_intersect_cluster() {
  __builtin_cpu_init();  // idempotent; needed when called before the constructors have run
  return __builtin_cpu_supports("avx2") ? &cluster_kernel::avx2::intersect_cluster : nullptr;
}

IntersectCluster best_intersect_cluster() {
  static const IntersectCluster best =
      avx2_intersect_cluster() ? avx2_intersect_cluster() : &cluster_kernel::baseline::intersect_cluster;
  return best;
}

#endif

}  // namespace rt
