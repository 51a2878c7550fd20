// Built twice: as itself (baseline x86-64) and included by batch_lanes_avx2.cpp with
// RT_BATCH_LANES_AVX2 and -mavx2. Only lane_math.h's always-inlined helpers and plain struct
// members are used here, so the AVX2 build emits no inline function that another file could link.

#include "batch_lanes.h"

#include <cmath>
#include <cstddef>

#include "lane_math.h"
#include "rt/render/ray_offset.h"

namespace rt::batch_lanes {

#ifdef RT_BATCH_LANES_AVX2
namespace avx2 {
#else
namespace baseline {
#endif

namespace lm = lane_math;
using lm::D4;
using lm::F4;
using lm::M4;
using lm::Xyz;
using ray_offset_detail::kScaledRoundoff;

// w0 v0 + w1 v1 + w2 v2, component by component, in that order (make_surface_point's and the
// shading normal's interpolation).
[[gnu::always_inline]] static inline Xyz interpolate(const D4& w0, const D4& w1, const D4& w2, const Xyz& v0,
                                                     const Xyz& v1, const Xyz& v2) {
  return {w0 * v0.x + w1 * v1.x + w2 * v2.x, w0 * v0.y + w1 * v1.y + w2 * v2.y,
          w0 * v0.z + w1 * v1.z + w2 * v2.z};
}

// offset_ray_origin for lanes g..g+3 along directions whose dot product with the geometric normal
// is `cosine`: off the surface along the normal, to the side the ray goes.
[[gnu::always_inline]] static inline void set_origins(const Lanes& block, int g, const D4& cosine,
                                                      const OriginPolicy& policy,
                                                      Vec3fLanes<kLanes>& origin) {
  const D4 sign = lm::select(cosine >= D4{}, lm::broadcast(1.0), lm::broadcast(-1.0));  // n or -n, exactly
  Xyz n, p;
  lm::load(n, block.geometric_normal, g);
  lm::load(p, block.point, g);
  const D4 sx = sign * n.x, sy = sign * n.y, sz = sign * n.z;
  if (policy.fixed) {
    const D4 epsilon = lm::broadcast(policy.epsilon);
    lm::store(origin.x + g, lm::to_float(p.x + epsilon * sx));
    lm::store(origin.y + g, lm::to_float(p.y + epsilon * sy));
    lm::store(origin.z + g, lm::to_float(p.z + epsilon * sz));
    return;
  }
  D4 bound;
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
// two-sided back face), the unit direction and the reflection ray, for block.count lanes.
void surfaces(const Gathered& in, const OriginPolicy& policy, Lanes& block) {
  const D4 zero{}, one = lm::broadcast(1.0);
  for (int g = 0; g < block.count; g += 4) {
    D4 b1, b2;
    lm::load(b1, in.b1.v + g);
    lm::load(b2, in.b2.v + g);
    const D4 w0 = one - b1 - b2;
    Xyz p0, p1, p2;
    lm::load(p0, in.p0, g);
    lm::load(p1, in.p1, g);
    lm::load(p2, in.p2, g);
    const auto [px, py, pz] = interpolate(w0, b1, b2, p0, p1, p2);
    lm::store(block.point, g, Xyz{px, py, pz});
    const D4 e1x = p1.x - p0.x, e1y = p1.y - p0.y, e1z = p1.z - p0.z;
    const D4 e2x = p2.x - p0.x, e2y = p2.y - p0.y, e2z = p2.z - p0.z;
    const D4 e3x = p2.x - p1.x, e3y = p2.y - p1.y, e3z = p2.z - p1.z;
    const D4 cx = e1y * e2z - e2y * e1z, cy = e1z * e2x - e2z * e1x, cz = e1x * e2y - e2x * e1y;
    const D4 area2 = lm::sqrt(cx * cx + cy * cy + cz * cz);
    const M4 has_area = area2 > zero;
    const D4 gx = lm::select(has_area, cx / area2, zero), gy = lm::select(has_area, cy / area2, zero),
             gz = lm::select(has_area, cz / area2, zero);
    lm::store(block.geometric_normal, g, Xyz{gx, gy, gz});
    const D4 l1 = lm::sqrt(e1x * e1x + e1y * e1y + e1z * e1z);
    const D4 l2 = lm::sqrt(e2x * e2x + e2y * e2y + e2z * e2z);
    const D4 l3 = lm::sqrt(e3x * e3x + e3y * e3y + e3z * e3z);
    const D4 kappa = lm::select(has_area, l1 * l2 / area2, one);
    const D4 longest = lm::max(lm::max(l1, l2), l3);
    const D4 largest = lm::max(lm::max(lm::abs(px), lm::abs(py)), lm::abs(pz));
    lm::store(block.error_bound.v + g,
              lm::broadcast(kScaledRoundoff) * (lm::broadcast(std::sqrt(3.0)) * largest +
                                                (lm::broadcast(4.0) + lm::broadcast(2.0) * kappa) * longest));

    Xyz n0, n1, n2, d;
    lm::load(n0, in.n0, g);
    lm::load(n1, in.n1, g);
    lm::load(n2, in.n2, g);
    lm::load(d, in.d, g);
    const auto [nx, ny, nz] = interpolate(w0, b1, b2, n0, n1, n2);
    // shading_normal: normalised, or the geometric normal where the vertex normals cancel to zero.
    const D4 n_length2 = nx * nx + ny * ny + nz * nz;
    const M4 has_normal = n_length2 > zero;
    const D4 n_scale = one / lm::sqrt(n_length2);
    const D4 d_scale = one / lm::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    const D4 ux = d.x * d_scale, uy = d.y * d_scale, uz = d.z * d_scale;
    lm::store(block.direction, g, Xyz{ux, uy, uz});
    // A two-sided surface seen from behind: dot(geometric normal, to_eye) < 0, to_eye = -direction.
    const D4 facing = gx * -ux + gy * -uy + gz * -uz;
    M4 flip;
    lm::load(flip, in.flip + g);
    const D4 sign = lm::select(flip & (facing < zero), lm::broadcast(-1.0), one);  // -x is x * -1 exactly
    const D4 sx = sign * lm::select(has_normal, nx * n_scale, gx), sy = sign * lm::select(has_normal, ny * n_scale, gy),
             sz = sign * lm::select(has_normal, nz * n_scale, gz);
    lm::store(block.normal, g, Xyz{sx, sy, sz});

    if (!block.reflections) continue;
    // The reflection ray: reflect_direction and offset_ray_origin.
    const D4 twice = lm::broadcast(2.0) * (ux * sx + uy * sy + uz * sz);
    const D4 rx = ux - twice * sx, ry = uy - twice * sy, rz = uz - twice * sz;
    lm::store(block.reflected, g, Xyz{rx, ry, rz});
    set_origins(block, g, gx * rx + gy * ry + gz * rz, policy, block.reflection_origin);
  }
}

// One light's direction, unshadowed intensity, n.l, n.h, geometric cosine and shadow ray at
// block.count lanes (shade_surface's, before the pow of the highlight).
void light(const LightLanes& light, const OriginPolicy& policy, const Lanes& block, Lanes::Light& out,
           Vec3Lanes<kLanes>& intensity, LaneArray<kLanes>& n_dot_l, LaneArray<kLanes>& n_dot_h) {
  const D4 zero{};
  for (int g = 0; g < block.count; g += 4) {
    D4 lx = lm::broadcast(light.to_light[0]), ly = lm::broadcast(light.to_light[1]),
       lz = lm::broadcast(light.to_light[2]);
    D4 ir = lm::broadcast(light.color[0]), ig = lm::broadcast(light.color[1]),
       ib = lm::broadcast(light.color[2]);
    M4 on_point{};
    if (!light.directional) {
      Xyz p;
      lm::load(p, block.point, g);
      const D4 ox = lm::broadcast(light.position[0]) - p.x, oy = lm::broadcast(light.position[1]) - p.y,
               oz = lm::broadcast(light.position[2]) - p.z;
      const D4 distance = lm::sqrt(ox * ox + oy * oy + oz * oz);
      on_point = ~(distance > zero);
      lx = ox / distance, ly = oy / distance, lz = oz / distance;
      const D4 attenuation = lm::broadcast(light.attenuation[0]) +
                             lm::broadcast(light.attenuation[1]) * distance +
                             lm::broadcast(light.attenuation[2]) * distance * distance;
      ir /= attenuation, ig /= attenuation, ib /= attenuation;
      if (light.spot) {
        const D4 along = lm::broadcast(light.spot_direction[0]) * -lx +
                         lm::broadcast(light.spot_direction[1]) * -ly +
                         lm::broadcast(light.spot_direction[2]) * -lz;
        const D4 cone =
            lm::clamp((along - lm::broadcast(light.spot_cos_outer)) / lm::broadcast(light.cone_width), zero,
                      lm::broadcast(1.0));
        ir *= cone * cone, ig *= cone * cone, ib *= cone * cone;
      }
    }
    lm::store(out.on_point + g, on_point);
    lm::store(out.to_light, g, Xyz{lx, ly, lz});
    lm::store(intensity, g, Xyz{ir, ig, ib});
    Xyz n, d, gn;
    lm::load(n, block.normal, g);
    lm::load(d, block.direction, g);
    lm::load(gn, block.geometric_normal, g);
    lm::store(n_dot_l.v + g, lm::max(n.x * lx + n.y * ly + n.z * lz, zero));
    if (block.highlights) {  // else n_dot_h is never read
      const D4 hx = lx + -d.x, hy = ly + -d.y, hz = lz + -d.z;
      const D4 half_length = lm::sqrt(hx * hx + hy * hy + hz * hz);
      lm::store(n_dot_h.v + g,
                lm::select(half_length > zero, lm::max((n.x * hx + n.y * hy + n.z * hz) / half_length, zero),
                           zero));
    }
    const D4 cosine = gn.x * lx + gn.y * ly + gn.z * lz;
    lm::store(out.geometric_cosine.v + g, cosine);

    // The shadow ray: offset_ray_origin along to_light, shadow_ray_tfar from the float32 origin.
    set_origins(block, g, cosine, policy, out.shadow_origin);
    if (light.directional) {
      lm::store(out.shadow_distance.v + g, lm::broadcast(double(kInfinity)));
      continue;
    }
    F4 fx, fy, fz;
    lm::load(fx, out.shadow_origin.x + g);
    lm::load(fy, out.shadow_origin.y + g);
    lm::load(fz, out.shadow_origin.z + g);
    const D4 ox = lm::broadcast(light.position[0]) - lm::to_double(fx),
             oy = lm::broadcast(light.position[1]) - lm::to_double(fy),
             oz = lm::broadcast(light.position[2]) - lm::to_double(fz);
    const D4 distance = lm::sqrt(ox * ox + oy * oy + oz * oz);
    lm::store(out.shadow_distance.v + g,
              policy.fixed ? distance - lm::broadcast(policy.epsilon)
                           : distance - lm::broadcast(kScaledRoundoff) *
                                            (lm::broadcast(std::sqrt(3.0)) * lm::broadcast(light.extent) +
                                             lm::broadcast(4.0) * distance));
  }
}

// The light term at block.count lanes: intensity (ambient + diffuse n.l + specular pow(n.h, s)),
// the highlight Vec3d(0.0) where it is skipped.
void terms(const Lanes& block, const Vec3Lanes<kLanes>& intensity, const LaneArray<kLanes>& n_dot_l,
           const LaneArray<kLanes>& power, Lanes::Light& out) {
  const D4 zero{};
  for (int g = 0; g < block.count; g += 4) {
    M4 highlight;
    lm::load(highlight, block.highlight + g);
    D4 ndl, pw;
    lm::load(ndl, n_dot_l.v + g);
    lm::load(pw, power.v + g);
    Xyz in, ambient, diffuse, specular;
    lm::load(in, intensity, g);
    lm::load(ambient, block.ambient, g);
    lm::load(diffuse, block.diffuse, g);
    lm::load(specular, block.specular, g);
    const D4 hr = lm::select(highlight, specular.x * pw, zero),
             hg = lm::select(highlight, specular.y * pw, zero),
             hb = lm::select(highlight, specular.z * pw, zero);
    lm::store(out.term, g,
              Xyz{in.x * (ambient.x + diffuse.x * ndl + hr), in.y * (ambient.y + diffuse.y * ndl + hg),
                  in.z * (ambient.z + diffuse.z * ndl + hb)});
  }
}

}  // namespace (baseline or avx2)

#ifdef RT_BATCH_LANES_AVX2
const Kernels* avx2_kernels() {
  static const Kernels kernels{avx2::gather, avx2::surfaces, avx2::light, avx2::terms};
  __builtin_cpu_init();  // idempotent; needed when called before the constructors have run
  return __builtin_cpu_supports("avx2") ? &kernels : nullptr;
}
#else
const Kernels& baseline_kernels() {
  static const Kernels kernels{baseline::gather, baseline::surfaces, baseline::light, baseline::terms};
  return kernels;
}

const Kernels& best_kernels() {
  static const Kernels& best = avx2_kernels() ? *avx2_kernels() : baseline_kernels();
  return best;
}
#endif

}  // namespace rt::batch_lanes
