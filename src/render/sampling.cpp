#include "rt/render/sampling.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

#include "lane_libm.h"
#include "light_sample_lanes.h"

namespace rt {

namespace {

// The smallest all-ones mask covering length - 1 (the next power of two, minus one).
std::uint32_t cover_mask(std::uint32_t length) {
  std::uint32_t w = length - 1;
  w |= w >> 1;
  w |= w >> 2;
  w |= w >> 4;
  w |= w >> 8;
  w |= w >> 16;
  return w;
}

// One round of Kensler's bijective hash on [0, w] (Kensler 2013, listing 3's loop body).
[[gnu::always_inline]] inline std::uint32_t hash_round(std::uint32_t i, std::uint32_t w, std::uint32_t pattern) {
  i ^= pattern;
  i *= 0xe170893du;
  i ^= pattern >> 16;
  i ^= (i & w) >> 4;
  i ^= pattern >> 8;
  i *= 0x0929eb3fu;
  i ^= pattern >> 23;
  i ^= (i & w) >> 1;
  i *= 1u | pattern >> 27;
  i *= 0x6935fa69u;
  i ^= (i & w) >> 11;
  i *= 0x74dcb303u;
  i ^= (i & w) >> 2;
  i *= 0x9e501cc3u;
  i ^= (i & w) >> 2;
  i *= 0xc860a3dfu;
  i &= w;
  i ^= i >> 5;
  return i;
}

// Kensler's hashed permutation of [0, length): element `i` of permutation number `pattern`, by
// cycle-walking a bijective hash on the next power of two (Kensler 2013, listing 3).
std::uint32_t permute(std::uint32_t i, std::uint32_t length, std::uint32_t pattern) {
  const std::uint32_t w = cover_mask(length);
  do {
    i = hash_round(i, w, pattern);
  } while (i >= length);
  return (i + pattern) % length;
}

// permute of each of v[0 .. n): the first round for all of them in one loop the compiler
// vectorises, the rare further rounds of the cycle walk one by one, and % as a mask when length is
// a power of two.
[[gnu::always_inline]] inline void permute_all(std::uint32_t* v, int n, std::uint32_t length, std::uint32_t pattern) {
  const std::uint32_t w = cover_mask(length);
  for (int k = 0; k < n; ++k) v[k] = hash_round(v[k], w, pattern);
  if (w == length - 1) {  // a power of two: every hash (masked by w) is already below it, no walk
    for (int k = 0; k < n; ++k) v[k] = (v[k] + pattern) & w;
    return;
  }
  for (int k = 0; k < n; ++k)
    while (v[k] >= length) v[k] = hash_round(v[k], w, pattern);
  for (int k = 0; k < n; ++k) v[k] = (v[k] + pattern) % length;
}

// Kensler's hash of (i, pattern) to [0, 1) (listing 4), kept in double: 32 bits of jitter.
[[gnu::always_inline]] inline double jitter(std::uint32_t i, std::uint32_t pattern) {
  i ^= pattern;
  i ^= i >> 17;
  i ^= i >> 10;
  i *= 0xb36534e5u;
  i ^= i >> 12;
  i ^= i >> 21;
  i *= 0x93fc4795u;
  i ^= 0xdf6e307fu;
  i ^= i >> 17;
  i *= 1u | pattern >> 18;
  return double(i) * 0x1p-32;
}

// sin and cos of `angle` (radians) by the lanes' sincos (lane_libm.h), so that
// SphericalTriangle::sample gives the bits of EmitterSampler::sample_many's lanes.
void sincos_as_lanes(double angle, double& sin_angle, double& cos_angle) {
  lane_math::D4 s, c;
  lane_math::sincos(lane_math::broadcast(angle), s, c);
  double lanes[4];
  lane_math::store(lanes, s);
  sin_angle = lanes[0];
  lane_math::store(lanes, c);
  cos_angle = lanes[0];
}

// The component of unit-length-or-not `v` orthogonal to unit `axis`, normalised.
Vec3d orthogonal_unit(const Vec3d& v, const Vec3d& axis) { return glm::normalize(v - glm::dot(v, axis) * axis); }

// cmj_samples for at most kCmjChunk points: cmj_sample's steps, each over all the points before
// the next.
// Built for AVX2 as well (8 lanes of 32-bit multiplies; SSE2 has no pmulld), chosen when the
// program loads; integer hashing and the same double operations, so both give the same bits.
constexpr std::size_t kCmjChunk = 64;
[[gnu::target_clones("avx512f", "avx2", "default")]] void cmj_chunk(std::uint32_t first, std::span<Vec2d> out, std::uint32_t count, std::uint32_t pattern) {
  const auto n = static_cast<int>(out.size());
  const auto columns = static_cast<std::uint32_t>(std::sqrt(double(count)));
  const std::uint32_t rows = (count + columns - 1) / columns;
  std::uint32_t s[kCmjChunk], sx[kCmjChunk], sy[kCmjChunk];
  for (int k = 0; k < n; ++k) s[k] = first + std::uint32_t(k);
  permute_all(s, n, count, pattern * 0x51633e2du);
  if ((columns & (columns - 1)) == 0) {
    const auto shift = unsigned(__builtin_ctz(columns));
    for (int k = 0; k < n; ++k) {
      sx[k] = s[k] & (columns - 1);
      sy[k] = s[k] >> shift;
    }
  } else {
    for (int k = 0; k < n; ++k) {
      sx[k] = s[k] % columns;
      sy[k] = s[k] / columns;
    }
  }
  permute_all(sx, n, columns, pattern * 0x68bc21ebu);
  permute_all(sy, n, rows, pattern * 0x02e5be93u);
  const auto points = [&](auto over_rows, auto over_columns, auto over_count) {
    for (int k = 0; k < n; ++k) {
      const double jx = jitter(s[k], pattern * 0x967a889bu), jy = jitter(s[k], pattern * 0x368cc8b7u);
      out[std::size_t(k)] = {std::min(over_columns(sx[k] + over_rows(sy[k] + jx)), 1.0 - 0x1p-53),
                             std::min(over_count(s[k] + jy), 1.0 - 0x1p-53)};
    }
  };
  const auto is_power_of_two = [](std::uint32_t x) { return (x & (x - 1)) == 0; };
  if (is_power_of_two(rows) && is_power_of_two(columns) && is_power_of_two(count)) {
    // Dividing by a power of two is multiplying by its reciprocal, exactly (the values here are far
    // from underflow): the same bits without the divisions' latency.
    const double by_rows = 1.0 / rows, by_columns = 1.0 / columns, by_count = 1.0 / count;
    points([=](double x) { return x * by_rows; }, [=](double x) { return x * by_columns; },
           [=](double x) { return x * by_count; });
  } else {
    points([=](double x) { return x / rows; }, [=](double x) { return x / columns; },
           [=](double x) { return x / count; });
  }
}

}  // namespace

Vec2d cmj_sample(std::uint32_t index, std::uint32_t count, std::uint32_t pattern) {
  // Kensler 2013, listing 5 ("cmj" for any count): a columns x rows grid with columns x rows >=
  // count, index shuffled first so that every prefix of the pattern stays stratified.
  const auto columns = static_cast<std::uint32_t>(std::sqrt(double(count)));
  const std::uint32_t rows = (count + columns - 1) / columns;
  const std::uint32_t s = permute(index, count, pattern * 0x51633e2du);
  const std::uint32_t sx = permute(s % columns, columns, pattern * 0x68bc21ebu);
  const std::uint32_t sy = permute(s / columns, rows, pattern * 0x02e5be93u);
  const double jx = jitter(s, pattern * 0x967a889bu), jy = jitter(s, pattern * 0x368cc8b7u);
  return {std::min((sx + (sy + jx) / rows) / columns, 1.0 - 0x1p-53), std::min((s + jy) / count, 1.0 - 0x1p-53)};
}

void cmj_samples(std::uint32_t first, std::span<Vec2d> out, std::uint32_t count, std::uint32_t pattern) {
  for (std::size_t done = 0; done < out.size(); done += kCmjChunk)
    cmj_chunk(first + std::uint32_t(done), out.subspan(done, std::min(kCmjChunk, out.size() - done)), count, pattern);
}

Vec3d sample_triangle_uniform(Vec2d u) {
  double b0, b1;
  if (u.x < u.y) {
    b0 = u.x / 2.0;
    b1 = u.y - b0;
  } else {
    b1 = u.y / 2.0;
    b0 = u.x - b1;
  }
  return {b0, b1, 1.0 - b0 - b1};
}

double triangle_solid_angle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d va = glm::normalize(a - p), vb = glm::normalize(b - p), vc = glm::normalize(c - p);
  // tan(omega / 2) = |va . (vb x vc)| / (1 + va.vb + vb.vc + vc.va) for unit vectors.
  const double numerator = std::abs(glm::dot(va, glm::cross(vb, vc)));
  const double denominator = 1.0 + glm::dot(va, vb) + glm::dot(vb, vc) + glm::dot(vc, va);
  return 2.0 * std::atan2(numerator, denominator);
}

