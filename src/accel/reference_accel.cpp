#include "rt/accel/reference_accel.h"

#include <cmath>
#include <utility>

namespace rt {

namespace {

// a*b - c*d with the sign of the exact result (Kahan's algorithm: the rounding error of c*d is
// recovered exactly by an FMA, so the result has a small relative error and is zero only when the
// exact value is). Used where plain rounding may produce a zero of unknown true sign.
double difference_of_products(double a, double b, double c, double d) {
  const double cd = c * d;
  const double error = std::fma(-c, d, cd);
  const double ab_minus_cd = std::fma(a, b, -cd);
  return ab_minus_cd + error;
}

int max_dimension(const Vec3d& v) { return v.x > v.y ? (v.x > v.z ? 0 : 2) : (v.y > v.z ? 1 : 2); }

Vec3d permute(const Vec3d& v, int x, int y, int z) { return {v[x], v[y], v[z]}; }

}  // namespace

bool intersect_triangle_barycentric(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                    const Vec3d& p1, const Vec3d& p2, const Vec3d& p3, TriangleHitD& hit) {
  // Substituting lambda1 = 1 - lambda2 - lambda3 into the seed's 4x4 system leaves
  //   lambda2 e1 + lambda3 e2 - t d = s,   e1 = p2 - p1, e2 = p3 - p1, s = p0 - p1,
  // solved by Cramer's rule with scalar triple products (the same algebra as Moller & Trumbore,
  // "Fast, minimum storage ray-triangle intersection", JGT 1997, here in double precision).
  const Vec3d e1 = p2 - p1, e2 = p3 - p1;
  const Vec3d d_cross_e2 = glm::cross(direction, e2);
  const double det = glm::dot(e1, d_cross_e2);  // = det[e1 e2 -d]
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double inv_det = 1.0 / det;
  const Vec3d s = origin - p1;
  const double l2 = glm::dot(s, d_cross_e2) * inv_det;
  if (!(l2 >= 0.0 && l2 <= 1.0)) return false;
  const Vec3d s_cross_e1 = glm::cross(s, e1);
  const double l3 = glm::dot(direction, s_cross_e1) * inv_det;
  if (!(l3 >= 0.0) || !(1.0 - l2 - l3 >= 0.0)) return false;
  const double t = glm::dot(e2, s_cross_e1) * inv_det;
  if (!(t >= tnear && t <= tfar)) return false;
  hit = {t, l2, l3};
  return true;
}

bool intersect_triangle_watertight(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                   const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, TriangleHitD& hit) {
  // 0. Degenerate triangles first, in the triangle's own space: after the shear below, rounding can
  //    make collinear or repeated vertices look like a sliver with a small non-zero area.
  if (glm::cross(p1 - p0, p2 - p0) == Vec3d(0.0)) return false;

  // 1. Ray-centred frame: translate by the origin, permute so the direction's largest component
  //    is z (kz), keeping the winding of (kx, ky, kz) cyclic.
  const int kz = max_dimension(glm::abs(direction));
  if (direction[kz] == 0.0) return false;  // zero direction
  const int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
  const Vec3d d = permute(direction, kx, ky, kz);
  Vec3d q0 = permute(p0 - origin, kx, ky, kz), q1 = permute(p1 - origin, kx, ky, kz),
        q2 = permute(p2 - origin, kx, ky, kz);

  // 2. Shear so the ray becomes the +z axis (only x and y now; z is scaled in step 5).
  const double sx = -d.x / d.z, sy = -d.y / d.z, sz = 1.0 / d.z;
  q0.x += sx * q0.z;
  q0.y += sy * q0.z;
  q1.x += sx * q1.z;
  q1.y += sy * q1.z;
  q2.x += sx * q2.z;
  q2.y += sy * q2.z;

  // 3. Edge functions: twice the signed area of the ray's projection against each edge. Each is
  //    computed from the two vertices of its edge only, with the same formula (no FMA contraction,
  //    see CMakeLists), so a neighbour sharing the edge gets exactly the negated value. A zero is
  //    recomputed exactly-signed; both neighbours then see zero first and agree again.
  double e0 = q1.x * q2.y - q1.y * q2.x;
  double e1 = q2.x * q0.y - q2.y * q0.x;
  double e2 = q0.x * q1.y - q0.y * q1.x;
  if (e0 == 0.0) e0 = difference_of_products(q1.x, q2.y, q1.y, q2.x);
  if (e1 == 0.0) e1 = difference_of_products(q2.x, q0.y, q2.y, q0.x);
  if (e2 == 0.0) e2 = difference_of_products(q0.x, q1.y, q0.y, q1.x);

  // 4. Inside when no edge function has a sign opposite to another (zeros are on the boundary).
  if ((e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0)) return false;
  const double det = e0 + e1 + e2;
  if (det == 0.0 || !std::isfinite(det)) return false;  // ray in the triangle's plane, or degenerate

  // 5. Scaled distance along the ray, then t and the barycentrics.
  q0.z *= sz;
  q1.z *= sz;
  q2.z *= sz;
  const double inv_det = 1.0 / det;
  const double t = (e0 * q0.z + e1 * q1.z + e2 * q2.z) * inv_det;
  if (!(t >= tnear && t <= tfar)) return false;
  hit = {t, e1 * inv_det, e2 * inv_det};
  return true;
}

bool intersect_sphere(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar, const FlatSphere& sphere,
                      double& t) {
  const Vec3d o(sphere.object_from_world * Vec4d(origin, 1.0));
  const Vec3d d = Mat3d(sphere.object_from_world) * direction;
  const double a = glm::dot(d, d);
  if (!(a > 0.0) || !std::isfinite(a)) return false;
  const double half_b = glm::dot(o, d);
  const Vec3d f = o - (half_b / a) * d;
  const double discriminant = a * (1.0 - glm::dot(f, f));  // = half_b^2 - a c
  if (!(discriminant >= 0.0)) return false;
  const double c = glm::dot(o, o) - 1.0;
  const double q = -(half_b + std::copysign(std::sqrt(discriminant), half_b));
  // q = 0 only when half_b = 0 and the discriminant is 0: a tangent ray whose origin is on the
  // sphere, touching it at t = 0.
  double t0 = q != 0.0 ? c / q : 0.0, t1 = q / a;
  if (t0 > t1) std::swap(t0, t1);
  if (t0 >= tnear && t0 <= tfar) {
    t = t0;
    return true;
  }
  if (t1 >= tnear && t1 <= tfar) {
    t = t1;
    return true;
  }
  return false;
}

ReferenceAccel::ReferenceAccel(const FlatScene& scene, ReferenceTest test, const SurfaceTest* surface_test)
    : test_(test), spheres_(scene.spheres) {
  // Kept only when it tests some triangle, as the Embree backend does.
  for (std::uint32_t t = 0; surface_test && t < scene.triangle_count() && !surface_test_; ++t)
    if (surface_test->tested(t)) surface_test_ = surface_test;
  triangles_.reserve(scene.triangle_count());
  for (const Vec3u& tri : scene.triangles)
    triangles_.push_back({Vec3d(scene.positions[tri.x]), Vec3d(scene.positions[tri.y]), Vec3d(scene.positions[tri.z])});
}

bool ReferenceAccel::intersect_one(const TriangleD& tri, const Vec3d& origin, const Vec3d& direction, double tnear,
                                   double tfar, TriangleHitD& hit) const {
  return test_ == ReferenceTest::watertight
             ? intersect_triangle_watertight(origin, direction, tnear, tfar, tri.p0, tri.p1, tri.p2, hit)
             : intersect_triangle_barycentric(origin, direction, tnear, tfar, tri.p0, tri.p1, tri.p2, hit);
}

bool ReferenceAccel::counts(std::uint32_t triangle, const Vec3d& direction, const TriangleHitD& hit, bool occlusion) const {
  if (!surface_test_ || !surface_test_->tested(triangle)) return true;
  const auto b1 = static_cast<float>(hit.b1), b2 = static_cast<float>(hit.b2);
  return occlusion ? surface_test_->blocks(triangle, b1, b2, direction)
                   : surface_test_->hit_counts(triangle, b1, b2, direction);
}

Hit ReferenceAccel::intersect(const Ray& ray) const {
  const Vec3d origin(ray.origin), direction(ray.direction);
  TriangleHitD best{double(ray.tfar), 0.0, 0.0};
  std::uint32_t best_index = kNoPrimitive;
  for (std::size_t i = 0; i < triangles_.size(); ++i) {
    TriangleHitD hit;
    // Later triangles must be strictly closer to replace a hit, so equal t keeps the lowest index.
    if (intersect_one(triangles_[i], origin, direction, ray.tnear, best.t, hit) &&
        (best_index == kNoPrimitive || hit.t < best.t) &&
        counts(std::uint32_t(i), direction, hit, false)) {
      best = hit;
      best_index = static_cast<std::uint32_t>(i);
    }
  }
  for (std::size_t s = 0; s < spheres_.size(); ++s) {
    double t;
    if (intersect_sphere(origin, direction, ray.tnear, best.t, spheres_[s], t) &&
        (best_index == kNoPrimitive || t < best.t)) {
      best = {t, 0.0, 0.0};
      best_index = static_cast<std::uint32_t>(triangles_.size() + s);
    }
  }
  if (best_index == kNoPrimitive) return Hit{};
  return Hit{static_cast<float>(best.t), static_cast<float>(best.b1), static_cast<float>(best.b2), best_index};
}

bool ReferenceAccel::occluded(const Ray& ray) const {
  const Vec3d origin(ray.origin), direction(ray.direction);
  TriangleHitD hit;
  for (std::size_t i = 0; i < triangles_.size(); ++i)
    if (intersect_one(triangles_[i], origin, direction, ray.tnear, ray.tfar, hit) &&
        counts(std::uint32_t(i), direction, hit, true))
      return true;
  double t;
  for (const FlatSphere& sphere : spheres_)
    if (intersect_sphere(origin, direction, ray.tnear, ray.tfar, sphere, t)) return true;
  return false;
}

}  // namespace rt
