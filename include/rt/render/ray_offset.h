#pragma once
// Where secondary rays start, and where shadow rays stop: the self-intersection policy, in one place.

#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>

#include <glm/geometric.hpp>

#include "rt/accel/accel.h"

namespace rt {

// robust: offsets derived from the floating-point error of the hit point and of a float32
// ray/triangle test (scale-independent; the default). fixed: a constant distance `epsilon` in world
// units, the classic textbook choice, kept so the difference can be measured.
struct RayOffset {
  enum class Mode { robust, fixed };
  Mode mode = Mode::robust;
  double epsilon = 1e-4;  // world units; fixed mode only
};

// Parses "robust" or "fixed:EPS" (EPS a positive number, e.g. fixed:1e-4); throws InputError.
RayOffset parse_ray_offset(std::string_view text);
std::string to_string(const RayOffset& offset);

// The surface a secondary ray leaves: a point on a triangle with what offsetting needs, computed
// once per hit and shared by all rays spawned there. World space, double.
struct SurfacePoint {
  Vec3d point;             // (1 - b1 - b2) p0 + b1 p1 + b2 p2: on the triangle up to ~1e-16 relative
  Vec3d geometric_normal;  // unit length, along (p1 - p0) x (p2 - p0)
  double error_bound = 0;  // world units; see make_surface_point
};

// The point with barycentrics (b1, b2) on triangle (p0, p1, p2), its geometric normal, and a bound
// on how far off the triangle's plane rounding can make a float32 ray/triangle test believe a ray
// origin near that point is (see the derivation in ray_offset.cpp). A zero-area triangle gets a
// zero normal.
SurfacePoint make_surface_point(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, double b1, double b2);

// The unit shading normal at a hit from its interpolated vertex normal (world space, double):
// `interpolated` normalised, or the surface's geometric normal where opposite vertex normals cancel
// to zero, as in pbrt-v4's Triangle::InteractionFromIntersection. Normalising zero would give NaN,
// and a ray leaving along it makes Debian's Embree, built with assertions, abort the process.
inline Vec3d shading_normal(const Vec3d& interpolated, const Vec3d& geometric_normal) {
  return glm::dot(interpolated, interpolated) > 0.0 ? glm::normalize(interpolated) : geometric_normal;
}

// What make_surface_point derives from the triangle alone, for a triangle whose points are made many
// times (an emitter's light samples): its geometric normal and the edge part of the error bound.
struct TriangleFrame {
  Vec3d geometric_normal{0.0};  // unit, or zero for a zero-area triangle
  double edge_term = 0.0;       // (4 + 2 kappa) x the longest edge, world units (see ray_offset.cpp)
};
TriangleFrame make_triangle_frame(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2);

// make_surface_point(p0, p1, p2, b1, b2) bit for bit, `frame` being make_triangle_frame(p0, p1, p2).
SurfacePoint make_surface_point(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, const TriangleFrame& frame,
                                double b1, double b2);

// The point where a ray (world space; origin and direction as traced, t from the Hit) meets an
// analytic sphere, with its outward unit normal as geometric normal. The point is computed in the
// sphere's object space and projected back onto the unit sphere (pbrt's reprojection), so it lies
// on the surface to double rounding whatever error t carries. error_bound: the float32 rounding of
// an origin near the point plus a generous bound (2^-40 relative) on the double-precision sphere
// test, times the same safety factor as for triangles.
SurfacePoint make_sphere_surface_point(const FlatSphere& sphere, const Vec3d& origin, const Vec3d& direction, double t);

// The arithmetic of offset_ray_origin and shadow_ray_tfar in pieces, for callers that compute many
// rays at once and must round exactly as those do (the batch shader, src/render/batch_shade.cpp).
namespace ray_offset_detail {

// std::nextafter(f, +inf) (up) or std::nextafter(f, -inf), for f not NaN and not the infinity it
// steps towards, on the bits: the float32 ordering of non-negative values is their integers' and
// of negative ones the reverse, and from either zero the next is the smallest subnormal.
inline float next_float(float f, bool up) {
  if (f == 0.0f) return up ? 0x1p-149f : -0x1p-149f;
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>((f > 0.0f) == up ? bits + 1 : bits - 1);
}

// One coordinate of a robust origin: p rounded to float32 and, when rounding moved it against
// `away` (towards the surface), one float further along `away`, so the offset survives.
inline float round_away(double p, double away) {
  const float f = static_cast<float>(p);
  if (away > 0.0 && double(f) < p) return next_float(f, true);
  if (away < 0.0 && double(f) > p) return next_float(f, false);
  return f;
}

// Unit roundoff of float32, the precision of Embree's test and of the origins we hand it.
inline constexpr double kFloatRoundoff = 0x1p-24;
// Safety factor over the first-order error bounds of ray_offset.cpp (covers second-order terms and
// the different but equally conditioned factorisations of Moller-Trumbore and Embree's Pluecker test).
inline constexpr double kSafety = 8.0;
inline constexpr double kScaledRoundoff = kSafety * kFloatRoundoff;

// shadow_ray_tfar's robust value for a ray of length `distance` towards a light whose largest
// coordinate magnitude is `light_extent` (world units).
inline double robust_shadow_tfar(double distance, double light_extent) {
  return distance - kScaledRoundoff * (std::sqrt(3.0) * light_extent + 4.0 * distance);
}

}  // namespace ray_offset_detail

// Origin (float32, world space) for a ray leaving `surface` along `direction`: the point moved
// along the geometric normal to the side `direction` points to, far enough that no float32 or
// double intersector can find the triangle it left at t >= 0, and rounded away from the surface.
Vec3f offset_ray_origin(const RayOffset& policy, const SurfacePoint& surface, const Vec3d& direction);

// tfar (world units along a unit direction) for a shadow ray from `origin` to a point light at
// `light`: the distance, shortened so that a surface the light sits on is not an occluder.
// Returns <= 0 when the light is closer than that margin (nothing can be in between).
double shadow_ray_tfar(const RayOffset& policy, const Vec3d& origin, const Vec3d& light);

}  // namespace rt
