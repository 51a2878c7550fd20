#pragma once
// Four double lanes with the scalar operations' exact results, for the batch shader
// (batch_shade.cpp): +, -, *, / and sqrt are correctly rounded in SIMD as in scalar code, and the
// helpers below reproduce std::max, std::abs, std::clamp, ?: and the float32 round trips of
// ray_offset_detail bit for bit, without branches. GCC/Clang vector extensions: two SSE2 registers
// in the portable build, one AVX register in an RT_NATIVE build of an AVX machine. The code using
// them has a single build (no target_clones): a helper taking a 32-byte vector by value between an
// AVX2 clone and a baseline helper changes the ABI, which Clang rejects; within one build the
// helpers are always inlined, so GCC's -Wpsabi note about that ABI is moot (off for the file).

#include <cstdint>
#include <cstring>

namespace rt::lane_math {

using D4 = double __attribute__((vector_size(32)));
using M4 = std::int64_t __attribute__((vector_size(32)));  // a D4 comparison: all ones or zero per lane
using F4 = float __attribute__((vector_size(16)));
using I4 = std::int32_t __attribute__((vector_size(16)));  // an F4 comparison, or float32 bits

#define RT_LANE_INLINE [[gnu::always_inline]] inline

RT_LANE_INLINE void load(D4& out, const double* p) { std::memcpy(&out, p, sizeof out); }
RT_LANE_INLINE void store(double* p, const D4& v) { std::memcpy(p, &v, sizeof v); }
RT_LANE_INLINE void load(F4& out, const float* p) { std::memcpy(&out, p, sizeof out); }
RT_LANE_INLINE void store(float* p, const F4& v) { std::memcpy(p, &v, sizeof v); }

// m ? a : b per lane.
RT_LANE_INLINE D4 select(const M4& m, const D4& a, const D4& b) {
  M4 ai, bi;
  std::memcpy(&ai, &a, sizeof ai);
  std::memcpy(&bi, &b, sizeof bi);
  const M4 r = (m & ai) | (~m & bi);
  D4 out;
  std::memcpy(&out, &r, sizeof out);
  return out;
}

// std::max(a, b) = (a < b) ? b : a, NaN operands included.
RT_LANE_INLINE D4 max(const D4& a, const D4& b) { return select(a < b, b, a); }

// std::clamp(v, lo, hi) = v < lo ? lo : hi < v ? hi : v.
RT_LANE_INLINE D4 clamp(const D4& v, const D4& lo, const D4& hi) { return select(v < lo, lo, select(hi < v, hi, v)); }

// std::abs: the sign bit cleared.
RT_LANE_INLINE D4 abs(const D4& v) {
  M4 bits;
  std::memcpy(&bits, &v, sizeof bits);
  bits &= M4{} + INT64_MAX;
  D4 out;
  std::memcpy(&out, &bits, sizeof out);
  return out;
}

// std::sqrt per lane (correctly rounded; the file is compiled with -fno-math-errno).
RT_LANE_INLINE D4 sqrt(const D4& v) {
  double lanes[4];
  std::memcpy(lanes, &v, sizeof lanes);
  for (double& x : lanes) x = __builtin_sqrt(x);
  D4 out;
  std::memcpy(&out, lanes, sizeof out);
  return out;
}

RT_LANE_INLINE D4 broadcast(double x) { return D4{} + x; }

// static_cast<float> and back to double, per lane (round to nearest, as the scalar conversions).
RT_LANE_INLINE F4 to_float(const D4& v) { return __builtin_convertvector(v, F4); }
RT_LANE_INLINE D4 to_double(const F4& v) { return __builtin_convertvector(v, D4); }

// A 64-bit-lane mask narrowed to the float lanes.
RT_LANE_INLINE I4 narrow(const M4& m) { return __builtin_convertvector(m, I4); }

// ray_offset_detail::round_away per lane: p rounded to float32 and, where rounding moved it against
// `away`, one float further along `away`. next_float's step on the bits: +1 moves a positive float
// (or +0) up and a negative one (or -0) down, -1 the reverse. Rounding lands on +0 only for p > 0
// (a step up) and on -0 only for p < 0 (a step down), so both zeros step to +-2^-149 as there.
RT_LANE_INLINE F4 round_away(const D4& p, const D4& away) {
  const F4 f = to_float(p);
  const D4 back = to_double(f);
  const D4 zero{};
  const I4 up = narrow((away > zero) & (back < p));
  const I4 down = narrow((away < zero) & (back > p));
  I4 bits;
  std::memcpy(&bits, &f, sizeof bits);
  const I4 negative = bits >> 31;  // all ones where the sign bit is set
  const I4 step = ~(negative ^ up) | (I4{} + 1);  // -1 where negative == up, else +1
  bits += (up | down) & step;
  F4 out;
  std::memcpy(&out, &bits, sizeof out);
  return out;
}

#undef RT_LANE_INLINE

}  // namespace rt::lane_math
