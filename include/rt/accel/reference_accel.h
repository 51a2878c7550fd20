#pragma once
// The reference intersectors: brute force over every triangle in double precision. Slow by
// design (O(triangles) per ray) and meant to be right, so that Embree can be checked against them.

#include <vector>

#include "rt/accel/accel.h"

namespace rt {

// Result of one ray/triangle test: ray parameter t and the barycentric weights b1, b2 of the
// second and third vertex (the point is (1 - b1 - b2) p0 + b1 p1 + b2 p2).
struct TriangleHitD {
  double t = 0.0, b1 = 0.0, b2 = 0.0;
};

// The seed's solve of  lambda1 p1 + lambda2 p2 + lambda3 p3 - t d = p0, sum lambda = 1,  in double
// by Cramer's rule on the 3x3 system left after eliminating lambda1. World space. Hits when all
// lambdas >= 0 and tnear <= t <= tfar; a parallel ray or a zero-area triangle never hits.
// Not watertight: rounding can let a ray slip between two triangles that share an edge.
bool intersect_triangle_barycentric(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                    const Vec3d& p1, const Vec3d& p2, const Vec3d& p3, TriangleHitD& hit);

// Watertight ray/triangle test of Woop, Benthin and Wald, "Watertight Ray/Triangle Intersection",
// JCGT 2(1), 2013 (as in pbrt-v4's IntersectTriangle), in double precision. The vertices are moved
// into a ray-centred frame where the ray is the +z axis; the three 2D edge functions then decide
// inside/outside. An edge function that rounds to zero is recomputed with an exactly-signed
// difference of products, so two triangles sharing an edge always agree on which side of it the
// ray passes: no ray slips through a closed mesh. Edges and vertices count as inside.
// Degenerate triangles (zero area, collinear or repeated vertices) and zero directions never hit
// and never produce NaN. Hits when tnear <= t <= tfar.
bool intersect_triangle_watertight(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                                   const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, TriangleHitD& hit);

// Ray against an analytic sphere (an ellipsoid in world space), in double precision: the ray is
// mapped into the unit sphere's object space (the parameter t is unchanged by the affine map) and
// |o + t d|^2 = 1 solved with the discriminant formed as a (1 - |f|^2), f = o - (o.d / a) d the
// point of closest approach, and the smaller root taken from the larger by Vieta's formula, which
// avoids the cancellations of the textbook b^2 - 4ac (Haines, Guenther and Akenine-Moller,
// "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems, 2019, ch. 7). Returns
// the nearest root in [tnear, tfar] in `t`; a zero direction never hits.
bool intersect_sphere(const Vec3d& origin, const Vec3d& direction, double tnear, double tfar, const FlatSphere& sphere,
                      double& t);

enum class ReferenceTest { watertight, barycentric };

// Holds double-precision copies of the float32 vertices Embree sees (exactly representable, so
// all backends intersect the same triangles) and of the spheres. Among equal t the lowest
// primitive index wins.
class ReferenceAccel final : public Accel {
 public:
  // `surface_test` (may be null) must outlive the accel.
  ReferenceAccel(const FlatScene& scene, ReferenceTest test, const SurfaceTest* surface_test = nullptr);

  Hit intersect(const Ray& ray) const override;
  bool occluded(const Ray& ray) const override;
  std::string_view name() const override {
    return test_ == ReferenceTest::watertight ? "reference" : "reference-barycentric";
  }
  const SurfaceTest* surface_test() const override { return surface_test_; }

 private:
  struct TriangleD {
    Vec3d p0, p1, p2;
  };
  bool intersect_one(const TriangleD& tri, const Vec3d& origin, const Vec3d& direction, double tnear, double tfar,
                     TriangleHitD& hit) const;
  // Whether `hit` on triangle `triangle` counts for a ray along `direction` (occlusion: blocks it).
  bool counts(std::uint32_t triangle, const Vec3d& direction, const TriangleHitD& hit, bool occlusion) const;

  ReferenceTest test_;
  const SurfaceTest* surface_test_ = nullptr;  // may be null
  std::vector<TriangleD> triangles_;
  std::vector<FlatSphere> spheres_;
};

}  // namespace rt
