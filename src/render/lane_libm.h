#pragma once
// Elementary functions over double lanes (lane_math.h's D4, and D8 in the AVX-512 build), for the
// area lights' per-sample path: the same IEEE operations in the same order in the SSE2, AVX2 and
// AVX-512 builds (no FMA), so a lane gives the same bits on every x86-64 CPU, and a scalar caller
// that puts its argument in a lane (sampling.cpp) gets the lanes' bits. Within 1 ulp of glibc, not
// bit for bit (binary powering for whole exponents: within (n - 1) 2^-53 relative of the exact
// power): the error bounds are asserted in tests/test_area_lights.cpp and what they do to images
// is in docs/performance.md. The polynomials and the argument reduction are fdlibm's (Sun
// Microsystems, 1993, freely distributable; as in musl's __sin, __cos and __rem_pio2, and
// fdlibm's e_pow.c, e_atan2.c and s_atan.c).

#include <cmath>
#include <cstdint>
#include <limits>

#include "lane_math.h"

namespace rt::lane_math {

#define RT_LANE_INLINE [[gnu::always_inline]] inline

inline namespace RT_LANE_NAMESPACE {

// N groups of four lanes as one value: every operation is issued for all N groups before the
// next, so that the out-of-order core overlaps their dependency chains. pow's chain is about 250
// cycles long (two divisions, two polynomials, a dozen exact-product steps), longer than the
// reorder window holds for one group: four groups at a time (AVX2) take half the time per value
// that one does. With SSE2 (two registers a group) more than two groups spill. A group G is D4
// or, in the AVX-512 build, D8 (lane_math.h).
template <int N, class G = D4>
struct WideMask;
template <int N, class G = D4>
struct Wide {
  static constexpr int kGroups = N, kGroupLanes = int(sizeof(G) / sizeof(double)), kLanes = N * kGroupLanes;
  using Group = G;
  using Mask = WideMask<N, G>;
  G g[N];
};
template <int N, class G>
struct WideMask {
  MaskOf<G> g[N];
};

#define RT_WIDE_EACH(expression)   \
  _Pragma("GCC unroll 16") for (int i = 0; i < N; ++i) expression
#define RT_WIDE_BINARY(Result, op, Operand)                                                  \
  template <int N, class G>                                                                  \
  RT_LANE_INLINE Result<N, G> operator op(const Operand<N, G>& a, const Operand<N, G>& b) {  \
    Result<N, G> r;                                                                          \
    RT_WIDE_EACH(r.g[i] = a.g[i] op b.g[i]);                                          \
    return r;                                                                          \
  }
RT_WIDE_BINARY(Wide, +, Wide)
RT_WIDE_BINARY(Wide, -, Wide)
RT_WIDE_BINARY(Wide, *, Wide)
RT_WIDE_BINARY(Wide, /, Wide)
RT_WIDE_BINARY(WideMask, <, Wide)
RT_WIDE_BINARY(WideMask, >, Wide)
RT_WIDE_BINARY(WideMask, >=, Wide)
RT_WIDE_BINARY(WideMask, ==, Wide)
RT_WIDE_BINARY(WideMask, !=, Wide)
RT_WIDE_BINARY(WideMask, &, WideMask)
RT_WIDE_BINARY(WideMask, |, WideMask)
#undef RT_WIDE_BINARY

// Unary and binary functions group by group: f(a) and f(a, b) of lane_math.h's groups or masks.
#define RT_WIDE_UNARY(Result, name, Operand)                   \
  template <int N, class G>                                    \
  RT_LANE_INLINE Result<N, G> name(const Operand<N, G>& a) {   \
    Result<N, G> r;                                            \
    RT_WIDE_EACH(r.g[i] = name(a.g[i]));                       \
    return r;                                                  \
  }
#define RT_WIDE_FUNCTION(name)                                                 \
  template <int N, class G>                                                    \
  RT_LANE_INLINE Wide<N, G> name(const Wide<N, G>& a, const Wide<N, G>& b) {   \
    Wide<N, G> r;                                                              \
    RT_WIDE_EACH(r.g[i] = name(a.g[i], b.g[i]));                       \
    return r;                                                          \
  }
RT_WIDE_UNARY(Wide, operator-, Wide)
RT_WIDE_UNARY(WideMask, operator~, WideMask)
RT_WIDE_UNARY(Wide, abs, Wide)
RT_WIDE_UNARY(Wide, sqrt, Wide)
RT_WIDE_UNARY(Wide, round_to_integer, Wide)
RT_WIDE_FUNCTION(max)
RT_WIDE_FUNCTION(bit_and)
RT_WIDE_FUNCTION(bit_or)
#undef RT_WIDE_UNARY
#undef RT_WIDE_FUNCTION

template <int N, class G>
RT_LANE_INLINE Wide<N, G> select(const WideMask<N, G>& m, const Wide<N, G>& a, const Wide<N, G>& b) {
  Wide<N, G> r;
  RT_WIDE_EACH(r.g[i] = select(m.g[i], a.g[i], b.g[i]));
  return r;
}
template <int N, class G>
RT_LANE_INLINE Wide<N, G> clamp(const Wide<N, G>& v, const Wide<N, G>& lo, const Wide<N, G>& hi) {
  Wide<N, G> r;
  RT_WIDE_EACH(r.g[i] = clamp(v.g[i], lo.g[i], hi.g[i]));
  return r;
}
template <int bits, int N, class G>
RT_LANE_INLINE Wide<N, G> shift_left(const Wide<N, G>& a) {
  Wide<N, G> r;
  RT_WIDE_EACH(r.g[i] = shift_left<bits>(a.g[i]));
  return r;
}
template <int bits, int N, class G>
RT_LANE_INLINE Wide<N, G> shift_right(const Wide<N, G>& a) {
  Wide<N, G> r;
  RT_WIDE_EACH(r.g[i] = shift_right<bits>(a.g[i]));
  return r;
}
#undef RT_WIDE_EACH

// A constant in every lane of a Wide (lane_math.h's Splat).
template <int N, class G>
struct Splat<Wide<N, G>> {
  RT_LANE_INLINE static Wide<N, G> value(double x) {
    Wide<N, G> r;
    for (G& g : r.g) g = Splat<G>::value(x);
    return r;
  }
  RT_LANE_INLINE static Wide<N, G> bits(std::uint64_t b) {
    Wide<N, G> r;
    for (G& g : r.g) g = Splat<G>::bits(b);
    return r;
  }
};

// sin(x) and cos(x) for |x| < 2^20 (radians), within 1 ulp of glibc's where the result is not
// within 1e-9 of zero (there, within 1e-24 absolute). NaN gives NaN. V is D4 or Wide<N>.
template <class V>
RT_LANE_INLINE void sincos(const V& x, V& sin_x, V& cos_x) {
  using S = Splat<V>;
  // x = n pi/2 + (y0 + y1): pi/2 in two parts, the first of 33 bits so that n * pio2_1 is exact
  // for |n| < 2^20 (fdlibm's __rem_pio2, medium range, first step).
  const V n = round_to_integer(x * S::value(6.36619772367581382433e-01));  // 2 / pi
  const V pio2_1 = S::value(1.57079632673412561417e+00), pio2_1t = S::value(6.07710050650619224932e-11);
  const V r = x - n * pio2_1, w = n * pio2_1t;
  const V y0 = r - w;
  const V y1 = (r - y0) - w;

  // fdlibm's kernels on |y0 + y1| <= pi/4.
  const V one = S::value(1.0), half = S::value(0.5);
  const V z = y0 * y0;
  const V v = z * y0;
  const V rs = S::value(8.33333333332248946124e-03) +
                z * (S::value(-1.98412698298579493134e-04) +
                     z * (S::value(2.75573137070700676789e-06) +
                          z * (S::value(-2.50507602534068634195e-08) + z * S::value(1.58969099521155010221e-10))));
  const V s = y0 - ((z * (half * y1 - v * rs) - y1) - v * S::value(-1.66666666666666324348e-01));
  const V rc = z * (S::value(4.16666666666666019037e-02) +
                     z * (S::value(-1.38888888888741095749e-03) +
                          z * (S::value(2.48015872894767294178e-05) +
                               z * (S::value(-2.75573143513906633035e-07) +
                                    z * (S::value(2.08757232129817482790e-09) +
                                         z * S::value(-1.13596475577881948265e-11))))));
  const V hz = half * z;
  const V c0 = one - hz;
  const V c = c0 + (((one - c0) - hz) + (z * rc - y0 * y1));

  // The quadrant q = n mod 4, exactly, from n / 4's floor: q 1 and 3 swap sine and cosine; the
  // sine is negated in quadrants 2 and 3, the cosine in 1 and 2.
  const V quarter = n * S::value(0.25);
  V floor_quarter = round_to_integer(quarter);
  floor_quarter = select(floor_quarter > quarter, floor_quarter - one, floor_quarter);
  const V q = n - S::value(4.0) * floor_quarter;
  const auto odd = (q == one) | (q == S::value(3.0));
  const V sine = select(odd, c, s), cosine = select(odd, s, c);
  sin_x = select(q > S::value(1.5), -sine, sine);
  cos_x = select((q > half) & (q < S::value(2.5)), -cosine, cosine);
}

// atan2(y, x) for y >= 0 (radians, in [0, pi]): fdlibm's e_atan2.c and s_atan.c (Sun
// Microsystems, 1993) for finite normal y > 0 and x != 0, the branches on the interval of |y / x|
// taken as selects (each interval's reduction written as (p t - q) / (r + s t), which is the same
// IEEE operations for its p, q, r, s); y = +0 gives +0 for x >= +0 and pi for x <= -0, x = +-0 with
// y > 0 gives pi/2, as glibc does. `outside` marks the lanes this does not cover (y < 0, -0,
// subnormal or not finite; x subnormal or not finite; NaN), whose value is meaningless.
template <class V, class M>
RT_LANE_INLINE V atan2_nonnegative(const V& y, const V& x, M& outside) {
  using S = Splat<V>;
  const V zero = S::value(0.0), one = S::value(1.0), two52 = S::value(0x1p52);
  const V ax = abs(x);
  // atan(t) for t = |y / x| (s_atan.c): t reduced about 0, 0.5, 1, 1.5 or infinity, whose
  // arctangents are atan_hi + atan_lo.
  const V t = y / ax;
  const M below_7_16 = t < S::value(0.4375), below_11_16 = t < S::value(0.6875), below_19_16 = t < S::value(1.1875),
          below_39_16 = t < S::value(2.4375);
  const auto by_interval = [&](double small, double half, double unit, double one_and_half, double infinite) {
    return select(below_7_16, S::value(small),
                  select(below_11_16, S::value(half),
                         select(below_19_16, S::value(unit), select(below_39_16, S::value(one_and_half), S::value(infinite)))));
  };
  const V p = by_interval(1.0, 2.0, 1.0, 1.0, 0.0), q = by_interval(0.0, 1.0, 1.0, 1.5, 1.0);
  const V r = by_interval(1.0, 2.0, 1.0, 1.0, 0.0), s = by_interval(0.0, 1.0, 1.0, 1.5, 1.0);
  const V atan_hi = by_interval(0.0, 4.63647609000806093515e-01, 7.85398163397448278999e-01, 9.82793723247329054082e-01,
                                1.57079632679489655800e+00);
  const V atan_lo = by_interval(0.0, 2.26987774529616870924e-17, 3.06161699786838301793e-17, 1.39033110312309984516e-17,
                                6.12323399573676603587e-17);
  const V reduced = (p * t - q) / (r + s * t);
  const V z = reduced * reduced;
  const V w = z * z;
  const V s1 = z * (S::value(3.33333333333329318027e-01) +
                    w * (S::value(1.42857142725034663711e-01) +
                         w * (S::value(9.09088713343650656196e-02) +
                              w * (S::value(6.66107313738753120669e-02) +
                                   w * (S::value(4.97687799461593236017e-02) + w * S::value(1.62858201153657823623e-02))))));
  const V s2 = w * (S::value(-1.99999999998764832476e-01) +
                    w * (S::value(-1.11111104054623557880e-01) +
                         w * (S::value(-7.69187620504482999495e-02) +
                              w * (S::value(-5.83357013379057348645e-02) + w * S::value(-3.65315727442169155270e-02)))));
  // Below 7/16 fdlibm returns t - t (s1 + s2); atan_hi = atan_lo = 0 gives those bits.
  const V atan_t = atan_hi - ((reduced * (s1 + s2) - atan_lo) - reduced);

  // e_atan2.c: the exponents of y and x more than 60 apart give pi/2, or 0 for x < 0; x < 0 takes
  // pi - atan(t), with pi's tail.
  const V k = bit_or(shift_right<52>(y), two52) - bit_or(shift_right<52>(ax), two52);
  const V pi_over_2 = S::value(1.5707963267948965580e+00), pi = S::value(3.1415926535897931160e+00),
          pi_lo = S::value(1.2246467991473531772e-16);
  const M negative_x = x < zero;
  const M huge_ratio = k > S::value(60.0);
  V angle = select(huge_ratio, pi_over_2 + S::value(0.5) * pi_lo, select(negative_x & (k < S::value(-60.0)), zero, atan_t));
  angle = select(negative_x & ~huge_ratio, pi - (angle - pi_lo), angle);

  // y = +0: +0 or pi by x's sign bit (+0 | 1.0 is 1.0; -0 | 1.0 is -1.0); x = +-0: pi/2.
  const M y_zero = y == zero;
  angle = select(y_zero, select(bit_or(x, one) < zero, pi, zero), select(x == zero, pi_over_2, angle));
  const V largest = S::value(std::numeric_limits<double>::max()), smallest = S::value(0x1p-1022);
  const M y_covered = (y_zero & ~(bit_or(y, one) < zero)) | ((y >= smallest) & (largest >= y));
  const M x_covered = (x == zero) | ((ax >= smallest) & (largest >= ax));
  outside = ~(y_covered & x_covered);
  return angle;
}

// std::atan2(y, x) per lane, within 1 ulp of glibc's for y >= 0 (the bound asserted in
// tests/test_area_lights.cpp): atan2_nonnegative, its other lanes from glibc.
RT_LANE_INLINE D4 atan2(const D4& y, const D4& x) {
  M4 outside;
  D4 angle = atan2_nonnegative(y, x, outside);
  if (any(outside)) {
    double ys[4], xs[4], angles[4];
    std::int64_t mask[4];
    store(ys, y);
    store(xs, x);
    store(angles, angle);
    store(mask, outside);
    for (int i = 0; i < 4; ++i)
      if (mask[i]) angles[i] = std::atan2(ys[i], xs[i]);
    load(angle, angles);
  }
  return angle;
}

// x^y for a positive normal x (2^-1022 <= x <= DBL_MAX), |y| <= 2^30 and y log2 x < 1023;
// `outside` marks the lanes that break these (their value is meaningless). fdlibm's
// __ieee754_pow, general case (Sun Microsystems, 1993): log2 x in two doubles (t1 + t2, t1 with
// 21 significant bits), y log2 x = (y1 + y2)(t1 + t2) with y1 y's high part so that y1 t1 is
// exact, then 2^z by fdlibm's exp kernel, scaled by multiplying with powers of two (rounding once,
// as ldexp does, where the result is subnormal). Results below 2^-1080 are +0. One change from
// fdlibm: t_h, an approximation of ax + bp with 21 significant bits, is the high part of their
// rounded sum (fdlibm builds it from ax's exponent bits); any such value keeps t_h - bp and
// ax - (t_h - bp) exact, which is all the step needs. V is D4 or Wide<N>, M its mask type.
template <class V, class M>
RT_LANE_INLINE V pow_positive(const V& x, const V& y, M& outside) {
  using S = Splat<V>;
  // x with its low 32 bits cleared (fdlibm's SET_LOW_WORD(x, 0)): at most 21 significant bits,
  // so that the product of two such values is exact.
  const V high_mask = S::bits(0xFFFFFFFF00000000);
  const auto high_part = [&](const V& v) { return bit_and(v, high_mask); };
  const V zero = S::value(0.0), one = S::value(1.0), two52 = S::value(0x1p52);

  // x = 2^n m with m in [1, 2) (x is positive: no sign bit); n through the exponent field as the
  // low bits of 2^52 + field. m is then brought to [sqrt(3)/2, sqrt(3)) and centred on bp = 1 or
  // 1.5 (dp_h + dp_l = log2(bp)).
  V n = (bit_or(shift_right<52>(x), two52) - two52) - S::value(1023.0);
  const V m = bit_or(bit_and(x, S::bits(0x000FFFFFFFFFFFFF)), one);
  const M above_sqrt3 = m >= S::bits(0x3FFBB67A00000000);
  const M middle = (m >= S::bits(0x3FF3988F00000000)) & ~above_sqrt3;
  const V ax = select(above_sqrt3, m * S::value(0.5), m);
  n = select(above_sqrt3, n + one, n);
  const V bp = select(middle, S::value(1.5), one);
  const V dp_h = select(middle, S::value(5.84962487220764160156e-01), zero);
  const V dp_l = select(middle, S::value(1.35003920212974897128e-08), zero);

  // log2(ax / bp) from s = (ax - bp) / (ax + bp) = s_h + s_l.
  V u = ax - bp;
  V v = one / (ax + bp);
  const V ss = u * v;
  const V s_h = high_part(ss);
  V t_h = high_part(ax + bp);
  V t_l = ax - (t_h - bp);
  const V s_l = v * ((u - s_h * t_h) - s_h * t_l);
  V s2 = ss * ss;
  V r = s2 * s2 *
        (S::value(5.99999999999994648725e-01) +
         s2 * (S::value(4.28571428578550184252e-01) +
               s2 * (S::value(3.33333329818377432918e-01) +
                     s2 * (S::value(2.72728123808534006489e-01) +
                           s2 * (S::value(2.30660745775561754067e-01) + s2 * S::value(2.06975017800338417784e-01))))));
  r = r + s_l * (s_h + ss);
  s2 = s_h * s_h;
  const V three = S::value(3.0);
  t_h = high_part((three + s2) + r);
  t_l = r - ((t_h - three) - s2);
  u = s_h * t_h;
  v = s_l * t_h + t_l * ss;
  V p_h = high_part(u + v);
  V p_l = v - (p_h - u);
  // 2 / (3 ln 2) = cp_h + cp_l; log2 x = n + dp_h + z_h + z_l = t1 + t2.
  const V z_h = S::value(9.61796700954437255859e-01) * p_h;
  const V z_l = S::value(-7.02846165095275826516e-09) * p_h + p_l * S::value(9.61796693925975554329e-01) + dp_l;
  const V t1 = high_part(((z_h + z_l) + dp_h) + n);
  const V t2 = z_l - (((t1 - n) - dp_h) - z_h);

  // y log2 x = p_h + p_l.
  const V y1 = high_part(y);
  p_l = (y - y1) * t1 + y * t2;
  p_h = y1 * t1;
  const V z_total = p_l + p_h;

  // 2^(p_h + p_l) = 2^k exp((p_h - k + p_l) ln 2), k the nearest integer (p_h - k is exact).
  V k = round_to_integer(z_total);
  p_h = p_h - k;
  V t = high_part(p_l + p_h);
  u = t * S::value(6.93147182464599609375e-01);  // ln 2's head
  v = (p_l - (t - p_h)) * S::value(6.93147180559945286227e-01) + t * S::value(-1.90465429995776804525e-09);
  V z = u + v;
  const V w = v - (z - u);
  t = z * z;
  const V c = z - t * (S::value(1.66666666666666019037e-01) +
                       t * (S::value(-2.77777777770155933842e-03) +
                            t * (S::value(6.61375632143793436117e-05) +
                                 t * (S::value(-1.65339022054652515390e-06) + t * S::value(4.13813679705723846039e-08)))));
  const V rr = (z * c) / (c - S::value(2.0)) - (w + z * w);
  z = one - (rr - z);

  // z 2^k, z in [0.7, 1.5]: 2^k's bits are k + 1023 in the exponent field (the low bits of
  // 2^52 + k + 1023, shifted up). Below 2^-1000 in two steps, the first exact, the second rounding
  // once to the subnormal result.
  k = clamp(k, S::value(-1100.0), S::value(1023.0));
  const M tiny = k < S::value(-1000.0);
  k = select(tiny, k + S::value(1000.0), k);
  const V scale = shift_left<52>((k + S::value(1023.0)) + two52);
  const V result = (z * scale) * select(tiny, S::value(0x1p-1000), one);

  outside = ~(x >= S::value(0x1p-1022)) | ~(S::value(std::numeric_limits<double>::max()) >= x) |
            ~(S::value(0x1p30) >= abs(y)) | ~(z_total < S::value(1023.0));
  return select(z_total < S::value(-1080.0), zero, result);
}

// out[i] = std::pow(x[i], y) for i < N times G's lanes, within 1 ulp of glibc's (asserted in
// tests/test_area_lights.cpp): pow_positive, with y = 0 giving 1 and x = +0, y > 0 giving +0 as
// there; lanes outside pow_positive's domain (negative or subnormal x, -0, infinities, NaN, huge
// y, overflow) take glibc's std::pow.
template <int N, class G = D4>
RT_LANE_INLINE void pow_many(const double* x, double y, double* out) {
  using W = Wide<N, G>;
  W xs, ys;
  for (int i = 0; i < N; ++i) {
    load(xs.g[i], x + W::kGroupLanes * i);
    ys.g[i] = Splat<G>::value(y);
  }
  typename W::Mask outside;
  const W result = pow_positive(xs, ys, outside);
  const G zero{}, one = Splat<G>::value(1.0);
  std::int64_t fallback[W::kLanes];
  bool any_fallback = false;
  for (int i = 0; i < N; ++i) {
    // x is +0 (not -0: +0 | 1.0 is 1.0, -0 | 1.0 is -1.0) and y > 0; or y is 0.
    const MaskOf<G> zero_result = (xs.g[i] == zero) & (bit_or(xs.g[i], one) == one) & (ys.g[i] > zero);
    const MaskOf<G> unit_result = ys.g[i] == zero;
    store(out + W::kGroupLanes * i, select(unit_result, one, select(zero_result, zero, result.g[i])));
    const MaskOf<G> glibc = outside.g[i] & ~(zero_result | unit_result);
    store(fallback + W::kGroupLanes * i, glibc);
    any_fallback = any_fallback || any(glibc);
  }
  if (any_fallback)
    for (int i = 0; i < W::kLanes; ++i)
      if (fallback[i]) out[i] = std::pow(x[i], y);
}

// The largest exponent pow_integer_many takes: its relative error grows with n (see there).
constexpr double kMaxIntegerPower = 1024.0;

// out[i] = x[i]^n for i < N times G's lanes, n an integer in [0, kMaxIntegerPower], by binary powering: x, x^2,
// x^4, ... by squaring, multiplied into the result where n has a bit, low bits first (x^40:
// five squarings and one product). At most 2 log2(n) roundings, each compounding the ones
// before it: relative error below (n - 1) 2^-53 + O(2^-106) against the exact power (Higham,
// "Accuracy and Stability of Numerical Algorithms", 2nd ed., section 3.1), about 1e-13 at n =
// 1024, where the result is normal; an underflowing result is off by less than 2^-1022. Used for
// integer shininess (the usual case), where it replaces pow_many's 250-cycle chain by a handful
// of products. x^0 is 1 and 0^n is 0, as pow gives.
template <int N, class G = D4>
RT_LANE_INLINE void pow_integer_many(const double* x, double n, double* out) {
  using W = Wide<N, G>;
  auto remaining = static_cast<std::uint32_t>(n);
  W base, result;
  for (int i = 0; i < N; ++i) {
    load(base.g[i], x + W::kGroupLanes * i);
    result.g[i] = Splat<G>::value(1.0);
  }
  while (remaining != 0) {
    if (remaining & 1u) result = result * base;  // the first time 1 * base: base exactly
    remaining >>= 1;
    if (remaining != 0) base = base * base;
  }
  for (int i = 0; i < N; ++i) store(out + W::kGroupLanes * i, result.g[i]);
}

}  // namespace RT_LANE_NAMESPACE

#undef RT_LANE_INLINE

}  // namespace rt::lane_math
