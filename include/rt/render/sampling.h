#pragma once
// Deterministic sample patterns and the warps that turn them into points on lights: hashing,
// correlated multi-jittered 2D points, uniform points on a triangle, uniform directions in the
// solid angle a triangle subtends. Double precision throughout; no state, so every sample is a
// function of its indices and the image does not depend on thread count or tile order.

#include <array>
#include <cstdint>
#include <span>
#include <optional>

#include "rt/core/math.h"

namespace rt {

// splitmix64's finaliser (Steele, Lea, Flood, "Fast Splittable Pseudorandom Number Generators",
// OOPSLA 2014): a bijective mix whose outputs pass BigCrush for consecutive inputs.
constexpr std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// The top 53 bits of `bits` as a double in [0, 1).
constexpr double unit_double(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1p-53; }

// Point `index` of `count` (0 <= index < count) of the correlated multi-jittered pattern number
// `pattern` in [0, 1)^2 (Kensler, "Correlated Multi-Jittered Sampling", Pixar Technical Memo
// 13-01, 2013, the arbitrary-count version): y is stratified into `count` equal strata (one point
// each), x into columns of a near-square grid, so any count is well stratified in both axes.
Vec2d cmj_sample(std::uint32_t index, std::uint32_t count, std::uint32_t pattern);

// Points first .. first + out.size() - 1 of the same pattern, out[k] = cmj_sample(first + k, count,
// pattern) bit for bit, computed step by step over all of them (about 4x faster per point: the
// integer hashing vectorises).
void cmj_samples(std::uint32_t first, std::span<Vec2d> out, std::uint32_t count, std::uint32_t pattern);

// Barycentrics (b0, b1, b2) of a uniformly distributed point on a triangle from u in [0, 1)^2, by
// Heitz's low-distortion map ("A Low-Distortion Map Between Triangle and Square", 2019), which keeps
// the stratification of u better than the square-root map and needs no square root.
Vec3d sample_triangle_uniform(Vec2d u);

// Solid angle (steradians) that the triangle a, b, c subtends at p (Van Oosterom and Strackee,
// "The Solid Angle of a Plane Triangle", IEEE Trans. Biomed. Eng. 30, 1983). World space.
double triangle_solid_angle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c);

// The spherical triangle that the triangle (a, b, c) subtends at p, set up once for drawing many
// directions uniformly distributed in its solid angle (Arvo, "Stratified Sampling of Spherical
// Triangles", SIGGRAPH 1995). valid() is false when the triangle is degenerate as seen from p (p on
// its plane or on a side's line): there is nothing to sample. World space, double.
class SphericalTriangle {
 public:
  SphericalTriangle()  // invalid: all zeros
      : A_(0.0), B_(0.0), C_perp_(0.0), alpha_(0.0), cos_alpha_(0.0), sin_alpha_(0.0), cos_c_(0.0), area_(0.0) {}
  // Members left unset, for storage that set_up_many fills later (zeroing it showed in profiles).
  struct Unset {};
  explicit SphericalTriangle(Unset) {}
  SphericalTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c);
  // The spherical triangles of triangles (corners[i], world space) seen from p, set up four at a
  // time in SIMD lanes: out[i] (out.size() >= corners.size()) gets SphericalTriangle(p,
  // corners[i][0], corners[i][1], corners[i][2]) bit for bit (the constructor takes this path).
  static void set_up_many(const Vec3d& p, std::span<const std::array<Vec3d, 3>> corners,
                          std::span<SphericalTriangle> out);
  // The same with triangle i seen from points[i] (points.size() == corners.size()): the set-ups of
  // several shading points share the lanes.
  static void set_up_many(std::span<const Vec3d> points, std::span<const std::array<Vec3d, 3>> corners,
                          std::span<SphericalTriangle> out);

  bool valid() const { return area_ > 0.0; }
  // Its area on the unit sphere (steradians, by Girard's theorem): the pdf of a direction is 1 / area.
  double solid_angle() const { return area_; }
  // The unit direction for u in [0, 1)^2: u.x chooses the sub-triangle of area u.x * solid_angle(),
  // u.y the point along its far side, so a stratified u gives stratified directions.
  Vec3d sample(Vec2d u) const;

  // sample's steps, for computing it over many u at once (light_sample_lanes.h): u.x chooses the
  // angle whose sine and cosine the warp takes; the rest reads the members below.
  double warp_angle(double ux) const { return ux * area_ - alpha_; }
  double alpha() const { return alpha_; }  // radians
  const Vec3d& a() const { return A_; }
  const Vec3d& b() const { return B_; }
  const Vec3d& c_perp() const { return C_perp_; }
  double cos_alpha() const { return cos_alpha_; }
  double sin_alpha() const { return sin_alpha_; }
  double cos_c() const { return cos_c_; }

 private:
  // set_up_many's lanes; triangle i is seen from points[i * point_stride].
  static void set_up_lanes(const Vec3d* points, std::size_t point_stride,
                           std::span<const std::array<Vec3d, 3>> corners, std::span<SphericalTriangle> out);

  Vec3d A_, B_;
  Vec3d C_perp_;  // unit, C's component orthogonal to A
  double alpha_, cos_alpha_, sin_alpha_, cos_c_;  // angle at A; cos of side AB
  double area_;
};

// Barycentrics (b0, b1, b2) of the point where the ray from p along w (world space) meets the plane
// of triangle (a, b, c), clamped onto the triangle against rounding; nullopt when w is parallel to
// the plane (Moeller and Trumbore's formulation).
std::optional<Vec3d> barycentrics_along(const Vec3d& p, const Vec3d& w, const Vec3d& a, const Vec3d& b,
                                        const Vec3d& c);

}  // namespace rt
