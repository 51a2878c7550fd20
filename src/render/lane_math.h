#pragma once
// Four double lanes with the scalar operations' exact results, for the batch shader
// (batch_lanes.cpp): +, -, *, / and sqrt are correctly rounded in SIMD as in scalar code, and the
// helpers below reproduce unary minus, std::max, std::abs, std::clamp, ?: and the float32 round
// trips of ray_offset_detail bit for bit, without branches. Two implementations with one
// interface: SSE2 intrinsics (two registers per value; every x86-64 has them) and, in a file built
// with -mavx2, AVX ones (one register). A file built with -mavx512f -mavx512dq -mavx512vl has the
// AVX ones and D8, eight lanes in one register with the same operations. Each build lives in its
// own inline namespace (RT_LANE_NAMESPACE: sse2, avx2 or avx512), so no two builds' types and
// helpers share a name. (GCC's generic 32-byte vectors lower their comparisons to scalar code
// without AVX, hence the intrinsics.)

#include <immintrin.h>

#include <cstdint>
#include <cstring>
#include <type_traits>

namespace rt::lane_math {

#define RT_LANE_INLINE [[gnu::always_inline]] inline

#if defined(__AVX512F__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
#define RT_LANE_NAMESPACE avx512
#elif defined(__AVX2__)
#define RT_LANE_NAMESPACE avx2
#else
#define RT_LANE_NAMESPACE sse2
#endif

#ifdef __AVX2__
inline namespace RT_LANE_NAMESPACE {

struct D4 {
  __m256d v;  // D4{} is all zeros
};
struct M4 {  // a comparison's result: all ones or all zeros per 64-bit lane
  __m256d v;
};
using F4 = __m128;  // four float32 lanes

RT_LANE_INLINE D4 broadcast(double x) {
  return {_mm256_set1_pd(x)};
}
// Lanes (a, b, c, d) from scalars, without a trip through memory: a wide load of values just
// stored one by one waits for the stores (store forwarding fails when a load spans several).
RT_LANE_INLINE D4 set(double a, double b, double c, double d) {
  return {_mm256_setr_pd(a, b, c, d)};
}
RT_LANE_INLINE void load(D4& out, const double* p) {
  out.v = _mm256_loadu_pd(p);
}
RT_LANE_INLINE void store(double* p, const D4& v) {
  _mm256_storeu_pd(p, v.v);
}

#define RT_LANE_BINARY(op, intrinsic)                       \
  RT_LANE_INLINE D4 operator op(const D4& a, const D4& b) { \
    return {intrinsic(a.v, b.v)};                           \
  }
RT_LANE_BINARY(+, _mm256_add_pd)
RT_LANE_BINARY(-, _mm256_sub_pd)
RT_LANE_BINARY(*, _mm256_mul_pd)
RT_LANE_BINARY(/, _mm256_div_pd)
#undef RT_LANE_BINARY

RT_LANE_INLINE D4 operator-(const D4& a) {
  return {_mm256_xor_pd(a.v, _mm256_set1_pd(-0.0))};
}

// Ordered, quiet comparisons: false where either operand is NaN, as in scalar code.
RT_LANE_INLINE M4 operator<(const D4& a, const D4& b) {
  return {_mm256_cmp_pd(a.v, b.v, _CMP_LT_OQ)};
}
RT_LANE_INLINE M4 operator>(const D4& a, const D4& b) {
  return {_mm256_cmp_pd(a.v, b.v, _CMP_GT_OQ)};
}
RT_LANE_INLINE M4 operator>=(const D4& a, const D4& b) {
  return {_mm256_cmp_pd(a.v, b.v, _CMP_GE_OQ)};
}
// Unordered: true where either operand is NaN, as scalar != is.
RT_LANE_INLINE M4 operator!=(const D4& a, const D4& b) {
  return {_mm256_cmp_pd(a.v, b.v, _CMP_NEQ_UQ)};
}

RT_LANE_INLINE M4 operator&(const M4& a, const M4& b) {
  return {_mm256_and_pd(a.v, b.v)};
}
RT_LANE_INLINE M4 operator|(const M4& a, const M4& b) {
  return {_mm256_or_pd(a.v, b.v)};
}
RT_LANE_INLINE M4 operator~(const M4& a) {
  return {_mm256_xor_pd(a.v, _mm256_castsi256_pd(_mm256_set1_epi32(-1)))};
}

RT_LANE_INLINE D4 select(const M4& m, const D4& a, const D4& b) {
  return {_mm256_or_pd(_mm256_and_pd(m.v, a.v), _mm256_andnot_pd(m.v, b.v))};
}
RT_LANE_INLINE D4 abs(const D4& v) {
  return {_mm256_andnot_pd(_mm256_set1_pd(-0.0), v.v)};
}
RT_LANE_INLINE D4 sqrt(const D4& v) {
  return {_mm256_sqrt_pd(v.v)};
}
RT_LANE_INLINE F4 to_float(const D4& v) {
  return _mm256_cvtpd_ps(v.v);
}
RT_LANE_INLINE D4 to_double(const F4& v) {
  return {_mm256_cvtps_pd(v)};
}
RT_LANE_INLINE __m128i narrow(const M4& m) {
  return _mm_castps_si128(_mm_shuffle_ps(_mm_castpd_ps(_mm256_castpd256_pd128(m.v)),
                                         _mm_castpd_ps(_mm256_extractf128_pd(m.v, 1)),
                                         _MM_SHUFFLE(2, 0, 2, 0)));
}

RT_LANE_INLINE bool any(const M4& m) {
  return _mm256_movemask_pd(m.v) != 0;
}

RT_LANE_INLINE D4 from_bits(std::uint64_t bits) {
  return {_mm256_castsi256_pd(_mm256_set1_epi64x(static_cast<long long>(bits)))};
}
RT_LANE_INLINE D4 bit_and(const D4& a, const D4& b) {
  return {_mm256_and_pd(a.v, b.v)};
}
RT_LANE_INLINE D4 bit_or(const D4& a, const D4& b) {
  return {_mm256_or_pd(a.v, b.v)};
}
template <int bits>
RT_LANE_INLINE D4 shift_left(const D4& a) {
  return {_mm256_castsi256_pd(_mm256_slli_epi64(_mm256_castpd_si256(a.v), bits))};
}
template <int bits>
RT_LANE_INLINE D4 shift_right(const D4& a) {
  return {_mm256_castsi256_pd(_mm256_srli_epi64(_mm256_castpd_si256(a.v), bits))};
}

// A lane's entry of a four-entry table (table[slot], slot 0 .. 3 exact in a double lane): one
// vpermps per lookup, the index set up once.
struct Lookup {
  __m256i index;  // the 32-bit halves (2 slot, 2 slot + 1) of each lane
};
RT_LANE_INLINE Lookup make_lookup(const D4& slot) {
  const __m256i twice = _mm256_cvtepi32_epi64(_mm_slli_epi32(_mm256_cvttpd_epi32(slot.v), 1));
  return {_mm256_or_si256(twice, _mm256_slli_epi64(_mm256_add_epi64(twice, _mm256_set1_epi64x(1)), 32))};
}
RT_LANE_INLINE D4 lookup(const double* table, const Lookup& l) {
  return {_mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(_mm256_loadu_pd(table)), l.index))};
}

}  // namespace RT_LANE_NAMESPACE
#else
inline namespace RT_LANE_NAMESPACE {

struct D4 {
  __m128d lo, hi;  // lanes 0-1 and 2-3; D4{} is all zeros
};
struct M4 {  // a comparison's result: all ones or all zeros per 64-bit lane
  __m128d lo, hi;
};
using F4 = __m128;  // four float32 lanes

RT_LANE_INLINE D4 broadcast(double x) {
  return {_mm_set1_pd(x), _mm_set1_pd(x)};
}
RT_LANE_INLINE D4 set(double a, double b, double c, double d) {
  return {_mm_setr_pd(a, b), _mm_setr_pd(c, d)};
}

RT_LANE_INLINE void load(D4& out, const double* p) {
  out.lo = _mm_loadu_pd(p);
  out.hi = _mm_loadu_pd(p + 2);
}
RT_LANE_INLINE void store(double* p, const D4& v) {
  _mm_storeu_pd(p, v.lo);
  _mm_storeu_pd(p + 2, v.hi);
}

#define RT_LANE_BINARY(op, intrinsic)                       \
  RT_LANE_INLINE D4 operator op(const D4& a, const D4& b) { \
    return {intrinsic(a.lo, b.lo), intrinsic(a.hi, b.hi)};  \
  }
RT_LANE_BINARY(+, _mm_add_pd)
RT_LANE_BINARY(-, _mm_sub_pd)
RT_LANE_BINARY(*, _mm_mul_pd)
RT_LANE_BINARY(/, _mm_div_pd)
#undef RT_LANE_BINARY

// -x flips the sign bit, as scalar negation does.
RT_LANE_INLINE D4 operator-(const D4& a) {
  const __m128d sign = _mm_set1_pd(-0.0);
  return {_mm_xor_pd(a.lo, sign), _mm_xor_pd(a.hi, sign)};
}

#define RT_LANE_COMPARE(op, intrinsic)                      \
  RT_LANE_INLINE M4 operator op(const D4& a, const D4& b) { \
    return {intrinsic(a.lo, b.lo), intrinsic(a.hi, b.hi)};  \
  }
RT_LANE_COMPARE(<, _mm_cmplt_pd)  // ordered: false where either is NaN, as in scalar code
RT_LANE_COMPARE(>, _mm_cmpgt_pd)
RT_LANE_COMPARE(>=, _mm_cmpge_pd)
RT_LANE_COMPARE(!=, _mm_cmpneq_pd)  // unordered: true where either is NaN, as scalar != is
#undef RT_LANE_COMPARE

RT_LANE_INLINE M4 operator&(const M4& a, const M4& b) {
  return {_mm_and_pd(a.lo, b.lo), _mm_and_pd(a.hi, b.hi)};
}
RT_LANE_INLINE M4 operator|(const M4& a, const M4& b) {
  return {_mm_or_pd(a.lo, b.lo), _mm_or_pd(a.hi, b.hi)};
}
RT_LANE_INLINE M4 operator~(const M4& a) {
  const __m128d ones = _mm_castsi128_pd(_mm_set1_epi32(-1));
  return {_mm_xor_pd(a.lo, ones), _mm_xor_pd(a.hi, ones)};
}

// m ? a : b per lane.
RT_LANE_INLINE D4 select(const M4& m, const D4& a, const D4& b) {
  return {_mm_or_pd(_mm_and_pd(m.lo, a.lo), _mm_andnot_pd(m.lo, b.lo)),
          _mm_or_pd(_mm_and_pd(m.hi, a.hi), _mm_andnot_pd(m.hi, b.hi))};
}

// std::abs: the sign bit cleared.
RT_LANE_INLINE D4 abs(const D4& v) {
  const __m128d sign = _mm_set1_pd(-0.0);
  return {_mm_andnot_pd(sign, v.lo), _mm_andnot_pd(sign, v.hi)};
}

// std::sqrt per lane: sqrtpd is correctly rounded like sqrtsd.
RT_LANE_INLINE D4 sqrt(const D4& v) {
  return {_mm_sqrt_pd(v.lo), _mm_sqrt_pd(v.hi)};
}

// static_cast<float> and back to double, per lane (round to nearest, as the scalar conversions).
RT_LANE_INLINE F4 to_float(const D4& v) {
  return _mm_movelh_ps(_mm_cvtpd_ps(v.lo), _mm_cvtpd_ps(v.hi));
}
RT_LANE_INLINE D4 to_double(const F4& v) {
  return {_mm_cvtps_pd(v), _mm_cvtps_pd(_mm_movehl_ps(v, v))};
}

// A 64-bit-lane mask narrowed to the four float lanes (the low half of each 64-bit lane).
RT_LANE_INLINE __m128i narrow(const M4& m) {
  return _mm_castps_si128(_mm_shuffle_ps(_mm_castpd_ps(m.lo), _mm_castpd_ps(m.hi), _MM_SHUFFLE(2, 0, 2, 0)));
}

// Whether any lane of m is set.
RT_LANE_INLINE bool any(const M4& m) {
  return (_mm_movemask_pd(m.lo) | _mm_movemask_pd(m.hi)) != 0;
}

// The lanes as 64-bit patterns (for lane_libm.h's exponent arithmetic): a pattern broadcast, the
// bitwise and and or, and logical shifts of each lane's 64 bits.
RT_LANE_INLINE D4 from_bits(std::uint64_t bits) {
  const __m128d v = _mm_castsi128_pd(_mm_set1_epi64x(static_cast<long long>(bits)));
  return {v, v};
}
RT_LANE_INLINE D4 bit_and(const D4& a, const D4& b) {
  return {_mm_and_pd(a.lo, b.lo), _mm_and_pd(a.hi, b.hi)};
}
RT_LANE_INLINE D4 bit_or(const D4& a, const D4& b) {
  return {_mm_or_pd(a.lo, b.lo), _mm_or_pd(a.hi, b.hi)};
}
template <int bits>
RT_LANE_INLINE D4 shift_left(const D4& a) {
  return {_mm_castsi128_pd(_mm_slli_epi64(_mm_castpd_si128(a.lo), bits)),
          _mm_castsi128_pd(_mm_slli_epi64(_mm_castpd_si128(a.hi), bits))};
}
template <int bits>
RT_LANE_INLINE D4 shift_right(const D4& a) {
  return {_mm_castsi128_pd(_mm_srli_epi64(_mm_castpd_si128(a.lo), bits)),
          _mm_castsi128_pd(_mm_srli_epi64(_mm_castpd_si128(a.hi), bits))};
}

}  // namespace RT_LANE_NAMESPACE
#endif

