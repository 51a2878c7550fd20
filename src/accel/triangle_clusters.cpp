#include "triangle_clusters.h"

#include <cmath>
#include <cstring>

namespace rt {

namespace {

// Eight float32 lanes (GCC/Clang vector extension: one AVX register, or two SSE ones). Helpers take
// and return them by reference only: a 32-byte vector passed by value changes the ABI between the
// AVX2 and baseline clones, which Clang rejects outright.
using Lanes = float __attribute__((vector_size(32)));
using Mask = int __attribute__((vector_size(32)));

[[gnu::always_inline]] inline void load(Lanes& out, const float (&p)[kClusterWidth]) {
  static_assert(sizeof out == sizeof p);
  std::memcpy(&out, p, sizeof out);
}

[[gnu::always_inline]] inline unsigned bits(const Mask& m) {
  // Through a copy: GCC 12 at -O1 under ASan miscompiled subscripts of a vector bound to a
  // reference (-Wmaybe-uninitialized on the lane index, and the sanitizer build lost hits).
  int lanes[kClusterWidth];
  static_assert(sizeof lanes == sizeof m);
  std::memcpy(lanes, &m, sizeof lanes);
  unsigned out = 0;
  for (unsigned l = 0; l < kClusterWidth; ++l) out |= (lanes[l] != 0 ? 1u : 0u) << l;
  return out;
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

}  // namespace

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

ShearedRay shear_ray(const Vec3f& origin, const Vec3f& direction) {
  ShearedRay ray;
  ray.origin = origin;
  const Vec3f a = glm::abs(direction);
  ray.kz = a.x > a.y ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2);
  ray.kx = (ray.kz + 1) % 3;
  ray.ky = (ray.kx + 1) % 3;
  const float dz = direction[ray.kz];
  ray.valid = dz != 0.0f && std::isfinite(dz) && std::isfinite(direction[ray.kx]) && std::isfinite(direction[ray.ky]);
  if (!ray.valid) return ray;
  // As intersect_triangle_watertight (reference_accel.cpp), in float32.
  ray.sx = -direction[ray.kx] / dz;
  ray.sy = -direction[ray.ky] / dz;
  ray.sz = 1.0f / dz;
  return ray;
}

// Two builds, AVX2 and baseline x86-64, chosen once by the loader (an ifunc). Both compute every
// lane with the same operations in the same order, without contraction (CMakeLists), so a vertex
// shared by two triangles is sheared to the same coordinates whichever lane or cluster holds it.
[[gnu::target_clones("avx2", "default")]]
unsigned intersect_cluster(const ShearedRay& ray, const TriangleCluster& cluster, float tnear, float tfar,
                           ClusterHits& hits) {
  if (!ray.valid) return 0;
  const int kx = ray.kx, ky = ray.ky, kz = ray.kz;
  // Lanes{} + x broadcasts x to every lane.
  const Lanes ox = Lanes{} + ray.origin[kx], oy = Lanes{} + ray.origin[ky], oz = Lanes{} + ray.origin[kz];
  const Lanes sx = Lanes{} + ray.sx, sy = Lanes{} + ray.sy, sz = Lanes{} + ray.sz;
  // Step 1 and 2 of the reference: vertex minus origin (float32, once per vertex), permuted, sheared.
  Lanes qx[3], qy[3], qz[3];
  for (int k = 0; k < 3; ++k) {
    Lanes vx, vy, vz;
    load(vx, cluster.v[k][kx]);
    load(vy, cluster.v[k][ky]);
    load(vz, cluster.v[k][kz]);
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
  const Mask agree = ~(negative & positive) & ~rounded_to_zero;
  const unsigned inside = bits(agree) & in_use;
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
    const Lanes b1 = e1 * inv_det, b2 = e2 * inv_det;
    for (unsigned lanes = found; lanes != 0; lanes &= lanes - 1) {
      const unsigned l = unsigned(__builtin_ctz(lanes));
      hits.t[l] = t[l];
      hits.b1[l] = b1[l];
      hits.b2[l] = b2[l];
    }
  }
  // Step 3's exact recomputation, for the lanes where some edge function rounded to zero.
  for (unsigned lanes = exact; lanes != 0; lanes &= lanes - 1) {
    const unsigned l = unsigned(__builtin_ctz(lanes));
    const float q[3][3] = {{qx[0][l], qy[0][l], qz[0][l]}, {qx[1][l], qy[1][l], qz[1][l]}, {qx[2][l], qy[2][l], qz[2][l]}};
    if (intersect_lane_exactly(q, tnear, tfar, hits.t[l], hits.b1[l], hits.b2[l])) found |= 1u << l;
  }
  return found;
}

}  // namespace rt