SphericalTriangle::SphericalTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const std::array<Vec3d, 3> corners{a, b, c};
  set_up_many(p, std::span(&corners, 1), std::span(this, 1));
}

// The unit directions A, B, C from p to the corners; the interior angles at A, B and C between
// the planes of the sides that meet there (each atan2(|u x v|, u . v) of the planes' unit normals,
// accurate over all of [0, pi], unlike acos; the lanes' atan2, within 1 ulp of glibc's); the area
// alpha + beta + gamma - pi (Girard). A vertex at p, p on a side's line or no positive area leave
// the triangle invalid (all zeros). Arithmetic in light_sample_lanes.cpp.
void SphericalTriangle::set_up_many(const Vec3d& p, std::span<const std::array<Vec3d, 3>> corners,
                                    std::span<SphericalTriangle> out) {
  set_up_lanes(&p, 0, corners, out);
}

void SphericalTriangle::set_up_many(std::span<const Vec3d> points, std::span<const std::array<Vec3d, 3>> corners,
                                    std::span<SphericalTriangle> out) {
  assert(points.size() == corners.size());
  set_up_lanes(points.data(), 1, corners, out);
}

void SphericalTriangle::set_up_lanes(const Vec3d* points, std::size_t point_stride,
                                     std::span<const std::array<Vec3d, 3>> corners, std::span<SphericalTriangle> out) {
  namespace lanes = light_sample_lanes;
  static const lanes::Kernels& kernels = lanes::best_kernels();
  assert(out.size() >= corners.size());
  lanes::SphericalInput in;
  for (std::size_t first = 0; first < corners.size(); first += 4) {
    const std::size_t count = std::min<std::size_t>(4, corners.size() - first);
    for (std::size_t i = 0; i < 4; ++i) {
      const std::size_t k = first + std::min(i, count - 1);  // unused lanes repeat the last
      const std::array<Vec3d, 3>& t = corners[k];
      const Vec3d& p = points[k * point_stride];
      for (auto [to, from] : {std::pair{&in.point, &p}, std::pair{&in.a, &t[0]}, std::pair{&in.b, &t[1]},
                              std::pair{&in.c, &t[2]}}) {
        to->x.v[i] = from->x;
        to->y.v[i] = from->y;
        to->z.v[i] = from->z;
      }
    }
    lanes::SphericalOutput lane;
    kernels.spherical(in, lane);
    for (std::size_t i = 0; i < count; ++i) {
      SphericalTriangle& s = out[first + i];
      s.A_ = {lane.a.x.v[i], lane.a.y.v[i], lane.a.z.v[i]};
      s.B_ = {lane.b.x.v[i], lane.b.y.v[i], lane.b.z.v[i]};
      s.C_perp_ = {lane.c_perp.x.v[i], lane.c_perp.y.v[i], lane.c_perp.z.v[i]};
      s.alpha_ = lane.alpha.v[i];
      s.cos_alpha_ = lane.cos_alpha.v[i];
      s.sin_alpha_ = lane.sin_alpha.v[i];
      s.cos_c_ = lane.cos_c.v[i];
      s.area_ = lane.area.v[i];
    }
  }
}