// Built on either implementation.

RT_LANE_INLINE void load(M4& out, const std::int64_t* p) {
  std::memcpy(&out, p, sizeof out);
}
RT_LANE_INLINE void store(std::int64_t* p, const M4& m) {
  std::memcpy(p, &m, sizeof m);
}
RT_LANE_INLINE void load(F4& out, const float* p) {
  out = _mm_loadu_ps(p);
}
RT_LANE_INLINE void store(float* p, const F4& v) {
  _mm_storeu_ps(p, v);
}

// a == b: false where either is NaN, as scalar == is.
RT_LANE_INLINE M4 operator==(const D4& a, const D4& b) {
  return ~(a != b);
}

// A lane's entry of a four-entry table (table[slot], slot 0 .. 3 exact in a double lane); the
// AVX2 build has its own.
#ifndef __AVX2__
struct Lookup {
  M4 is[4];  // [s]: the lane's slot is s (from 1)
};
RT_LANE_INLINE Lookup make_lookup(const D4& slot) {
  Lookup l;
  for (int s = 1; s < 4; ++s) l.is[s] = slot == broadcast(double(s));
  return l;
}
RT_LANE_INLINE D4 lookup(const double* table, const Lookup& l) {
  D4 v = broadcast(table[0]);
  for (int s = 1; s < 4; ++s) v = select(l.is[s], broadcast(table[s]), v);
  return v;
}
#endif

