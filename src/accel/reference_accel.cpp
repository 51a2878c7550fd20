#include "rt/accel/reference_accel.h"

namespace rt {

bool intersect_triangle_barycentric(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                    const Vec3d& p1, const Vec3d& p2, const Vec3d& p3, double& t,
                                    double& lambda2, double& lambda3) {
  // Substituting lambda1 = 1 - lambda2 - lambda3 into the seed's 4x4 system leaves
  //   lambda2 e1 + lambda3 e2 - t d = s,   e1 = p2 - p1, e2 = p3 - p1, s = p0 - p1,
  // solved by Cramer's rule with scalar triple products (the same algebra as Moller & Trumbore,
  // "Fast, minimum storage ray-triangle intersection", JGT 1997, here in double precision).
  const Vec3d e1 = p2 - p1, e2 = p3 - p1, s = origin - p1;
  const Vec3d d_cross_e2 = glm::cross(direction, e2);
  const double det = glm::dot(e1, d_cross_e2);  // = det[e1 e2 -d]
  if (det == 0.0) return false;                 // ray parallel to the plane, or zero-area triangle
  const double inv_det = 1.0 / det;
  const double l2 = glm::dot(s, d_cross_e2) * inv_det;
  if (!(l2 >= 0.0)) return false;
  const Vec3d s_cross_e1 = glm::cross(s, e1);
  const double l3 = glm::dot(direction, s_cross_e1) * inv_det;
  if (!(l3 >= 0.0) || !(1.0 - l2 - l3 >= 0.0)) return false;
  const double hit_t = glm::dot(e2, s_cross_e1) * inv_det;
  if (!(hit_t >= tnear && hit_t <= tfar)) return false;
  t = hit_t;
  lambda2 = l2;
  lambda3 = l3;
  return true;
}

ReferenceAccel::ReferenceAccel(const FlatScene& scene) {
  triangles_.reserve(scene.triangle_count());
  for (const Vec3u& tri : scene.triangles)
    triangles_.push_back({Vec3d(scene.positions[tri.x]), Vec3d(scene.positions[tri.y]), Vec3d(scene.positions[tri.z])});
}

Hit ReferenceAccel::intersect(const Ray& ray) const {
  const Vec3d origin(ray.origin), direction(ray.direction);
  double best_t = ray.tfar, best_u = 0.0, best_v = 0.0;
  std::uint32_t best = kNoTriangle;
  for (std::size_t i = 0; i < triangles_.size(); ++i) {
    const TriangleD& tri = triangles_[i];
    double t, u, v;
    // Shrinking tfar to the best t so far keeps the closest hit; an equal t later is rejected
    // only if strictly farther, so the lowest index wins ties.
    if (intersect_triangle_barycentric(origin, direction, ray.tnear, best_t, tri.p1, tri.p2, tri.p3, t, u, v) &&
        (best == kNoTriangle || t < best_t)) {
      best_t = t;
      best_u = u;
      best_v = v;
      best = static_cast<std::uint32_t>(i);
    }
  }
  if (best == kNoTriangle) return Hit{};
  return Hit{static_cast<float>(best_t), static_cast<float>(best_u), static_cast<float>(best_v), best};
}

bool ReferenceAccel::occluded(const Ray& ray) const {
  const Vec3d origin(ray.origin), direction(ray.direction);
  for (const TriangleD& tri : triangles_) {
    double t, u, v;
    if (intersect_triangle_barycentric(origin, direction, ray.tnear, ray.tfar, tri.p1, tri.p2, tri.p3, t, u, v))
      return true;
  }
  return false;
}

}  // namespace rt
