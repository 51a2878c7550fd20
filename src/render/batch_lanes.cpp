// Built three times: as itself (baseline x86-64), included by batch_lanes_avx2.cpp with
// RT_BATCH_LANES_AVX2 and -mavx2, and by batch_lanes_avx512.cpp with RT_BATCH_LANES_AVX512 and
// -mavx512f -mavx512dq -mavx512vl. Only lane_math.h's always-inlined helpers and plain struct
// members are used here, so the wider builds emit no inline function that another file could link.

#include "batch_lanes.h"

#include <cmath>
#include <cstddef>
#include <vector>

#include "lane_math.h"
#include "rt/render/ray_offset.h"

namespace rt::batch_lanes {

#if defined(RT_BATCH_LANES_AVX512)
namespace avx512 {
#elif defined(RT_BATCH_LANES_AVX2)
namespace avx2 {
#else
namespace baseline {
#endif

namespace lm = lane_math;
using lm::D4;
using lm::F4;
using ray_offset_detail::kScaledRoundoff;
// surfaces, light and terms are written for a group G of lanes: D4, or D8 in the AVX-512 build.
template <class G>
using V3 = lm::Vec3Of<G>;
template <class G>
[[gnu::always_inline]] static inline G splat(double x) {
  return lm::Splat<G>::value(x);
}

// w0 v0 + w1 v1 + w2 v2, component by component, in that order (make_surface_point's and the
// shading normal's interpolation).
template <class G>
[[gnu::always_inline]] static inline V3<G> interpolate(const G& w0, const G& w1, const G& w2, const V3<G>& v0,
                                                       const V3<G>& v1, const V3<G>& v2) {
  return {w0 * v0.x + w1 * v1.x + w2 * v2.x, w0 * v0.y + w1 * v1.y + w2 * v2.y,
          w0 * v0.z + w1 * v1.z + w2 * v2.z};
}

// offset_ray_origin for lanes g .. g + G's lanes - 1 along directions whose dot product with the
// geometric normal is `cosine`: off the surface along the normal, to the side the ray goes.
template <class G>
[[gnu::always_inline]] static inline void set_origins(const Lanes& block, int g, const G& cosine,
                                                      const OriginPolicy& policy,
                                                      Vec3fLanes<kLanes>& origin) {
  const G sign = lm::select(cosine >= G{}, splat<G>(1.0), splat<G>(-1.0));  // n or -n, exactly
  V3<G> n, p;
  lm::load(n, block.geometric_normal, g);
  lm::load(p, block.point, g);
  const G sx = sign * n.x, sy = sign * n.y, sz = sign * n.z;
  if (policy.fixed) {
    const G epsilon = splat<G>(policy.epsilon);
    lm::store(origin.x + g, lm::to_float(p.x + epsilon * sx));
    lm::store(origin.y + g, lm::to_float(p.y + epsilon * sy));
    lm::store(origin.z + g, lm::to_float(p.z + epsilon * sz));
    return;
  }
  G bound;
  lm::load(bound, block.error_bound.v + g);
  lm::store(origin.x + g, lm::round_away(p.x + bound * sx, sx));
  lm::store(origin.y + g, lm::round_away(p.y + bound * sy, sy));
  lm::store(origin.z + g, lm::round_away(p.z + bound * sz, sz));
}

// The three floats at p (the fourth lane unspecified): one 16-byte load where a float of the
// same array follows them, else three.
[[gnu::always_inline]] static inline F4 load3(const Vec3f* array, std::uint32_t index, std::size_t count) {
  const float* p = &array[index].x;
  return index + 1 < count ? _mm_loadu_ps(p) : _mm_setr_ps(p[0], p[1], p[2], 0.0f);
}

// Rows r[0..3] (lanes' x, y, z, -) transposed into axes, widened and stored at lanes g..g+3.
[[gnu::always_inline]] static inline void put_transposed(F4 (&r)[4], int g, Vec3Lanes<kLanes>& to) {
  _MM_TRANSPOSE4_PS(r[0], r[1], r[2], r[3]);
  lm::store(to.x.v + g, lm::to_double(r[0]));
  lm::store(to.y.v + g, lm::to_double(r[1]));
  lm::store(to.z.v + g, lm::to_double(r[2]));
}

void gather(const VertexArrays& vertices, const Vec3u* triangles, const Ray* rays, const Hit* hits, int count,
            Gathered& in) {
  for (int g = 0; g < count; g += 4) {
    int lane[4];
    for (int l = 0; l < 4; ++l) lane[l] = g + l < count ? g + l : 0;
    for (int corner = 0; corner < 3; ++corner) {
      F4 p[4], n[4];
      for (int l = 0; l < 4; ++l) {
        const std::uint32_t v = triangles[lane[l]][corner];
        p[l] = load3(vertices.positions, v, vertices.count);
        n[l] = load3(vertices.normals, v, vertices.count);
      }
      put_transposed(p, g, corner == 0 ? in.p0 : corner == 1 ? in.p1 : in.p2);
      put_transposed(n, g, corner == 0 ? in.n0 : corner == 1 ? in.n1 : in.n2);
    }
    F4 d[4], h[4];
    for (int l = 0; l < 4; ++l) {
      static_assert(sizeof(Ray) >= offsetof(Ray, direction) + 16 && sizeof(Hit) == 16);
      d[l] = _mm_loadu_ps(&rays[lane[l]].direction.x);  // direction, then tnear
      h[l] = _mm_loadu_ps(&hits[lane[l]].t);            // t, u, v, primitive
    }
    put_transposed(d, g, in.d);
    _MM_TRANSPOSE4_PS(h[0], h[1], h[2], h[3]);
    lm::store(in.b1.v + g, lm::to_double(h[1]));
    lm::store(in.b2.v + g, lm::to_double(h[2]));
  }
}

// make_surface_point, the shading normal (interpolated, unit, flipped towards the viewer on a
// two-sided back face), the unit direction and the reflection ray, for lanes g .. g + G's lanes - 1.
template <class G>
[[gnu::always_inline]] static inline void surfaces_group(const Gathered& in, const OriginPolicy& policy, int g,
                                                         Lanes& block) {
  using M = lm::MaskOf<G>;
  const G zero{}, one = splat<G>(1.0);
  G b1, b2;
  lm::load(b1, in.b1.v + g);
  lm::load(b2, in.b2.v + g);
  const G w0 = one - b1 - b2;
  V3<G> p0, p1, p2;
  lm::load(p0, in.p0, g);
  lm::load(p1, in.p1, g);
  lm::load(p2, in.p2, g);
  const auto [px, py, pz] = interpolate(w0, b1, b2, p0, p1, p2);
  lm::store(block.point, g, V3<G>{px, py, pz});
  const G e1x = p1.x - p0.x, e1y = p1.y - p0.y, e1z = p1.z - p0.z;
  const G e2x = p2.x - p0.x, e2y = p2.y - p0.y, e2z = p2.z - p0.z;
  const G e3x = p2.x - p1.x, e3y = p2.y - p1.y, e3z = p2.z - p1.z;
  const G cx = e1y * e2z - e2y * e1z, cy = e1z * e2x - e2z * e1x, cz = e1x * e2y - e2x * e1y;
  const G area2 = lm::sqrt(cx * cx + cy * cy + cz * cz);
  const M has_area = area2 > zero;
  const G gx = lm::select(has_area, cx / area2, zero), gy = lm::select(has_area, cy / area2, zero),
          gz = lm::select(has_area, cz / area2, zero);
  lm::store(block.geometric_normal, g, V3<G>{gx, gy, gz});
  const G l1 = lm::sqrt(e1x * e1x + e1y * e1y + e1z * e1z);
  const G l2 = lm::sqrt(e2x * e2x + e2y * e2y + e2z * e2z);
  const G l3 = lm::sqrt(e3x * e3x + e3y * e3y + e3z * e3z);
  const G kappa = lm::select(has_area, l1 * l2 / area2, one);
  const G longest = lm::max(lm::max(l1, l2), l3);
  const G largest = lm::max(lm::max(lm::abs(px), lm::abs(py)), lm::abs(pz));
  lm::store(block.error_bound.v + g,
            splat<G>(kScaledRoundoff) *
                (splat<G>(std::sqrt(3.0)) * largest + (splat<G>(4.0) + splat<G>(2.0) * kappa) * longest));

  V3<G> n0, n1, n2, d;
  lm::load(n0, in.n0, g);
  lm::load(n1, in.n1, g);
  lm::load(n2, in.n2, g);
  lm::load(d, in.d, g);
  const auto [nx, ny, nz] = interpolate(w0, b1, b2, n0, n1, n2);
  // shading_normal: normalised, or the geometric normal where the vertex normals cancel to zero.
  const G n_length2 = nx * nx + ny * ny + nz * nz;
  const M has_normal = n_length2 > zero;
  const G n_scale = one / lm::sqrt(n_length2);
  const G d_scale = one / lm::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  const G ux = d.x * d_scale, uy = d.y * d_scale, uz = d.z * d_scale;
  lm::store(block.direction, g, V3<G>{ux, uy, uz});
  // A two-sided surface seen from behind: dot(geometric normal, to_eye) < 0, to_eye = -direction.
  const G facing = gx * -ux + gy * -uy + gz * -uz;
  M flip;
  lm::load(flip, in.flip + g);
  const G sign = lm::select(flip & (facing < zero), splat<G>(-1.0), one);  // -x is x * -1 exactly
  const G sx = sign * lm::select(has_normal, nx * n_scale, gx), sy = sign * lm::select(has_normal, ny * n_scale, gy),
          sz = sign * lm::select(has_normal, nz * n_scale, gz);
  lm::store(block.normal, g, V3<G>{sx, sy, sz});

  if (!block.reflections) return;
  // The reflection ray: reflect_direction and offset_ray_origin.
  const G twice = splat<G>(2.0) * (ux * sx + uy * sy + uz * sz);
  const G rx = ux - twice * sx, ry = uy - twice * sy, rz = uz - twice * sz;
  lm::store(block.reflected, g, V3<G>{rx, ry, rz});
  set_origins(block, g, gx * rx + gy * ry + gz * rz, policy, block.reflection_origin);
}

// One light's direction, unshadowed intensity, n.l, n.h, geometric cosine and shadow ray at
// lanes g .. g + G's lanes - 1 (shade_surface's, before the pow of the highlight).
template <class G>
[[gnu::always_inline]] static inline void light_group(const LightLanes& light, const OriginPolicy& policy,
                                                      const Lanes& block, int g, Lanes::Light& out,
                                                      Vec3Lanes<kLanes>& intensity, LaneArray<kLanes>& n_dot_l,
                                                      LaneArray<kLanes>& n_dot_h) {
  using M = lm::MaskOf<G>;
  const G zero{};
  G lx = splat<G>(light.to_light[0]), ly = splat<G>(light.to_light[1]), lz = splat<G>(light.to_light[2]);
  G ir = splat<G>(light.color[0]), ig = splat<G>(light.color[1]), ib = splat<G>(light.color[2]);
  M on_point{};
  if (!light.directional) {
    V3<G> p;
    lm::load(p, block.point, g);
    const G ox = splat<G>(light.position[0]) - p.x, oy = splat<G>(light.position[1]) - p.y,
            oz = splat<G>(light.position[2]) - p.z;
    const G distance = lm::sqrt(ox * ox + oy * oy + oz * oz);
    on_point = ~(distance > zero);
    lx = ox / distance, ly = oy / distance, lz = oz / distance;
    const G attenuation = splat<G>(light.attenuation[0]) + splat<G>(light.attenuation[1]) * distance +
                          splat<G>(light.attenuation[2]) * distance * distance;
    ir /= attenuation, ig /= attenuation, ib /= attenuation;
    if (light.spot) {
      const G along = splat<G>(light.spot_direction[0]) * -lx + splat<G>(light.spot_direction[1]) * -ly +
                      splat<G>(light.spot_direction[2]) * -lz;
      const G cone =
          lm::clamp((along - splat<G>(light.spot_cos_outer)) / splat<G>(light.cone_width), zero, splat<G>(1.0));
      ir *= cone * cone, ig *= cone * cone, ib *= cone * cone;
    }
  }
  lm::store(out.on_point + g, on_point);
  lm::store(out.to_light, g, V3<G>{lx, ly, lz});
  lm::store(intensity, g, V3<G>{ir, ig, ib});
  V3<G> n, d, gn;
  lm::load(n, block.normal, g);
  lm::load(d, block.direction, g);
  lm::load(gn, block.geometric_normal, g);
  lm::store(n_dot_l.v + g, lm::max(n.x * lx + n.y * ly + n.z * lz, zero));
  if (block.highlights) {  // else n_dot_h is never read
    const G hx = lx + -d.x, hy = ly + -d.y, hz = lz + -d.z;
    const G half_length = lm::sqrt(hx * hx + hy * hy + hz * hz);
    lm::store(n_dot_h.v + g,
              lm::select(half_length > zero, lm::max((n.x * hx + n.y * hy + n.z * hz) / half_length, zero),
                         zero));
  }
  const G cosine = gn.x * lx + gn.y * ly + gn.z * lz;
  lm::store(out.geometric_cosine.v + g, cosine);

  // The shadow ray: offset_ray_origin along to_light, shadow_ray_tfar from the float32 origin.
  set_origins(block, g, cosine, policy, out.shadow_origin);
  if (light.directional) {
    lm::store(out.shadow_distance.v + g, splat<G>(double(kInfinity)));
    return;
  }
  decltype(lm::to_float(G{})) fx, fy, fz;
  lm::load(fx, out.shadow_origin.x + g);
  lm::load(fy, out.shadow_origin.y + g);
  lm::load(fz, out.shadow_origin.z + g);
  const G ox = splat<G>(light.position[0]) - lm::to_double(fx),
          oy = splat<G>(light.position[1]) - lm::to_double(fy),
          oz = splat<G>(light.position[2]) - lm::to_double(fz);
  const G distance = lm::sqrt(ox * ox + oy * oy + oz * oz);
  lm::store(out.shadow_distance.v + g,
            policy.fixed ? distance - splat<G>(policy.epsilon)
                         : distance - splat<G>(kScaledRoundoff) *
                                          (splat<G>(std::sqrt(3.0)) * splat<G>(light.extent) +
                                           splat<G>(4.0) * distance));
}

// The light term at lanes g .. g + G's lanes - 1: intensity (ambient + diffuse n.l + specular
// pow(n.h, s)), the highlight Vec3d(0.0) where it is skipped.
template <class G>
[[gnu::always_inline]] static inline void terms_group(const Lanes& block, const Vec3Lanes<kLanes>& intensity,
                                                      const LaneArray<kLanes>& n_dot_l, const LaneArray<kLanes>& power,
                                                      int g, Lanes::Light& out) {
  using M = lm::MaskOf<G>;
  const G zero{};
  M highlight;
  lm::load(highlight, block.highlight + g);
  G ndl, pw;
  lm::load(ndl, n_dot_l.v + g);
  lm::load(pw, power.v + g);
  V3<G> in, ambient, diffuse, specular;
  lm::load(in, intensity, g);
  lm::load(ambient, block.ambient, g);
  lm::load(diffuse, block.diffuse, g);
  lm::load(specular, block.specular, g);
  const G hr = lm::select(highlight, specular.x * pw, zero),
          hg = lm::select(highlight, specular.y * pw, zero),
          hb = lm::select(highlight, specular.z * pw, zero);
  const V3<G> term{in.x * (ambient.x + diffuse.x * ndl + hr), in.y * (ambient.y + diffuse.y * ndl + hg),
                   in.z * (ambient.z + diffuse.z * ndl + hb)};
  lm::store(out.term, g, term);
  lm::store(out.zero_term + g, (term.x == zero) & (term.y == zero) & (term.z == zero));
}

void surfaces(const Gathered& in, const OriginPolicy& policy, Lanes& block) {
  lm::for_each_group(block.count, [&](auto group, int g) { surfaces_group<decltype(group)>(in, policy, g, block); });
}

void light(const LightLanes& light, const OriginPolicy& policy, const Lanes& block, Lanes::Light& out,
           Vec3Lanes<kLanes>& intensity, LaneArray<kLanes>& n_dot_l, LaneArray<kLanes>& n_dot_h) {
  lm::for_each_group(block.count, [&](auto group, int g) {
    light_group<decltype(group)>(light, policy, block, g, out, intensity, n_dot_l, n_dot_h);
  });
}

void terms(const Lanes& block, const Vec3Lanes<kLanes>& intensity, const LaneArray<kLanes>& n_dot_l,
           const LaneArray<kLanes>& power, Lanes::Light& out) {
  lm::for_each_group(block.count,
             [&](auto group, int g) { terms_group<decltype(group)>(block, intensity, n_dot_l, power, g, out); });
}

}  // namespace (baseline, avx2 or avx512)

#if defined(RT_BATCH_LANES_AVX512)
const Kernels* avx512_kernels() {
  static const Kernels kernels{avx512::gather, avx512::surfaces, avx512::light, avx512::terms};
  return lane_math::cpu_runs_this_build() ? &kernels : nullptr;
}
#elif defined(RT_BATCH_LANES_AVX2)
const Kernels* avx2_kernels() {
  static const Kernels kernels{avx2::gather, avx2::surfaces, avx2::light, avx2::terms};
  return lane_math::cpu_runs_this_build() ? &kernels : nullptr;
}
#else
const Kernels& baseline_kernels() {
  static const Kernels kernels{baseline::gather, baseline::surfaces, baseline::light, baseline::terms};
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

}  // namespace rt::batch_lanes
