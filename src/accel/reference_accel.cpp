#include "rt/accel/reference_accel.h"

namespace rt {

namespace {

// The seed's solve for one triangle given as p1 and the edges e1 = p2 - p1, e2 = p3 - p1.
// Substituting lambda1 = 1 - lambda2 - lambda3 into the seed's 4x4 system leaves
//   lambda2 e1 + lambda3 e2 - t d = s,   s = p0 - p1,
// solved by Cramer's rule with scalar triple products (the same algebra as Moller & Trumbore,
// "Fast, minimum storage ray-triangle intersection", JGT 1997, here in double precision).
inline bool solve_barycentric(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                              const Vec3d& p1, const Vec3d& e1, const Vec3d& e2, double& t, double& lambda2,
                              double& lambda3) {
  const Vec3d d_cross_e2 = glm::cross(direction, e2);
  const double det = glm::dot(e1, d_cross_e2);  // = det[e1 e2 -d]
  if (det == 0.0) return false;                 // ray parallel to the plane, or zero-area triangle
  const double inv_det = 1.0 / det;
  const Vec3d s = origin - p1;
  const double l2 = glm::dot(s, d_cross_e2) * inv_det;
  if (!(l2 >= 0.0 && l2 <= 1.0)) return false;
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

}  // namespace

bool intersect_triangle_barycentric(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                    const Vec3d& p1, const Vec3d& p2, const Vec3d& p3, double& t,
                                    double& lambda2, double& lambda3) {
  return solve_barycentric(origin, direction, tnear, tfar, p1, p2 - p1, p3 - p1, t, lambda2, lambda3);
}

ReferenceAccel::ReferenceAccel(const FlatScene& scene) {
  triangles_.reserve(scene.triangle_count());
  for (const Vec3u& tri : scene.triangles) {
    const Vec3d p1(scene.positions[tri.x]), p2(scene.positions[tri.y]), p3(scene.positions[tri.z]);
    // Precomputing the edges gives bit-identical results: the same subtraction, done once.
    triangles_.push_back({p1, p2 - p1, p3 - p1});
  }
}

Hit ReferenceAccel::intersect(const Ray& ray) const {
  const Vec3d origin(ray.origin), direction(ray.direction);
  double best_t = ray.tfar, best_u = 0.0, best_v = 0.0;
  std::uint32_t best = kNoTriangle;
  for (std::size_t i = 0; i < triangles_.size(); ++i) {
    const TriangleD& tri = triangles_[i];
    double t, u, v;
    // Later triangles must be strictly closer to replace a hit, so equal t keeps the lowest index.
    if (solve_barycentric(origin, direction, ray.tnear, best_t, tri.p1, tri.e1, tri.e2, t, u, v) &&
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
    if (solve_barycentric(origin, direction, ray.tnear, ray.tfar, tri.p1, tri.e1, tri.e2, t, u, v)) return true;
  }
  return false;
}

}  // namespace rt
