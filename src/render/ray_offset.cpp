#include "rt/render/ray_offset.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "rt/core/error.h"

namespace rt {

namespace {

using ray_offset_detail::kFloatRoundoff;
using ray_offset_detail::kSafety;
using ray_offset_detail::kScaledRoundoff;

double max_abs_component(const Vec3d& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

// Rounds each component of `p` to float32, and when rounding moved it against `away` (towards the
// surface), steps one float further along `away`: the offset survives the conversion.
Vec3f round_away(const Vec3d& p, const Vec3d& away) {
  return {ray_offset_detail::round_away(p.x, away.x), ray_offset_detail::round_away(p.y, away.y),
          ray_offset_detail::round_away(p.z, away.z)};
}

}  // namespace

RayOffset parse_ray_offset(std::string_view text) {
  if (text == "robust") return {};
  if (text.starts_with("fixed:")) {
    const std::string number(text.substr(6));
    char* end = nullptr;
    const double epsilon = std::strtod(number.c_str(), &end);
    if (!number.empty() && end == number.c_str() + number.size() && std::isfinite(epsilon) && epsilon > 0.0)
      return {RayOffset::Mode::fixed, epsilon};
  }
  throw InputError(fmt::format("invalid ray offset '{}' (expected robust or fixed:EPS with EPS > 0)", text));
}

std::string to_string(const RayOffset& offset) {
  return offset.mode == RayOffset::Mode::robust ? "robust" : fmt::format("fixed:{}", offset.epsilon);
}

TriangleFrame make_triangle_frame(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2) {
  const Vec3d e1 = p1 - p0, e2 = p2 - p0, e3 = p2 - p1;
  const Vec3d cross = glm::cross(e1, e2);
  const double area2 = glm::length(cross);
  TriangleFrame frame;
  frame.geometric_normal = area2 > 0.0 ? cross / area2 : Vec3d(0.0);

  // A float32 test decides whether a ray from o meets the triangle it leaves from the sign of
  //   N = Ng . (p0 - o),  Ng = (p1 - p0) x (p2 - p0),
  // i.e. from the signed distance of o to the triangle's plane. Its rounding errors, measured as a
  // distance (divided by |Ng|), are at most about
  //   u sqrt(3) |o|_inf        rounding the origin to float32,
  //   u |p0 - o|               the float32 subtraction p0 - o,
  //   2 u kappa |p0 - o|       the direction of the float32 cross product Ng, where
  //                            kappa = |e1||e2| / |e1 x e2| >= 1 grows as the triangle becomes a sliver,
  //   3 u |p0 - o|             the float32 dot product,
  // with u = 2^-24 and |p0 - o| <= L, the longest edge, since o sits on the triangle. Our point is
  // interpolated from the vertices in double, so it is on the plane to ~1e-16 relative and adds
  // nothing comparable (pbrt-v4's OffsetRayOrigin bounds the same quantity for its own
  // intersector). Moving o off the plane by more than that total, times kSafety, keeps the computed
  // sign of N right, so the triangle left is never found at t >= 0 again, at any scene scale.
  // The edge terms are the triangle's; the first is the point's (make_surface_point).
  const double kappa = area2 > 0.0 ? glm::length(e1) * glm::length(e2) / area2 : 1.0;
  const double longest_edge = std::max({glm::length(e1), glm::length(e2), glm::length(e3)});
  frame.edge_term = (4.0 + 2.0 * kappa) * longest_edge;
  return frame;
}

SurfacePoint make_surface_point(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, const TriangleFrame& frame,
                                double b1, double b2) {
  SurfacePoint surface;
  surface.point = (1.0 - b1 - b2) * p0 + b1 * p1 + b2 * p2;
  surface.geometric_normal = frame.geometric_normal;
  surface.error_bound = kScaledRoundoff * (std::sqrt(3.0) * max_abs_component(surface.point) + frame.edge_term);
  return surface;
}

SurfacePoint make_surface_point(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, double b1, double b2) {
  return make_surface_point(p0, p1, p2, make_triangle_frame(p0, p1, p2), b1, b2);
}

SurfacePoint make_sphere_surface_point(const FlatSphere& sphere, const Vec3d& origin, const Vec3d& direction,
                                       double t) {
  const Vec3d o(sphere.object_from_world * Vec4d(origin, 1.0));
  const Vec3d d = Mat3d(sphere.object_from_world) * direction;
  Vec3d p = o + t * d;  // object space, on the unit sphere up to the error of t
  const double length = glm::length(p);
  p = length > 0.0 ? p / length : Vec3d(0.0, 0.0, 1.0);
  SurfacePoint surface;
  surface.point = Vec3d(sphere.world_from_object * Vec4d(p, 1.0));
  const Vec3d n = sphere.normal_from_object * p;
  surface.geometric_normal = glm::normalize(n);
  const Mat3d linear(sphere.world_from_object);
  const double largest_axis = std::max({glm::length(linear[0]), glm::length(linear[1]), glm::length(linear[2])});
  surface.error_bound = kSafety * (kFloatRoundoff * std::sqrt(3.0) * max_abs_component(surface.point) +
                                   0x1p-40 * (max_abs_component(surface.point) + largest_axis));
  return surface;
}

Vec3f offset_ray_origin(const RayOffset& policy, const SurfacePoint& surface, const Vec3d& direction) {
  const Vec3d& n = surface.geometric_normal;
  const Vec3d side = glm::dot(n, direction) >= 0.0 ? n : -n;
  if (policy.mode == RayOffset::Mode::fixed) return Vec3f(surface.point + policy.epsilon * side);
  return round_away(surface.point + surface.error_bound * side, side);
}

double shadow_ray_tfar(const RayOffset& policy, const Vec3d& origin, const Vec3d& light) {
  const double distance = glm::length(light - origin);
  if (policy.mode == RayOffset::Mode::fixed) return distance - policy.epsilon;
  // A surface through the light point is met at t = distance up to the float32 error of t, which is
  // relative to the coordinates involved; stop short by the same kind of bound as above.
  return ray_offset_detail::robust_shadow_tfar(distance, max_abs_component(light));
}

}  // namespace rt
