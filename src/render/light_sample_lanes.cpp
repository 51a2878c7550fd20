// Built three times: as itself (baseline x86-64), included by light_sample_lanes_avx2.cpp with
// RT_LIGHT_SAMPLE_LANES_AVX2 and -mavx2, and by light_sample_lanes_avx512.cpp with
// RT_LIGHT_SAMPLE_LANES_AVX512 and -mavx512f -mavx512dq -mavx512vl. Only lane_math.h's and
// lane_libm.h's always-inlined helpers are used, each in its build's inline namespace, so the
// wider builds emit no function that a baseline file could link.

#include "light_sample_lanes.h"

#include <cmath>
#include <numbers>
#include <vector>

#include "lane_libm.h"
#include "lane_math.h"
#include "rt/render/ray_offset.h"

namespace rt::light_sample_lanes {

#if defined(RT_LIGHT_SAMPLE_LANES_AVX512)
namespace avx512 {
#elif defined(RT_LIGHT_SAMPLE_LANES_AVX2)
namespace avx2 {
#else
namespace baseline {
#endif

namespace lm = lane_math;
using lm::D4;
using lm::Wide;
using lm::WideMask;

// W = Wide<N, G>: N groups G of lanes (lane_libm.h). The kernel's arithmetic is issued for all N
// groups together, so that their long chains of divisions and square roots overlap. Three-vectors
// of them are lane_math.h's Vec3Of, with glm's dot, cross and normalize.
using lm::Vec3Of;

template <class W>
[[gnu::always_inline]] static inline W at(const Lanes& v, int g) {
  W out;
  for (int i = 0; i < W::kGroups; ++i) lm::load(out.g[i], v.v + g + W::kGroupLanes * i);
  return out;
}
template <class W>
[[gnu::always_inline]] static inline Vec3Of<W> at3(const Vec3& v, int g) {
  return {at<W>(v.x, g), at<W>(v.y, g), at<W>(v.z, g)};
}
template <class W>
[[gnu::always_inline]] static inline void put(Lanes& to, int g, const W& v) {
  for (int i = 0; i < W::kGroups; ++i) lm::store(to.v + g + W::kGroupLanes * i, v.g[i]);
}
template <class W>
[[gnu::always_inline]] static inline void put(Vec3& to, int g, const Vec3Of<W>& v) {
  put(to.x, g, v.x);
  put(to.y, g, v.y);
  put(to.z, g, v.z);
}
template <class W>
[[gnu::always_inline]] static inline void put(std::int64_t* to, int g, const typename W::Mask& m) {
  for (int i = 0; i < W::kGroups; ++i) lm::store(to + g + W::kGroupLanes * i, m.g[i]);
}
template <class W>
[[gnu::always_inline]] static inline typename W::Mask mask_at(const std::int64_t* from, int g) {
  typename W::Mask out;
  for (int i = 0; i < W::kGroups; ++i) lm::load(out.g[i], from + g + W::kGroupLanes * i);
  return out;
}
template <class W>
[[gnu::always_inline]] static inline W splat(double x) {
  return lm::Splat<W>::value(x);
}
template <class M>
[[gnu::always_inline]] static inline bool any(const M& m) {
  bool set = false;
  for (const auto& group : m.g) set = set || lm::any(group);
  return set;
}

// Where lanes g .. g + W::kLanes - 1 read their triangle's inputs (Input's per-triangle fields):
// their own lanes, or the entries of their slots.
template <class W>
struct PerLane {
  PerLane(const Input&, int g) : first(g) {}
  W operator()(const Lanes& field) const { return at<W>(field, first); }
  Vec3Of<W> operator()(const Vec3& field) const { return at3<W>(field, first); }
  int first;
};
template <class W>
struct BySlot {
  BySlot(const Input& in, int g) {
    for (int i = 0; i < W::kGroups; ++i) {
      typename W::Group slot;
      lm::load(slot, in.slot.v + g + W::kGroupLanes * i);
      lookups[i] = lm::make_lookup(slot);
    }
  }
  W operator()(const Lanes& field) const {
    W v;
    for (int i = 0; i < W::kGroups; ++i) v.g[i] = lm::lookup(field.v, lookups[i]);
    return v;
  }
  Vec3Of<W> operator()(const Vec3& field) const { return {(*this)(field.x), (*this)(field.y), (*this)(field.z)}; }
  decltype(lm::make_lookup(typename W::Group{})) lookups[W::kGroups];
};

// a s + b t, component by component.
template <class W>
[[gnu::always_inline]] static inline Vec3Of<W> combine(const W& s, const Vec3Of<W>& a, const W& t, const Vec3Of<W>& b) {
  return {s * a.x + t * b.x, s * a.y + t * b.y, s * a.z + t * b.z};
}

// SphericalTriangle::sample (sampling.cpp).
template <class W, class Fetch>
[[gnu::always_inline]] static inline Vec3Of<W> arvo_direction(const Input& in, int g, const Fetch& fetch) {
  const W zero = splat<W>(0.0), one = splat<W>(1.0);
  W s, t;
  lm::sincos(at<W>(in.angle, g), s, t);
  const W cos_alpha = fetch(in.cos_alpha), sin_alpha = fetch(in.sin_alpha);
  const W uu = t - cos_alpha, vv = s + sin_alpha * fetch(in.cos_c);
  const W denominator = (vv * s + uu * t) * sin_alpha;
  const W q = lm::select(denominator != zero, lm::clamp(((vv * t - uu * s) * cos_alpha - vv) / denominator, -one, one), one);
  const Vec3Of<W> b = fetch(in.b);
  const Vec3Of<W> c_prime = combine(q, fetch(in.a), lm::sqrt(lm::max(zero, one - q * q)), fetch(in.c_perp));
  const W cosine = dot(c_prime, b);
  const W z = one - at<W>(in.v, g) * (one - cosine);
  const Vec3Of<W> across = normalize(Vec3Of<W>{c_prime.x - cosine * b.x, c_prime.y - cosine * b.y, c_prime.z - cosine * b.z});
  return normalize(combine(z, b, lm::sqrt(lm::max(zero, one - z * z)), across));
}

// Lanes g .. g + W::kLanes - 1 of the kernel.
template <class W, template <class> class Fetch>
[[gnu::always_inline]] static inline void sample_groups(const Input& in, int g, Output& out) {
  using Mask = typename W::Mask;
  const Fetch<W> fetch(in, g);
  const W zero = splat<W>(0.0), one = splat<W>(1.0);
  const Vec3Of<W> point{splat<W>(in.point[0]), splat<W>(in.point[1]), splat<W>(in.point[2])};
  const Vec3Of<W> p0 = fetch(in.p0), p1 = fetch(in.p1), p2 = fetch(in.p2);
  const Mask by_solid_angle = mask_at<W>(in.by_solid_angle, g);
  const Mask all = zero == zero;

  // Where sampled by area, sample_triangle_uniform's barycentrics; elsewhere barycentrics_along(
  // point, w, p0, p1, p2) for the warped direction w. What no lane of the groups reads is not
  // computed: the divider is this kernel's bottleneck, and skipping changes no lane's bits.
  W b1 = at<W>(in.b1, g), b2 = at<W>(in.b2, g);
  Mask valid = all;
  if (any(by_solid_angle)) {
    const Vec3Of<W> w = arvo_direction<W>(in, g, fetch);
    const Vec3Of<W> e1 = minus(p1, p0), e2 = minus(p2, p0);
    const Vec3Of<W> pv = cross(w, e2);
    const W determinant = dot(e1, pv);
    const Vec3Of<W> tv = minus(point, p0);
    W along1 = lm::clamp(dot(tv, pv) / determinant, zero, one);
    W along2 = lm::clamp(dot(w, cross(tv, e1)) / determinant, zero, one);
    const W sum = along1 + along2;
    const Mask over = sum > one;
    if (any(over)) {  // rare: rounding put the point past the far side
      along1 = lm::select(over, along1 / sum, along1);
      along2 = lm::select(over, along2 / sum, along2);
    }
    b1 = lm::select(by_solid_angle, along1, b1);
    b2 = lm::select(by_solid_angle, along2, b2);
    valid = ~by_solid_angle | (determinant != zero);
  }

  put(out.b1, g, b1);
  put(out.b2, g, b2);

  // make_surface_point.
  const W w0 = one - b1 - b2;
  const Vec3Of<W> p{w0 * p0.x + b1 * p1.x + b2 * p2.x, w0 * p0.y + b1 * p1.y + b2 * p2.y, w0 * p0.z + b1 * p1.z + b2 * p2.z};
  put(out.point, g, p);
  const W largest = lm::max(lm::max(lm::abs(p.x), lm::abs(p.y)), lm::abs(p.z));
  put(out.error_bound, g,
      splat<W>(ray_offset_detail::kScaledRoundoff) * (splat<W>(std::sqrt(3.0)) * largest + fetch(in.edge_term)));

  // The unit direction and distance from the shading point (EmitterSampler::sample).
  const Vec3Of<W> offset = minus(p, point);
  const W distance = lm::sqrt(dot(offset, offset));
  valid = valid & (distance > zero);
  put(out.distance, g, distance);
  const Vec3Of<W> direction{offset.x / distance, offset.y / distance, offset.z / distance};
  put(out.direction, g, direction);
  put<W>(out.valid, g, valid);

  // EmitterSampler::weigh: the solid-angle density by the view's value, or by area probability /
  // area * r^2 / cos(theta'); zero where the triangle's back faces the point.
  const Vec3Of<W> normal = fetch(in.normal);
  put(out.normal, g, normal);
  const W cos_emitter = -dot(normal, direction);
  const Mask front = cos_emitter > zero;
  const W by_area =
      any(~by_solid_angle) ? (fetch(in.area) * cos_emitter) / ((fetch(in.probability) * distance) * distance) : zero;
  const Vec3Of<W> solid = fetch(in.solid_radiance);
  const auto radiance = [&](const W& solid_radiance, double emission) {
    return lm::select(front, lm::select(by_solid_angle, solid_radiance, splat<W>(emission) * by_area), zero);
  };
  put(out.radiance_over_pdf, g,
      Vec3Of<W>{radiance(solid.x, in.emission[0]), radiance(solid.y, in.emission[1]), radiance(solid.z, in.emission[2])});
  put<W>(out.front, g, front);
}

// EmitterSampler::choose over lanes, with choose_many's operations: the index counts the cdf's
// upper ends at or below uy, clamped to the last slot; v = (uy - low) / (high - low), clamped.
template <class G>
[[gnu::always_inline]] static inline void choose_group(Input& in, int g, std::uint32_t* triangle) {
  constexpr int kWidth = Wide<1, G>::kGroupLanes;
  const auto splat = [](double x) { return lm::Splat<G>::value(x); };
  const G zero{}, one = splat(1.0), last = splat(double(in.slots - 1));
  G ux, uy;
  lm::load(ux, in.ux.v + g);
  lm::load(uy, in.uy.v + g);
  G index{};
  for (int s = 0; s < in.slots; ++s) index = index + lm::select(uy < splat(in.high.v[s]), zero, one);
  const G slot = lm::select(last < index, last, index);
  const auto lookup = lm::make_lookup(slot);
  const G low = lm::lookup(in.low.v, lookup), high = lm::lookup(in.high.v, lookup);
  lm::store(in.slot.v + g, slot);
  lm::store(in.v.v + g, lm::clamp((uy - low) / (high - low), zero, splat(1.0 - 0x1p-53)));
  lm::store(in.angle.v + g, ux * lm::lookup(in.solid_area.v, lookup) - lm::lookup(in.alpha.v, lookup));
  lm::store(in.b1.v + g, zero);
  lm::store(in.b2.v + g, zero);
  lm::store(in.by_solid_angle + g, zero == zero);
  alignas(64) double slots[kWidth];
  lm::store(slots, slot);
  for (int l = 0; l < kWidth; ++l) triangle[g + l] = static_cast<std::uint32_t>(slots[l]);
}

void choose(Input& in, int count, std::uint32_t* triangle) {
  lm::for_each_group(count, [&](auto group, int g) { choose_group<decltype(group)>(in, g, triangle); });
}

// The lanes in use, as many groups at a time as the build's registers hold: 16 lanes in two zmm
// registers (AVX-512), in four ymm (AVX2) or in four pairs of xmm (SSE2: eight lanes, more would
// spill); then what is left by smaller steps, the last group of four in full (Input's lanes past
// `count` are read but their results are not).
template <template <class> class Fetch>
static void sample_by(const Input& in, int count, Output& out) {
  int g = 0;
#if defined(RT_LIGHT_SAMPLE_LANES_AVX512)
  for (; g + 16 <= count; g += 16) sample_groups<Wide<2, lm::D8>, Fetch>(in, g, out);
  for (; g + 8 <= count; g += 8) sample_groups<Wide<1, lm::D8>, Fetch>(in, g, out);
#elif defined(RT_LIGHT_SAMPLE_LANES_AVX2)
  for (; g + 16 <= count; g += 16) sample_groups<Wide<4>, Fetch>(in, g, out);
#else
  for (; g + 8 <= count; g += 8) sample_groups<Wide<2>, Fetch>(in, g, out);
#endif
  for (; g < count; g += 4) sample_groups<Wide<1>, Fetch>(in, g, out);
}

void sample(const Input& in, int count, Output& out) {
  if (in.slots == 0)
    sample_by<PerLane>(in, count, out);
  else
    sample_by<BySlot>(in, count, out);
}

// pow(x[k], y) for the 16 lanes: by binary powering where y is a whole number up to
// lm::kMaxIntegerPower, else by lm::pow_many; two groups of eight at a time with AVX-512, four of
// four with AVX2 (one register each), two of four with SSE2 (two registers each; four would
// spill), to overlap the chains.
void powers(const double* x, double y, double* out) {
  static_assert(kLanes == 16);
  const bool whole = y >= 0.0 && y <= lm::kMaxIntegerPower && y == std::floor(y);
#if defined(RT_LIGHT_SAMPLE_LANES_AVX512)
  if (whole)
    lm::pow_integer_many<2, lm::D8>(x, y, out);
  else
    lm::pow_many<2, lm::D8>(x, y, out);
#elif defined(RT_LIGHT_SAMPLE_LANES_AVX2)
  if (whole)
    lm::pow_integer_many<4>(x, y, out);
  else
    lm::pow_many<4>(x, y, out);
#else
  for (int half = 0; half < 2; ++half) {
    if (whole)
      lm::pow_integer_many<2>(x + 8 * half, y, out + 8 * half);
    else
      lm::pow_many<2>(x + 8 * half, y, out + 8 * half);
  }
#endif
}

// SphericalTriangle::SphericalTriangle's arithmetic, one triangle per lane; its three interior
// angles by the lanes' atan2 (the scalar constructor takes this path as well).
void spherical(const SphericalInput& in, SphericalOutput& out) {
  using lm::Xyz;
  const D4 zero{};
  const auto length = [](const Xyz& v) { return lm::sqrt(lm::dot(v, v)); };
  const auto divide = [](const Xyz& v, const D4& s) { return Xyz{v.x / s, v.y / s, v.z / s}; };
  const auto negate = [](const Xyz& v) { return Xyz{-v.x, -v.y, -v.z}; };
  Xyz point, a, b, c;
  lm::load(point, in.point, 0);
  lm::load(a, in.a, 0);
  lm::load(b, in.b, 0);
  lm::load(c, in.c, 0);
  // Unit directions from the point to the vertices.
  const Xyz da{a.x - point.x, a.y - point.y, a.z - point.z}, db{b.x - point.x, b.y - point.y, b.z - point.z},
      dc{c.x - point.x, c.y - point.y, c.z - point.z};
  const D4 la = length(da), lb = length(db), lc = length(dc);
  const Xyz A = divide(da, la), B = divide(db, lb), C = divide(dc, lc);
  // The great circles' unit normals; the interior angles between them (angle_between's atan2 of
  // |u x v| and u . v, v negated: (-n) / l has the bits of -(n / l)).
  const Xyz n_ab = lm::cross(A, B), n_bc = lm::cross(B, C), n_ca = lm::cross(C, A);
  const D4 l_ab = length(n_ab), l_bc = length(n_bc), l_ca = length(n_ca);
  const Xyz u_ab = divide(n_ab, l_ab), u_bc = divide(n_bc, l_bc), u_ca = divide(n_ca, l_ca);
  const Xyz pairs[3][2] = {{u_ab, negate(u_ca)}, {u_bc, negate(u_ab)}, {u_ca, negate(u_bc)}};
  Wide<3> sines, cosines;
  for (int i = 0; i < 3; ++i) {
    sines.g[i] = length(lm::cross(pairs[i][0], pairs[i][1]));
    cosines.g[i] = lm::dot(pairs[i][0], pairs[i][1]);
  }
  WideMask<3> outside;
  Wide<3> angles = lm::atan2_nonnegative(sines, cosines, outside);
  for (int i = 0; i < 3; ++i)
    if (lm::any(outside.g[i])) angles.g[i] = lm::atan2(sines.g[i], cosines.g[i]);
  const D4 alpha = angles.g[0];
  const D4 area = ((alpha + angles.g[1]) + angles.g[2]) - lm::broadcast(std::numbers::pi);
  const lm::M4 valid = (la > zero) & (lb > zero) & (lc > zero) & (l_ab > zero) & (l_bc > zero) & (l_ca > zero) &
                       (area > zero);
  // orthogonal_unit(C, A) = normalize(C - (C . A) A).
  const D4 c_dot_a = lm::dot(C, A);
  const Xyz c_perp = lm::normalize(Xyz{C.x - c_dot_a * A.x, C.y - c_dot_a * A.y, C.z - c_dot_a * A.z});
  D4 sin_alpha, cos_alpha;
  lm::sincos(alpha, sin_alpha, cos_alpha);
  const auto kept = [&](const D4& v) { return lm::select(valid, v, zero); };
  const auto kept3 = [&](const Xyz& v) { return Xyz{kept(v.x), kept(v.y), kept(v.z)}; };
  lm::store(out.a, 0, kept3(A));
  lm::store(out.b, 0, kept3(B));
  lm::store(out.c_perp, 0, kept3(c_perp));
  lm::store(out.alpha.v, kept(alpha));
  lm::store(out.cos_alpha.v, kept(cos_alpha));
  lm::store(out.sin_alpha.v, kept(sin_alpha));
  lm::store(out.cos_c.v, kept(lm::dot(A, B)));
  lm::store(out.area.v, kept(area));
}

// The groups of four lanes a chunk uses.
static int groups_in_use(const Chunk& chunk) { return (chunk.count + 3) / 4 * 4; }

// Lanes g .. g + G's lanes - 1 of a field, as one group G (D4 or D8).
template <class G>
[[gnu::always_inline]] static inline G group_at(const Lanes& v, int g) {
  G r;
  lm::load(r, v.v + g);
  return r;
}
template <class G>
[[gnu::always_inline]] static inline Vec3Of<G> group_at(const Vec3& v, int g) {
  return {group_at<G>(v.x, g), group_at<G>(v.y, g), group_at<G>(v.z, g)};
}
template <class G>
[[gnu::always_inline]] static inline Vec3Of<G> splat3(const double (&v)[3]) {
  return {lm::Splat<G>::value(v[0]), lm::Splat<G>::value(v[1]), lm::Splat<G>::value(v[2])};
}

// n.l and the highlight's cosine max(n.h, 0) of lanes g .. g + G's lanes - 1.
template <class G>
[[gnu::always_inline]] static inline void facing_group(const Shading& shading, const Chunk& chunk, int g,
                                                       FacingOutput& out, double* n_dot_h) {
  const G zero{}, one = lm::Splat<G>::value(1.0);
  const Vec3Of<G> normal = splat3<G>(shading.normal), to_eye = splat3<G>(shading.to_eye);
  const Vec3Of<G> direction = group_at<G>(chunk.out.direction, g);
  const G n_dot_l = dot(normal, direction);
  lm::store(out.n_dot_l.v + g, n_dot_l);
  const Vec3Of<G> half_sum{direction.x + to_eye.x, direction.y + to_eye.y, direction.z + to_eye.z};
  const G half_length = lm::sqrt(dot(half_sum, half_sum));
  const G cosine = lm::select(half_length > zero, lm::max(dot(normal, half_sum) / half_length, zero), zero);
  lm::MaskOf<G> valid;
  lm::load(valid, chunk.out.valid + g);
  lm::store(n_dot_h + g, lm::select(valid & (n_dot_l > zero), cosine, one));
}

void facing(const Shading& shading, const Chunk& chunk, FacingOutput& out) {
  alignas(64) double n_dot_h[kLanes];
  const int used = groups_in_use(chunk);
  lm::for_each_group(used, [&](auto group, int g) { facing_group<decltype(group)>(shading, chunk, g, out, n_dot_h); });
  for (int g = used; g < kLanes; ++g) n_dot_h[g] = 1.0;
  if (shading.highlights)
    powers(n_dot_h, shading.shininess, out.power.v);
  else
    for (double& p : out.power.v) p = 1.0;
}

void set_origins(Shading& shading) {
  // One lane per axis (the fourth unused): offset_ray_origin along n, then along -n.
  const D4 p = lm::set(shading.point[0], shading.point[1], shading.point[2], 0.0);
  const D4 n = lm::set(shading.geometric_normal[0], shading.geometric_normal[1], shading.geometric_normal[2], 0.0);
  for (int side = 0; side < 2; ++side) {
    const D4 away = side == 0 ? n : -n;
    const lm::F4 origin = shading.fixed_offset ? lm::to_float(p + lm::broadcast(shading.epsilon) * away)
                                               : lm::round_away(p + lm::broadcast(shading.error_bound) * away, away);
    alignas(16) float lanes[4];
    _mm_store_ps(lanes, origin);
    for (int axis = 0; axis < 3; ++axis) shading.origin[side][axis] = lanes[axis];
  }
}

// The term, then shadow_ray_to_sample: the origin on the side the direction leaves by, the target
// offset off the emitter towards it (offset_ray_origin), the float32 direction between them and
// the shortened tfar, each with the scalar code's operations; lanes g .. g + G's lanes - 1.
template <class G>
[[gnu::always_inline]] static inline void emit_group(const Shading& shading, const Chunk& chunk,
                                                     const FacingOutput& facing, bool lit, int g, EmitOutput& out) {
  using ray_offset_detail::kScaledRoundoff;
  using V = Vec3Of<G>;
  const auto splat = [](double x) { return lm::Splat<G>::value(x); };
  const G zero{}, one = splat(1.0);
  const V diffuse = splat3<G>(shading.diffuse), specular = splat3<G>(shading.specular),
          normal = splat3<G>(shading.geometric_normal);
  const V direction = group_at<G>(chunk.out.direction, g), radiance = group_at<G>(chunk.out.radiance_over_pdf, g);
  const V light_point = group_at<G>(chunk.out.point, g), light_normal = group_at<G>(chunk.out.normal, g);
  const G n_dot_l = group_at<G>(facing.n_dot_l, g), power = group_at<G>(facing.power, g),
          error_bound = group_at<G>(chunk.out.error_bound, g);

  // term = radiance (C_d n.l + C_s power) / (pi N), or (0, 0, 0).
  const auto counted = (lit ? zero == zero : zero != zero) & (n_dot_l > zero);
  const G scale = splat(shading.scale);
  const auto term = [&](const G& r, const G& d, const G& sp) {
    const G highlight = shading.highlights ? sp * power : zero;
    return lm::select(counted, (r * (d * n_dot_l + highlight)) * scale, zero);
  };
  const V terms{term(radiance.x, diffuse.x, specular.x), term(radiance.y, diffuse.y, specular.y),
                term(radiance.z, diffuse.z, specular.z)};
  lm::store(out.term.x.v + g, terms.x);
  lm::store(out.term.y.v + g, terms.y);
  lm::store(out.term.z.v + g, terms.z);

  // The origin leaving on the side of the direction (SideOrigins::leaving_along), chosen as double:
  // float32 values, exactly.
  const auto leaves_front = dot(normal, direction) >= zero;
  const V o{lm::select(leaves_front, splat(shading.origin[0][0]), splat(shading.origin[1][0])),
            lm::select(leaves_front, splat(shading.origin[0][1]), splat(shading.origin[1][1])),
            lm::select(leaves_front, splat(shading.origin[0][2]), splat(shading.origin[1][2]))};
  // The target: offset_ray_origin(light point, origin - light point).
  const V back = minus(o, light_point);
  const G sign = lm::select(dot(light_normal, back) >= zero, one, -one);  // n or -n, exactly
  const G sx = sign * light_normal.x, sy = sign * light_normal.y, sz = sign * light_normal.z;
  V t;
  if (shading.fixed_offset) {
    const G epsilon = splat(shading.epsilon);
    t = {lm::to_double(lm::to_float(light_point.x + epsilon * sx)), lm::to_double(lm::to_float(light_point.y + epsilon * sy)),
         lm::to_double(lm::to_float(light_point.z + epsilon * sz))};
  } else {
    t = {lm::to_double(lm::round_away(light_point.x + error_bound * sx, sx)),
         lm::to_double(lm::round_away(light_point.y + error_bound * sy, sy)),
         lm::to_double(lm::round_away(light_point.z + error_bound * sz, sz))};
  }
  const V span = minus(t, o);
  const G length = lm::sqrt(dot(span, span));
  const auto apart = length > zero;
  const G tfar = shading.fixed_offset
                     ? length - splat(shading.epsilon)
                     : length - splat(kScaledRoundoff) * (splat(std::sqrt(3.0)) * lm::max(lm::max(lm::abs(t.x), lm::abs(t.y)), lm::abs(t.z)) +
                                                          splat(4.0) * length);
  lm::store(out.origin.x + g, lm::to_float(o.x));
  lm::store(out.origin.y + g, lm::to_float(o.y));
  lm::store(out.origin.z + g, lm::to_float(o.z));
  lm::store(out.direction.x + g, lm::to_float(lm::select(apart, span.x / length, direction.x)));
  lm::store(out.direction.y + g, lm::to_float(lm::select(apart, span.y / length, direction.y)));
  lm::store(out.direction.z + g, lm::to_float(lm::select(apart, span.z / length, direction.z)));
  lm::store(out.tfar + g, lm::to_float(lm::select(apart, tfar, zero)));
}

void emit(const Shading& shading, const Chunk& chunk, const FacingOutput& facing, bool lit, EmitOutput& out) {
  lm::for_each_group(groups_in_use(chunk),
                     [&](auto group, int g) { emit_group<decltype(group)>(shading, chunk, facing, lit, g, out); });
}

}  // namespace (baseline, avx2 or avx512)

#if defined(RT_LIGHT_SAMPLE_LANES_AVX512)
const Kernels* avx512_kernels() {
  static const Kernels kernels{&avx512::choose, &avx512::sample, &avx512::powers, &avx512::spherical,
                               &avx512::facing, &avx512::emit, &avx512::set_origins};
  return lane_math::cpu_runs_this_build() ? &kernels : nullptr;
}
#elif defined(RT_LIGHT_SAMPLE_LANES_AVX2)
const Kernels* avx2_kernels() {
  static const Kernels kernels{&avx2::choose, &avx2::sample, &avx2::powers, &avx2::spherical,
                               &avx2::facing, &avx2::emit, &avx2::set_origins};
  return lane_math::cpu_runs_this_build() ? &kernels : nullptr;
}
#else
const Kernels& baseline_kernels() {
  static const Kernels kernels{&baseline::choose, &baseline::sample, &baseline::powers, &baseline::spherical,
                               &baseline::facing, &baseline::emit, &baseline::set_origins};
  return kernels;
}

std::vector<const Kernels*> wider_kernels() {
  std::vector<const Kernels*> builds;
  for (const Kernels* build : {avx2_kernels(), avx512_kernels()})
    if (build) builds.push_back(build);
  return builds;
}

const Kernels& best_kernels() {
  static const Kernels& best = avx512_kernels() ? *avx512_kernels() : avx2_kernels() ? *avx2_kernels() : baseline_kernels();
  return best;
}
#endif

}  // namespace rt::light_sample_lanes