// ray_offset_detail::round_away per lane: p rounded to float32 and, where rounding moved it against
// `away`, one float further along `away`. next_float's step on the bits: +1 moves a positive float
// (or +0) up and a negative one (or -0) down, -1 the reverse. Rounding lands on +0 only for p > 0
// (a step up) and on -0 only for p < 0 (a step down), so both zeros step to +-2^-149 as there.
RT_LANE_INLINE F4 round_away(const D4& p, const D4& away) {
  const F4 f = to_float(p);
  const D4 back = to_double(f);
  const D4 zero{};
  const __m128i up = narrow((away > zero) & (back < p));
  const __m128i down = narrow((zero > away) & (p < back));
  const __m128i bits = _mm_castps_si128(f);
  const __m128i negative = _mm_srai_epi32(bits, 31);  // all ones where the sign bit is set
  // -1 where negative == up, else +1.
  const __m128i step =
      _mm_or_si128(_mm_xor_si128(_mm_xor_si128(negative, up), _mm_set1_epi32(-1)), _mm_set1_epi32(1));
  return _mm_castsi128_ps(_mm_add_epi32(bits, _mm_and_si128(_mm_or_si128(up, down), step)));
}

#ifdef __AVX512F__
inline namespace RT_LANE_NAMESPACE {

// Eight double lanes in one zmm register (the AVX-512 build only) with D4's operations and the
// same bits per lane; a comparison's result is a bit mask, one bit per lane. (Some operations use
// the all-lanes masked form of an intrinsic: GCC 12's unmasked one starts from an "undefined"
// register that -Wmaybe-uninitialized reports; a full mask compiles to the same instruction.)
struct D8 {
  __m512d v;  // D8{} is all zeros
};
struct M8 {
  __mmask8 k;
};
using F8 = __m256;  // eight float32 lanes

RT_LANE_INLINE void load(D8& out, const double* p) {
  out.v = _mm512_loadu_pd(p);
}
RT_LANE_INLINE void store(double* p, const D8& v) {
  _mm512_storeu_pd(p, v.v);
}
// From and to int64 masks (all ones or 0 per lane, as M4's memory layout).
RT_LANE_INLINE void load(M8& out, const std::int64_t* p) {
  const __m512i v = _mm512_loadu_si512(p);
  out.k = _mm512_test_epi64_mask(v, v);
}
RT_LANE_INLINE void store(std::int64_t* p, const M8& m) {
  _mm512_storeu_si512(p, _mm512_maskz_set1_epi64(m.k, -1));
}

#define RT_LANE_BINARY(op, intrinsic)                       \
  RT_LANE_INLINE D8 operator op(const D8& a, const D8& b) { \
    return {intrinsic(a.v, b.v)};                           \
  }
RT_LANE_BINARY(+, _mm512_add_pd)
RT_LANE_BINARY(-, _mm512_sub_pd)
RT_LANE_BINARY(*, _mm512_mul_pd)
RT_LANE_BINARY(/, _mm512_div_pd)
#undef RT_LANE_BINARY
RT_LANE_INLINE D8 operator-(const D8& a) {
  return {_mm512_xor_pd(a.v, _mm512_set1_pd(-0.0))};
}

// The predicates of D4's comparisons: ordered and quiet, != unordered; == is ~(!=).
#define RT_LANE_COMPARE(op, predicate)                      \
  RT_LANE_INLINE M8 operator op(const D8& a, const D8& b) { \
    return {_mm512_cmp_pd_mask(a.v, b.v, predicate)};       \
  }
RT_LANE_COMPARE(<, _CMP_LT_OQ)
RT_LANE_COMPARE(>, _CMP_GT_OQ)
RT_LANE_COMPARE(>=, _CMP_GE_OQ)
RT_LANE_COMPARE(!=, _CMP_NEQ_UQ)
RT_LANE_COMPARE(==, _CMP_EQ_OQ)
#undef RT_LANE_COMPARE

RT_LANE_INLINE M8 operator&(const M8& a, const M8& b) {
  return {static_cast<__mmask8>(a.k & b.k)};
}
RT_LANE_INLINE M8 operator|(const M8& a, const M8& b) {
  return {static_cast<__mmask8>(a.k | b.k)};
}
RT_LANE_INLINE M8 operator~(const M8& a) {
  return {static_cast<__mmask8>(~a.k)};
}
RT_LANE_INLINE bool any(const M8& m) {
  return m.k != 0;
}

RT_LANE_INLINE D8 select(const M8& m, const D8& a, const D8& b) {
  return {_mm512_mask_blend_pd(m.k, b.v, a.v)};
}
RT_LANE_INLINE D8 abs(const D8& v) {
  return {_mm512_andnot_pd(_mm512_set1_pd(-0.0), v.v)};
}
RT_LANE_INLINE D8 sqrt(const D8& v) {
  return {_mm512_maskz_sqrt_pd(0xFF, v.v)};
}

RT_LANE_INLINE D8 bit_and(const D8& a, const D8& b) {
  return {_mm512_and_pd(a.v, b.v)};
}
RT_LANE_INLINE D8 bit_or(const D8& a, const D8& b) {
  return {_mm512_or_pd(a.v, b.v)};
}
template <int bits>
RT_LANE_INLINE D8 shift_left(const D8& a) {
  return {_mm512_castsi512_pd(_mm512_maskz_slli_epi64(0xFF, _mm512_castpd_si512(a.v), bits))};
}
template <int bits>
RT_LANE_INLINE D8 shift_right(const D8& a) {
  return {_mm512_castsi512_pd(_mm512_maskz_srli_epi64(0xFF, _mm512_castpd_si512(a.v), bits))};
}

// static_cast<float> and back, per lane (round to nearest).
RT_LANE_INLINE F8 to_float(const D8& v) {
  return _mm512_maskz_cvtpd_ps(0xFF, v.v);
}
RT_LANE_INLINE D8 to_double(const F8& v) {
  return {_mm512_maskz_cvtps_pd(0xFF, v)};
}
RT_LANE_INLINE void load(F8& out, const float* p) {
  out = _mm256_loadu_ps(p);
}
RT_LANE_INLINE void store(float* p, const F8& v) {
  _mm256_storeu_ps(p, v);
}

// round_away (D4's, above) for eight lanes: the step on the float's bits is +1 where rounding
// moved p against a positive `away` (up), -1 where against a negative one (down), negated where
// the float is negative ((s ^ n) - n, n all ones there).
RT_LANE_INLINE F8 round_away(const D8& p, const D8& away) {
  const F8 f = to_float(p);
  const D8 back = to_double(f);
  const D8 zero{};
  const M8 up = (away > zero) & (back < p);
  const M8 down = (zero > away) & (p < back);
  const __m256i bits = _mm256_castps_si256(f);
  const __m256i negative = _mm256_srai_epi32(bits, 31);
  const __m256i direction = _mm256_mask_blend_epi32(up.k, _mm256_set1_epi32(-1), _mm256_set1_epi32(1));
  const __m256i step = _mm256_sub_epi32(_mm256_xor_si256(direction, negative), negative);
  return _mm256_castsi256_ps(_mm256_mask_add_epi32(bits, (up | down).k, bits, step));
}

// A lane's entry of a four-entry table, as make_lookup and lookup for D4 (one vpermpd).
struct Lookup8 {
  __m512i index;  // the lane's slot, 0 .. 3
};
RT_LANE_INLINE Lookup8 make_lookup(const D8& slot) {
  return {_mm512_cvttpd_epi64(slot.v)};
}
RT_LANE_INLINE D8 lookup(const double* table, const Lookup8& l) {
  return {_mm512_maskz_permutexvar_pd(0xFF, l.index, _mm512_maskz_loadu_pd(0x0F, table))};
}

}  // namespace RT_LANE_NAMESPACE
#endif

