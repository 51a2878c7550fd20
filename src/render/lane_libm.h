#pragma once
// Elementary functions over four double lanes (lane_math.h's D4), for the area lights' per-sample
// path: the same IEEE operations in the same order in the SSE2 and the AVX2 build (no FMA), so a
// lane gives the same bits on every x86-64 CPU, and a scalar caller that puts its argument in a
// lane (sampling.cpp) gets the lanes' bits. Within 1 ulp of glibc, not bit for bit: the error
// bounds are asserted in tests/test_area_lights.cpp and what they do to images is in
// docs/performance.md. The polynomials and the argument reduction are fdlibm's (Sun Microsystems,
// 1993, freely distributable; as in musl's __sin, __cos and __rem_pio2).

#include "lane_math.h"

namespace rt::lane_math {

#define RT_LANE_INLINE [[gnu::always_inline]] inline

#ifdef __AVX2__
inline namespace avx2 {
#else
inline namespace sse2 {
#endif

// sin(x) and cos(x) for |x| < 2^20 (radians), within 1 ulp of glibc's where the result is not
// within 1e-9 of zero (there, within 1e-24 absolute). NaN gives NaN.
RT_LANE_INLINE void sincos(const D4& x, D4& sin_x, D4& cos_x) {
  // x = n pi/2 + (y0 + y1): pi/2 in two parts, the first of 33 bits so that n * pio2_1 is exact
  // for |n| < 2^20 (fdlibm's __rem_pio2, medium range, first step).
  const D4 n = round_to_integer(x * broadcast(6.36619772367581382433e-01));  // 2 / pi
  const D4 pio2_1 = broadcast(1.57079632673412561417e+00), pio2_1t = broadcast(6.07710050650619224932e-11);
  const D4 r = x - n * pio2_1, w = n * pio2_1t;
  const D4 y0 = r - w;
  const D4 y1 = (r - y0) - w;

  // fdlibm's kernels on |y0 + y1| <= pi/4.
  const D4 one = broadcast(1.0), half = broadcast(0.5);
  const D4 z = y0 * y0;
  const D4 v = z * y0;
  const D4 rs = broadcast(8.33333333332248946124e-03) +
                z * (broadcast(-1.98412698298579493134e-04) +
                     z * (broadcast(2.75573137070700676789e-06) +
                          z * (broadcast(-2.50507602534068634195e-08) + z * broadcast(1.58969099521155010221e-10))));
  const D4 s = y0 - ((z * (half * y1 - v * rs) - y1) - v * broadcast(-1.66666666666666324348e-01));
  const D4 rc = z * (broadcast(4.16666666666666019037e-02) +
                     z * (broadcast(-1.38888888888741095749e-03) +
                          z * (broadcast(2.48015872894767294178e-05) +
                               z * (broadcast(-2.75573143513906633035e-07) +
                                    z * (broadcast(2.08757232129817482790e-09) +
                                         z * broadcast(-1.13596475577881948265e-11))))));
  const D4 hz = half * z;
  const D4 c0 = one - hz;
  const D4 c = c0 + (((one - c0) - hz) + (z * rc - y0 * y1));

  // The quadrant q = n mod 4, exactly, from n / 4's floor: q 1 and 3 swap sine and cosine; the
  // sine is negated in quadrants 2 and 3, the cosine in 1 and 2.
  const D4 quarter = n * broadcast(0.25);
  D4 floor_quarter = round_to_integer(quarter);
  floor_quarter = select(floor_quarter > quarter, floor_quarter - one, floor_quarter);
  const D4 q = n - broadcast(4.0) * floor_quarter;
  const M4 odd = (q == one) | (q == broadcast(3.0));
  const D4 sine = select(odd, c, s), cosine = select(odd, s, c);
  sin_x = select(q > broadcast(1.5), -sine, sine);
  cos_x = select((q > half) & (q < broadcast(2.5)), -cosine, cosine);
}

}  // namespace avx2 or sse2

#undef RT_LANE_INLINE

}  // namespace rt::lane_math