Vec3d SphericalTriangle::sample(Vec2d u) const {
  // Arvo's first step: the sub-triangle A, B, C' of area u.x * area puts C' on the arc A C, at
  // cos(angle A C') = q.
  double s, t;
  sincos_as_lanes(warp_angle(u.x), s, t);
  const double uu = t - cos_alpha_, vv = s + sin_alpha_ * cos_c_;
  const double denominator = (vv * s + uu * t) * sin_alpha_;
  const double q = denominator != 0.0 ? std::clamp(((vv * t - uu * s) * cos_alpha_ - vv) / denominator, -1.0, 1.0) : 1.0;
  const Vec3d c_prime = q * A_ + std::sqrt(std::max(0.0, 1.0 - q * q)) * C_perp_;
  // Second step: the direction on the arc B C' whose cosine to B is uniform between 1 and B.C'.
  const double z = 1.0 - u.y * (1.0 - glm::dot(c_prime, B_));
  return glm::normalize(z * B_ + std::sqrt(std::max(0.0, 1.0 - z * z)) * orthogonal_unit(c_prime, B_));
}

std::optional<Vec3d> barycentrics_along(const Vec3d& p, const Vec3d& w, const Vec3d& a, const Vec3d& b,
                                        const Vec3d& c) {
  const Vec3d e1 = b - a, e2 = c - a;
  const Vec3d pv = glm::cross(w, e2);
  const double determinant = glm::dot(e1, pv);
  if (determinant == 0.0) return std::nullopt;
  const Vec3d tv = p - a;
  double b1 = std::clamp(glm::dot(tv, pv) / determinant, 0.0, 1.0);
  double b2 = std::clamp(glm::dot(w, glm::cross(tv, e1)) / determinant, 0.0, 1.0);
  if (b1 + b2 > 1.0) {
    const double sum = b1 + b2;
    b1 /= sum;
    b2 /= sum;
  }
  return Vec3d(1.0 - b1 - b2, b1, b2);
}

}  // namespace rt