inline namespace RT_LANE_NAMESPACE {

// The mask type of a group G's comparisons (M4 or M8).
template <class G>
using MaskOf = decltype(G{} < G{});

// A constant in every lane of a value of type V (a group, D4 or D8, or lane_libm.h's Wide).
template <class V>
struct Splat;
template <>
struct Splat<D4> {
  RT_LANE_INLINE static D4 value(double x) { return broadcast(x); }
  RT_LANE_INLINE static D4 bits(std::uint64_t b) { return from_bits(b); }
};
#ifdef __AVX512F__
template <>
struct Splat<D8> {
  RT_LANE_INLINE static D8 value(double x) { return {_mm512_set1_pd(x)}; }
  RT_LANE_INLINE static D8 bits(std::uint64_t b) {
    return {_mm512_castsi512_pd(_mm512_set1_epi64(static_cast<long long>(b)))};
  }
};
#endif

// Whether G is a group of lanes (D4, or D8 in the AVX-512 build), for the operations below.
template <class G>
inline constexpr bool kIsGroup = std::is_same_v<G, D4>
#ifdef __AVX512F__
                                 || std::is_same_v<G, D8>
#endif
    ;

// a op= b.
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G& operator+=(G& a, const G& b) {
  return a = a + b;
}
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G& operator-=(G& a, const G& b) {
  return a = a - b;
}
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G& operator*=(G& a, const G& b) {
  return a = a * b;
}
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G& operator/=(G& a, const G& b) {
  return a = a / b;
}

// std::max(a, b) = (a < b) ? b : a, NaN operands included (maxpd differs there).
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G max(const G& a, const G& b) {
  return select(a < b, b, a);
}

// std::clamp(v, lo, hi) = v < lo ? lo : hi < v ? hi : v.
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G clamp(const G& v, const G& lo, const G& hi) {
  return select(v < lo, lo, select(hi < v, hi, v));
}

// Round to the nearest integer, ties to even, for |x| < 2^51: adding and subtracting 1.5 * 2^52
// leaves no fraction bits (the round-to-nearest of the addition does the rounding).
template <class G>
  requires kIsGroup<G>
RT_LANE_INLINE G round_to_integer(const G& x) {
  const G shift = Splat<G>::value(0x1.8p52);
  return (x + shift) - shift;
}

// f(G{}, g) for each group G of lanes 0 .. count - 1, g its first lane: D8 (eight lanes) while
// eight remain in the AVX-512 build, then D4 (four, the last one possibly past `count`).
template <class F>
RT_LANE_INLINE void for_each_group(int count, const F& f) {
  int g = 0;
#ifdef __AVX512F__
  for (; g + 8 <= count; g += 8) f(D8{}, g);
#endif
  for (; g < count; g += 4) f(D4{}, g);
}

// Whether the CPU runs the build this file is compiled in (AVX-512 F, DQ and VL; AVX2; SSE2, which
// every x86-64 has).
RT_LANE_INLINE bool cpu_runs_this_build() {
  __builtin_cpu_init();  // idempotent; needed when called before the constructors have run
#if defined(__AVX512F__)
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx2");
#elif defined(__AVX2__)
  return __builtin_cpu_supports("avx2");
#else
  return true;
#endif
}

// Three-vectors of lanes (world space, double) and glm's operations on them, with glm's order of
// operations; V is a group (D4, D8) or lane_libm.h's Wide. Their layout differs between the
// implementations, so they live in each one's inline namespace.
template <class V>
struct Vec3Of {
  V x, y, z;
};
using Xyz = Vec3Of<D4>;

// Lanes g .. g + G's lanes - 1 of a structure of arrays `v` (v.x.v, v.y.v, v.z.v: double arrays),
// and back.
template <class G, class Lanes3>
RT_LANE_INLINE void load(Vec3Of<G>& out, const Lanes3& v, int g) {
  load(out.x, v.x.v + g);
  load(out.y, v.y.v + g);
  load(out.z, v.z.v + g);
}
template <class G, class Lanes3>
RT_LANE_INLINE void store(Lanes3& to, int g, const Vec3Of<G>& v) {
  store(to.x.v + g, v.x);
  store(to.y.v + g, v.y);
  store(to.z.v + g, v.z);
}

// glm::dot: (a.x b.x + a.y b.y) + a.z b.z.
template <class V>
RT_LANE_INLINE V dot(const Vec3Of<V>& a, const Vec3Of<V>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

// glm::cross.
template <class V>
RT_LANE_INLINE Vec3Of<V> cross(const Vec3Of<V>& a, const Vec3Of<V>& b) {
  return {a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y};
}

// glm::normalize: v times 1 / sqrt(v . v).
template <class V>
RT_LANE_INLINE Vec3Of<V> normalize(const Vec3Of<V>& v) {
  const V scale = Splat<V>::value(1.0) / sqrt(dot(v, v));
  return {v.x * scale, v.y * scale, v.z * scale};
}

// a - b, component by component.
template <class V>
RT_LANE_INLINE Vec3Of<V> minus(const Vec3Of<V>& a, const Vec3Of<V>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}

}  // namespace RT_LANE_NAMESPACE

#undef RT_LANE_INLINE

}  // namespace rt::lane_math
