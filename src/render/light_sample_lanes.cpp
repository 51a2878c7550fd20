// Built twice: as itself (baseline x86-64) and included by light_sample_lanes_avx2.cpp with
// RT_LIGHT_SAMPLE_LANES_AVX2 and -mavx2. Only lane_math.h's always-inlined helpers are used, so the
// AVX2 build emits no inline function that another file could link.

#include "light_sample_lanes.h"

#include <cmath>

#include "lane_libm.h"
#include "lane_math.h"
#include "rt/render/ray_offset.h"

namespace rt::light_sample_lanes {

#ifdef RT_LIGHT_SAMPLE_LANES_AVX2
namespace avx2 {
#else
namespace baseline {
#endif

namespace lm = lane_math;
using lm::D4;
using lm::M4;
using lm::cross;
using lm::dot;
using lm::normalize;

using lm::Xyz;

[[gnu::always_inline]] static inline D4 at(const Lanes& v, int g) {
  D4 out;
  lm::load(out, v.v + g);
  return out;
}

[[gnu::always_inline]] static inline Xyz at(const Vec3& v, int g) {
  Xyz out;
  lm::load(out, v, g);
  return out;
}

// a s + b t, component by component.
[[gnu::always_inline]] static inline Xyz combine(const D4& s, const Xyz& a, const D4& t, const Xyz& b) {
  return {s * a.x + t * b.x, s * a.y + t * b.y, s * a.z + t * b.z};
}

// SphericalTriangle::sample (sampling.cpp).
[[gnu::always_inline]] static inline Xyz arvo_direction(const Input& in, int g) {
  const D4 zero{}, one = lm::broadcast(1.0);
  D4 s, t;
  lm::sincos(at(in.angle, g), s, t);
  const D4 cos_alpha = at(in.cos_alpha, g), sin_alpha = at(in.sin_alpha, g);
  const D4 uu = t - cos_alpha, vv = s + sin_alpha * at(in.cos_c, g);
  const D4 denominator = (vv * s + uu * t) * sin_alpha;
  const D4 q = lm::select(denominator != zero,
                          lm::clamp(((vv * t - uu * s) * cos_alpha - vv) / denominator, -one, one), one);
  const Xyz b = at(in.b, g);
  const Xyz c_prime = combine(q, at(in.a, g), lm::sqrt(lm::max(zero, one - q * q)), at(in.c_perp, g));
  const D4 cosine = dot(c_prime, b);
  const D4 z = one - at(in.v, g) * (one - cosine);
  const Xyz across = normalize({c_prime.x - cosine * b.x, c_prime.y - cosine * b.y, c_prime.z - cosine * b.z});
  return normalize(combine(z, b, lm::sqrt(lm::max(zero, one - z * z)), across));
}

void sample(const Input& in, int count, Output& out) {
  const D4 zero{}, one = lm::broadcast(1.0);
  const Xyz point{lm::broadcast(in.point[0]), lm::broadcast(in.point[1]), lm::broadcast(in.point[2])};
  for (int g = 0; g < count; g += 4) {
    const Xyz p0 = at(in.p0, g), p1 = at(in.p1, g), p2 = at(in.p2, g);
    M4 by_solid_angle;
    lm::load(by_solid_angle, in.by_solid_angle + g);

    // barycentrics_along(point, w, p0, p1, p2) for the warped direction w.
    const Xyz w = arvo_direction(in, g);
    const Xyz e1{p1.x - p0.x, p1.y - p0.y, p1.z - p0.z}, e2{p2.x - p0.x, p2.y - p0.y, p2.z - p0.z};
    const Xyz pv = cross(w, e2);
    const D4 determinant = dot(e1, pv);
    const Xyz tv{point.x - p0.x, point.y - p0.y, point.z - p0.z};
    D4 b1 = lm::clamp(dot(tv, pv) / determinant, zero, one);
    D4 b2 = lm::clamp(dot(w, cross(tv, e1)) / determinant, zero, one);
    const D4 sum = b1 + b2;
    const M4 over = sum > one;
    b1 = lm::select(over, b1 / sum, b1);
    b2 = lm::select(over, b2 / sum, b2);

    // Where sampled by area, sample_triangle_uniform's barycentrics instead.
    b1 = lm::select(by_solid_angle, b1, at(in.b1, g));
    b2 = lm::select(by_solid_angle, b2, at(in.b2, g));
    M4 valid = ~by_solid_angle | (determinant != zero);

    lm::store(out.b1.v + g, b1);
    lm::store(out.b2.v + g, b2);

    // make_surface_point.
    const D4 w0 = one - b1 - b2;
    const Xyz p{w0 * p0.x + b1 * p1.x + b2 * p2.x, w0 * p0.y + b1 * p1.y + b2 * p2.y,
                w0 * p0.z + b1 * p1.z + b2 * p2.z};
    lm::store(out.point, g, p);
    const D4 largest = lm::max(lm::max(lm::abs(p.x), lm::abs(p.y)), lm::abs(p.z));
    lm::store(out.error_bound.v + g, lm::broadcast(ray_offset_detail::kScaledRoundoff) *
                                         (lm::broadcast(std::sqrt(3.0)) * largest + at(in.edge_term, g)));

    // The unit direction and distance from the shading point (EmitterSampler::sample).
    const Xyz offset{p.x - point.x, p.y - point.y, p.z - point.z};
    const D4 distance = lm::sqrt(dot(offset, offset));
    valid = valid & (distance > zero);
    lm::store(out.distance.v + g, distance);
    lm::store(out.direction, g, Xyz{offset.x / distance, offset.y / distance, offset.z / distance});
    lm::store(out.valid + g, valid);
  }
}

// pow(x[k], y) for the 16 lanes: four groups of four at a time with AVX2 (one register each),
// two with SSE2 (two registers each; four would spill), to overlap pow's long dependency chains.
void powers(const double* x, double y, double* out) {
  static_assert(kLanes == 16);
#ifdef RT_LIGHT_SAMPLE_LANES_AVX2
  lm::pow_many<4>(x, y, out);
#else
  lm::pow_many<2>(x, y, out);
  lm::pow_many<2>(x + 8, y, out + 8);
#endif
}

}  // namespace (baseline or avx2)

#ifdef RT_LIGHT_SAMPLE_LANES_AVX2
const Kernels* avx2_kernels() {
  static const Kernels kernels{&avx2::sample, &avx2::powers};
  __builtin_cpu_init();  // idempotent; needed when called before the constructors have run
  return __builtin_cpu_supports("avx2") ? &kernels : nullptr;
}
#else
const Kernels& baseline_kernels() {
  static const Kernels kernels{&baseline::sample, &baseline::powers};
  return kernels;
}

const Kernels& best_kernels() {
  static const Kernels& best = avx2_kernels() ? *avx2_kernels() : baseline_kernels();
  return best;
}
#endif

}  // namespace rt::light_sample_lanes
