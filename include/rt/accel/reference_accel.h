#pragma once
// The reference intersector: the seed's barycentric solve in double precision, brute force over
// every triangle. Slow by design (O(triangles) per ray) and meant to be right, so that the
// Embree backend can be checked against it.

#include <vector>

#include "rt/accel/accel.h"

namespace rt {

// Solves the seed's system  lambda1 p1 + lambda2 p2 + lambda3 p3 - t d = p0,
// lambda1 + lambda2 + lambda3 = 1  for one triangle, in double precision, by Cramer's rule on
// the 3x3 system left after eliminating lambda1. Inputs are world space. Returns true and
// writes (t, lambda2, lambda3) when all lambdas >= 0 and tnear <= t <= tfar; a triangle the
// ray is parallel to, or a degenerate one (zero determinant), is never hit.
bool intersect_triangle_barycentric(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                    const Vec3d& p1, const Vec3d& p2, const Vec3d& p3, double& t,
                                    double& lambda2, double& lambda3);

// Holds double-precision copies of the float32 vertices Embree sees (exactly representable, so
// both backends intersect the same triangles). Equal t goes to the lowest triangle index.
class ReferenceAccel final : public Accel {
 public:
  explicit ReferenceAccel(const FlatScene& scene);

  Hit intersect(const Ray& ray) const override;
  bool occluded(const Ray& ray) const override;
  std::string_view name() const override { return "reference"; }

 private:
  struct TriangleD {
    Vec3d p1, e1, e2;  // first vertex and the edges to the other two
  };
  std::vector<TriangleD> triangles_;
};

}  // namespace rt
