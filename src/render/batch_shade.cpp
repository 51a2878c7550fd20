#include "batch_shade.h"

#include <algorithm>
#include <cmath>

#include "rt/render/dielectric.h"
#include "shading_margins.h"
#include "shadow_records.h"

// Every expression below mirrors shade_surface's (and glm's: dot(a, b) = (ax bx + ay by) + az bz,
// normalize(v) = v * (1 / sqrt(dot(v, v))), v / s divides each component) operation for
// operation. The loops over lanes may therefore be vectorised without changing a bit (SIMD
// division and square root are correctly rounded like the scalar ones), provided nothing is
// contracted into an FMA (this file is compiled with -ffp-contract=off) and pow stays the scalar
// libm call. GCC 12 does not vectorise them yet ("control flow in loop"; docs/performance.md).

namespace rt {

namespace {

using ray_offset_detail::kScaledRoundoff;

void count_at(std::vector<std::uint64_t>& counts, std::size_t index) {
  if (counts.size() <= index) counts.resize(index + 1, 0);
  ++counts[index];
}

double max_channel(const Vec3d& c) { return std::max({c.r, c.g, c.b}); }

template <class V>
Vec3d lane(const V& v, int i) {
  return Vec3d(v.x.v[i], v.y.v[i], v.z.v[i]);
}

}  // namespace

BatchShader::BatchShader(const ShadingContext& context)
    : context_(context), background_(context.scene.settings.background) {
  const Scene& scene = context.scene;
  const EffectsPlan& plan = context.plan;
  if (plan.area_lights || context.trace) return;
  materials_.resize(scene.materials.size());
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    const Material& material = scene.materials[m];
    const auto id = static_cast<std::uint32_t>(m);
    const bool textured = has_texcoords(context.flat) && context.textures && context.textures->has_diffuse(id);
    PlainMaterial& plain = materials_[m];
    plain.batched = !textured && !plan.materials[m].surface_maps && !material.is_dielectric() && !material.emits_light &&
                    !(material.alpha_mode == AlphaMode::blend && material.has_alpha());
    plain.flip_back_face = material.back_face == BackFace::flipped;
    plain.highlight = plan.materials[m].specular || !plan.options.prune;
    plain.reflects = plan.materials[m].reflection;
    plain.shininess = material.shininess;
    plain.ambient = Vec3d(material.ambient);
    plain.diffuse = Vec3d(material.diffuse);
    plain.specular = Vec3d(material.specular);
    plain.reflective = Vec3d(material.reflective.value_or(material.specular));
    plain.emission = Vec3d(material.emission);
    enabled_ = enabled_ || plain.batched;
  }
}

bool BatchShader::batchable(const Hit& hit) const {
  const FlatScene& flat = context_.flat;
  return hit.found() && !flat.is_sphere(hit.primitive) && materials_[flat.material_ids[hit.primitive]].batched;
}

void BatchShader::compute_lanes(Lanes& lanes, const std::array<Ray, kLanes>& rays,
                                const std::array<Hit, kLanes>& hits) const {
  if (lanes.count == 0) return;
  compute_surfaces(lanes, rays, hits);
  lanes.lights.resize(context_.scene.lights.size());
  for (std::size_t j = 0; j < context_.scene.lights.size(); ++j)
    if (context_.plan.lights[j].contributes) compute_light(lanes, j);
}

void BatchShader::prepare(std::span<const Ray> rays, std::span<const Hit> hits, std::span<const bool> unbatched,
                          Workspace& work) const {
  std::array<Ray, kLanes> lane_rays;
  std::array<Hit, kLanes> lane_hits;
  int count = 0;
  for (std::size_t k = 0; k < hits.size(); ++k) {
    const bool batched = !unbatched[k] && batchable(hits[k]);
    work.lane_of[k] = static_cast<std::int8_t>(batched ? count : -1);
    if (!batched) continue;
    lane_rays[std::size_t(count)] = rays[k];
    lane_hits[std::size_t(count)] = hits[k];
    ++count;
  }
  work.lanes.count = count;
  compute_lanes(work.lanes, lane_rays, lane_hits);
  if (work.waves.size() < 2) work.waves.resize(2);
  work.waves[1].clear();
}

void BatchShader::compute_surfaces(Lanes& block, const std::array<Ray, kLanes>& rays,
                                   const std::array<Hit, kLanes>& hits) const {
  const FlatScene& flat = context_.flat;
  const int lanes = block.count;
  // Gathered: the triangle's vertices and vertex normals, float32 widened to double.
  Vec3Lanes<kLanes> p0, p1, p2, n0, n1, n2, d;
  LaneArray<kLanes> b1, b2;
  std::array<bool, kLanes> flip{};
  // Indices first, then vertices: each loop's loads are independent, so their cache misses overlap.
  std::array<Vec3u, kLanes> triangles;
  for (int i = 0; i < lanes; ++i) triangles[std::size_t(i)] = flat.triangles[hits[std::size_t(i)].primitive];
  for (int i = 0; i < lanes; ++i) {
    const Hit& hit = hits[std::size_t(i)];
    const Vec3u tri = triangles[std::size_t(i)];
    const auto put = [i](Vec3Lanes<kLanes>& to, const Vec3f& from) {
      to.x.v[i] = from.x;
      to.y.v[i] = from.y;
      to.z.v[i] = from.z;
    };
    put(p0, flat.positions[tri.x]);
    put(p1, flat.positions[tri.y]);
    put(p2, flat.positions[tri.z]);
    put(n0, flat.normals[tri.x]);
    put(n1, flat.normals[tri.y]);
    put(n2, flat.normals[tri.z]);
    put(d, rays[std::size_t(i)].direction);
    b1.v[i] = hit.u;
    b2.v[i] = hit.v;
    const std::uint32_t material = flat.material_ids[hit.primitive];
    block.material[std::size_t(i)] = material;
    const PlainMaterial& plain = materials_[material];
    flip[std::size_t(i)] = plain.flip_back_face;
    block.ambient.x.v[i] = plain.ambient.x, block.ambient.y.v[i] = plain.ambient.y, block.ambient.z.v[i] = plain.ambient.z;
    block.diffuse.x.v[i] = plain.diffuse.x, block.diffuse.y.v[i] = plain.diffuse.y, block.diffuse.z.v[i] = plain.diffuse.z;
    block.specular.x.v[i] = plain.specular.x, block.specular.y.v[i] = plain.specular.y,
    block.specular.z.v[i] = plain.specular.z;
    block.shininess.v[i] = plain.shininess;
    block.highlight[std::size_t(i)] = plain.highlight;
  }

  // make_surface_point: the point, the geometric normal and the offset bound.
  for (int i = 0; i < lanes; ++i) {
    const double w1 = b1.v[i], w2 = b2.v[i], w0 = 1.0 - w1 - w2;
    block.point.x.v[i] = w0 * p0.x.v[i] + w1 * p1.x.v[i] + w2 * p2.x.v[i];
    block.point.y.v[i] = w0 * p0.y.v[i] + w1 * p1.y.v[i] + w2 * p2.y.v[i];
    block.point.z.v[i] = w0 * p0.z.v[i] + w1 * p1.z.v[i] + w2 * p2.z.v[i];
    const double e1x = p1.x.v[i] - p0.x.v[i], e1y = p1.y.v[i] - p0.y.v[i], e1z = p1.z.v[i] - p0.z.v[i];
    const double e2x = p2.x.v[i] - p0.x.v[i], e2y = p2.y.v[i] - p0.y.v[i], e2z = p2.z.v[i] - p0.z.v[i];
    const double e3x = p2.x.v[i] - p1.x.v[i], e3y = p2.y.v[i] - p1.y.v[i], e3z = p2.z.v[i] - p1.z.v[i];
    const double cx = e1y * e2z - e2y * e1z, cy = e1z * e2x - e2z * e1x, cz = e1x * e2y - e2x * e1y;
    const double area2 = std::sqrt(cx * cx + cy * cy + cz * cz);
    const bool has_area = area2 > 0.0;
    block.geometric_normal.x.v[i] = has_area ? cx / area2 : 0.0;
    block.geometric_normal.y.v[i] = has_area ? cy / area2 : 0.0;
    block.geometric_normal.z.v[i] = has_area ? cz / area2 : 0.0;
    const double l1 = std::sqrt(e1x * e1x + e1y * e1y + e1z * e1z);
    const double l2 = std::sqrt(e2x * e2x + e2y * e2y + e2z * e2z);
    const double l3 = std::sqrt(e3x * e3x + e3y * e3y + e3z * e3z);
    const double kappa = has_area ? l1 * l2 / area2 : 1.0;
    const double longest = std::max(std::max(l1, l2), l3);
    const double largest = std::max(std::max(std::abs(block.point.x.v[i]), std::abs(block.point.y.v[i])),
                                    std::abs(block.point.z.v[i]));
    block.error_bound.v[i] = kScaledRoundoff * (std::sqrt(3.0) * largest + (4.0 + 2.0 * kappa) * longest);
  }

  // The interpolated shading normal and the unit ray direction.
  for (int i = 0; i < lanes; ++i) {
    const double w1 = b1.v[i], w2 = b2.v[i], w0 = 1.0 - w1 - w2;
    const double nx = w0 * n0.x.v[i] + w1 * n1.x.v[i] + w2 * n2.x.v[i];
    const double ny = w0 * n0.y.v[i] + w1 * n1.y.v[i] + w2 * n2.y.v[i];
    const double nz = w0 * n0.z.v[i] + w1 * n1.z.v[i] + w2 * n2.z.v[i];
    const double n_scale = 1.0 / std::sqrt(nx * nx + ny * ny + nz * nz);
    const double dx = d.x.v[i], dy = d.y.v[i], dz = d.z.v[i];
    const double d_scale = 1.0 / std::sqrt(dx * dx + dy * dy + dz * dz);
    const double ux = dx * d_scale, uy = dy * d_scale, uz = dz * d_scale;
    block.direction.x.v[i] = ux;
    block.direction.y.v[i] = uy;
    block.direction.z.v[i] = uz;
    // A two-sided surface seen from behind: dot(geometric normal, to_eye) < 0, to_eye = -direction.
    const double facing = block.geometric_normal.x.v[i] * -ux + block.geometric_normal.y.v[i] * -uy +
                          block.geometric_normal.z.v[i] * -uz;
    const double sign = flip[std::size_t(i)] && facing < 0.0 ? -1.0 : 1.0;  // -x is x * -1 exactly
    block.normal.x.v[i] = sign * (nx * n_scale);
    block.normal.y.v[i] = sign * (ny * n_scale);
    block.normal.z.v[i] = sign * (nz * n_scale);
  }

  // The reflection ray: reflect_direction and offset_ray_origin.
  for (int i = 0; i < lanes; ++i) {
    const double dx = block.direction.x.v[i], dy = block.direction.y.v[i], dz = block.direction.z.v[i];
    const double nx = block.normal.x.v[i], ny = block.normal.y.v[i], nz = block.normal.z.v[i];
    const double twice = 2.0 * (dx * nx + dy * ny + dz * nz);
    const double rx = dx - twice * nx, ry = dy - twice * ny, rz = dz - twice * nz;
    block.reflected.x.v[i] = rx, block.reflected.y.v[i] = ry, block.reflected.z.v[i] = rz;
    const double cosine = block.geometric_normal.x.v[i] * rx + block.geometric_normal.y.v[i] * ry +
                          block.geometric_normal.z.v[i] * rz;
    set_origin(block, i, cosine, block.reflection_origin);
  }
}

void BatchShader::set_origin(const Lanes& block, int i, double cosine, Vec3fLanes<kLanes>& origin) const {
  // offset_ray_origin: off the surface along the geometric normal, to the side the ray goes.
  const double sign = cosine >= 0.0 ? 1.0 : -1.0;  // n or -n: multiplying by -1 negates exactly
  const double sx = sign * block.geometric_normal.x.v[i], sy = sign * block.geometric_normal.y.v[i],
               sz = sign * block.geometric_normal.z.v[i];
  const double px = block.point.x.v[i], py = block.point.y.v[i], pz = block.point.z.v[i];
  if (context_.ray_offset.mode == RayOffset::Mode::fixed) {
    const double epsilon = context_.ray_offset.epsilon;
    origin.x[i] = float(px + epsilon * sx), origin.y[i] = float(py + epsilon * sy), origin.z[i] = float(pz + epsilon * sz);
    return;
  }
  const double bound = block.error_bound.v[i];
  origin.x[i] = ray_offset_detail::round_away(px + bound * sx, sx);
  origin.y[i] = ray_offset_detail::round_away(py + bound * sy, sy);
  origin.z[i] = ray_offset_detail::round_away(pz + bound * sz, sz);
}

void BatchShader::compute_light(Lanes& block, std::size_t j) const {
  const Light& light = context_.scene.lights[j];
  const LightPlan& plan = context_.plan.lights[j];
  Lanes::Light& out = block.lights[j];
  const int lanes = block.count;
  const Vec3d position(light.position);
  const Vec3d& color = plan.color;
  const bool directional = light.is_directional(), spot = light.is_spot();
  const double cone_width = std::max(light.spot_cos_inner - light.spot_cos_outer, 1e-3);
  LaneArray<kLanes> n_dot_h, n_dot_l;
  Vec3Lanes<kLanes> intensity;
  for (int i = 0; i < lanes; ++i) {
    double lx = plan.to_light.x, ly = plan.to_light.y, lz = plan.to_light.z;
    double ir = color.r, ig = color.g, ib = color.b;
    bool on_point = false;
    if (!directional) {
      const double ox = position.x - block.point.x.v[i], oy = position.y - block.point.y.v[i],
                   oz = position.z - block.point.z.v[i];
      const double distance = std::sqrt(ox * ox + oy * oy + oz * oz);
      on_point = !(distance > 0.0);
      lx = ox / distance, ly = oy / distance, lz = oz / distance;
      const double attenuation =
          light.attenuation.x + light.attenuation.y * distance + light.attenuation.z * distance * distance;
      ir /= attenuation, ig /= attenuation, ib /= attenuation;
      if (spot) {
        const double along = light.spot_direction.x * -lx + light.spot_direction.y * -ly + light.spot_direction.z * -lz;
        const double cone = std::clamp((along - light.spot_cos_outer) / cone_width, 0.0, 1.0);
        ir *= cone * cone, ig *= cone * cone, ib *= cone * cone;
      }
    }
    out.on_point[std::size_t(i)] = on_point;
    out.to_light.x.v[i] = lx, out.to_light.y.v[i] = ly, out.to_light.z.v[i] = lz;
    intensity.x.v[i] = ir, intensity.y.v[i] = ig, intensity.z.v[i] = ib;
    const double nx = block.normal.x.v[i], ny = block.normal.y.v[i], nz = block.normal.z.v[i];
    const double hx = lx + -block.direction.x.v[i], hy = ly + -block.direction.y.v[i], hz = lz + -block.direction.z.v[i];
    const double half_length = std::sqrt(hx * hx + hy * hy + hz * hz);
    n_dot_l.v[i] = std::max(nx * lx + ny * ly + nz * lz, 0.0);
    n_dot_h.v[i] = half_length > 0.0 ? std::max((nx * hx + ny * hy + nz * hz) / half_length, 0.0) : 0.0;
    out.geometric_cosine.v[i] = block.geometric_normal.x.v[i] * lx + block.geometric_normal.y.v[i] * ly +
                                block.geometric_normal.z.v[i] * lz;
  }
  // The shadow ray: offset_ray_origin along to_light, shadow_ray_tfar from the float32 origin.
  const double light_extent = std::max({std::abs(position.x), std::abs(position.y), std::abs(position.z)});
  for (int i = 0; i < lanes; ++i) {
    set_origin(block, i, out.geometric_cosine.v[i], out.shadow_origin);
    if (directional) {
      out.shadow_distance.v[i] = double(kInfinity);
      continue;
    }
    const double ox = position.x - double(out.shadow_origin.x[i]), oy = position.y - double(out.shadow_origin.y[i]),
                 oz = position.z - double(out.shadow_origin.z[i]);
    const double distance = std::sqrt(ox * ox + oy * oy + oz * oz);
    out.shadow_distance.v[i] = context_.ray_offset.mode == RayOffset::Mode::fixed
                                   ? distance - context_.ray_offset.epsilon
                                   : ray_offset_detail::robust_shadow_tfar(distance, light_extent);
  }
  LaneArray<kLanes> power;
  for (int i = 0; i < lanes; ++i)
    power.v[i] = block.highlight[std::size_t(i)] ? std::pow(n_dot_h.v[i], block.shininess.v[i]) : 0.0;
  for (int i = 0; i < lanes; ++i) {
    const bool highlight = block.highlight[std::size_t(i)];
    // specular * pow, or Vec3d(0.0) when the highlight is skipped.
    const double hr = highlight ? block.specular.x.v[i] * power.v[i] : 0.0;
    const double hg = highlight ? block.specular.y.v[i] * power.v[i] : 0.0;
    const double hb = highlight ? block.specular.z.v[i] * power.v[i] : 0.0;
    out.term.x.v[i] = intensity.x.v[i] * (block.ambient.x.v[i] + block.diffuse.x.v[i] * n_dot_l.v[i] + hr);
    out.term.y.v[i] = intensity.y.v[i] * (block.ambient.y.v[i] + block.diffuse.y.v[i] * n_dot_l.v[i] + hg);
    out.term.z.v[i] = intensity.z.v[i] * (block.ambient.z.v[i] + block.diffuse.z.v[i] * n_dot_l.v[i] + hb);
  }
}

namespace {

// A reflection hit's terms, each shadow ray traced at once: shade.cpp's ImmediateShadows without
// its trace and timing hooks, which the batch never runs with.
struct ImmediateSink {
  const Accel& accel;
  RayCounts& counts;
  std::size_t light_count;
  Vec3d radiance{0.0};
  void lit(std::size_t, const Vec3d& term) { radiance += term; }
  void query(std::size_t slot, const Vec3d& term, const Ray& shadow_ray) {
    counts.add_shadow_query(light_count, slot);
    if (!accel.occluded(shadow_ray)) radiance += term;
  }
};

}  // namespace

template <class Sink>
std::int32_t BatchShader::shade_lane(const Lanes& lanes, int i, int depth, const Ray& ray, const Hit& hit,
                                     const Vec3d& throughput, std::int32_t parent, RayCounts& counts, Sink& sink,
                                     std::vector<Secondary>& next) const {
  const PlainMaterial& plain = materials_[lanes.material[std::size_t(i)]];
  const EffectsPlan& plan = context_.plan;
  const bool prune = plan.options.prune;
  const auto skip = [&](SkipRule rule) { ++counts.skipped[static_cast<int>(rule)]; };
  count_at(counts.hits_per_depth, std::size_t(depth));

  for (std::size_t j = 0; j < context_.scene.lights.size(); ++j) {
    const LightPlan& light_plan = plan.lights[j];
    if (!light_plan.contributes) {
      skip(SkipRule::light_off);
      continue;
    }
    const Lanes::Light& light = lanes.lights[j];
    if (light.on_point[std::size_t(i)]) {
      skip(SkipRule::light_on_surface);
      continue;
    }
    const Vec3d term = lane(light.term, i);
    if (prune && term == Vec3d(0.0)) {
      skip(SkipRule::zero_contribution);
      continue;
    }
    if (plan.options.min_light_contribution > 0.0 && max_channel(term) < plan.options.min_light_contribution) {
      skip(SkipRule::dim_light);
      continue;
    }
    const Vec3d to_light = lane(light.to_light, i);
    if (depth == 0 && light_plan.at_eye) {  // see shade_surface
      if (prune) {
        skip(SkipRule::light_at_eye);
        sink.lit(j, term);
      } else {
        Ray shadow_ray = ray;
        shadow_ray.tfar = hit.t * (1.0f - kRetraceMargin);
        sink.query(j, term, shadow_ray);
      }
    } else if (plan.convex && light.geometric_cosine.v[i] > kConvexFacingMargin) {
      skip(SkipRule::convex_facing);
      sink.lit(j, term);
    } else {
      Ray shadow_ray;
      shadow_ray.origin = Vec3f(light.shadow_origin.x[i], light.shadow_origin.y[i], light.shadow_origin.z[i]);
      const double light_distance = light.shadow_distance.v[i];
      if (light_distance > 0.0) {
        shadow_ray.direction = Vec3f(to_light);
        shadow_ray.tfar = static_cast<float>(light_distance);
        sink.query(j, term, shadow_ray);
      } else {
        skip(SkipRule::light_on_surface);
        sink.lit(j, term);
      }
    }
  }

  if (depth >= context_.scene.settings.max_depth) return -1;
  const Vec3d& reflective = plain.reflective;
  const Vec3d next_throughput = throughput * reflective;
  if (prune && (!plain.reflects || reflective == Vec3d(0.0))) {
    skip(SkipRule::black_reflection);
    return -1;
  }
  if (plan.options.min_throughput > 0.0 && max_channel(next_throughput) < plan.options.min_throughput) {
    skip(SkipRule::low_throughput);
    return -1;
  }
  Secondary& secondary = next.emplace_back();  // in place, as ShadowRecorder's records
  secondary.ray.origin = Vec3f(lanes.reflection_origin.x[i], lanes.reflection_origin.y[i], lanes.reflection_origin.z[i]);
  secondary.ray.direction = Vec3f(lane(lanes.reflected, i));
  secondary.throughput = next_throughput;
  secondary.weight = reflective;
  secondary.parent = parent;
  secondary.child = -1;
  secondary.batched = false;
  ++counts.reflection;
  count_at(counts.reflection_per_depth, std::size_t(depth) + 1);
  return static_cast<std::int32_t>(next.size() - 1);
}

void BatchShader::finish_camera_hit(Workspace& work, int k, const Ray& ray, const Hit& hit, RayCounts& counts,
                                    PendingShading& pending) const {
  const int i = work.lane_of[std::size_t(k)];
  const auto index = static_cast<std::int32_t>(pending.pixels.size());
  PendingShading::Pixel& pixel = pending.pixels.emplace_back();  // in place: see PixelCentreRays::set_ray
  pixel.emission = materials_[work.lanes.material[std::size_t(i)]].emission;
  pixel.first_term = static_cast<std::uint32_t>(pending.terms.size());
  ShadowRecorder sink{pending, counts, context_.scene.lights.size()};
  shade_lane(work.lanes, i, 0, ray, hit, Vec3d(1.0), index, counts, sink, work.waves[1]);
  pixel.term_count = static_cast<std::uint32_t>(pending.terms.size()) - pixel.first_term;
}

void BatchShader::shade_wave(Workspace& work, int depth, RayCounts& counts) const {
  if (work.waves.size() < std::size_t(depth) + 2) work.waves.resize(std::size_t(depth) + 2);
  std::vector<Secondary>& wave = work.waves[std::size_t(depth)];
  std::vector<Secondary>& next = work.waves[std::size_t(depth) + 1];
  next.clear();
  for (Secondary& secondary : wave) secondary.hit = context_.accel.intersect(secondary.ray);
  std::array<Ray, kLanes> lane_rays;
  std::array<Hit, kLanes> lane_hits;
  std::array<std::int32_t, kLanes> lane_index;
  const auto shade_lanes = [&] {
    compute_lanes(work.lanes, lane_rays, lane_hits);
    for (int i = 0; i < work.lanes.count; ++i) {
      Secondary& secondary = wave[std::size_t(lane_index[std::size_t(i)])];
      ImmediateSink sink{context_.accel, counts, context_.scene.lights.size(),
                         materials_[work.lanes.material[std::size_t(i)]].emission};
      secondary.child = shade_lane(work.lanes, i, depth, secondary.ray, secondary.hit, secondary.throughput,
                                   lane_index[std::size_t(i)], counts, sink, next);
      secondary.local = sink.radiance;
    }
    work.lanes.count = 0;
  };
  work.lanes.count = 0;
  for (std::size_t s = 0; s < wave.size(); ++s) {
    Secondary& secondary = wave[s];
    secondary.batched = batchable(secondary.hit);
    if (!secondary.batched) {  // find_color's own way, its reflections included
      secondary.color = secondary.hit.found()
                            ? shade_hit(context_, secondary.ray, secondary.hit, depth, counts, secondary.throughput, 0)
                            : context_.scene.settings.background;
      continue;
    }
    const auto i = std::size_t(work.lanes.count++);
    lane_rays[i] = secondary.ray;
    lane_hits[i] = secondary.hit;
    lane_index[i] = static_cast<std::int32_t>(s);
    if (work.lanes.count == kLanes) shade_lanes();
  }
  shade_lanes();
}

void BatchShader::trace_reflections(Workspace& work, RayCounts& counts, PendingShading& pending) const {
  int deepest = 0;
  for (int depth = 1; std::size_t(depth) < work.waves.size() && !work.waves[std::size_t(depth)].empty(); ++depth) {
    shade_wave(work, depth, counts);
    deepest = depth;
  }
  // Colours from the deepest rays up: local + weight * colour of the child (shade_surface's order).
  for (int depth = deepest; depth >= 1; --depth) {
    std::vector<Secondary>& wave = work.waves[std::size_t(depth)];
    for (Secondary& secondary : wave) {
      if (!secondary.batched) continue;
      Vec3d radiance = secondary.local;
      if (secondary.child >= 0) {
        const Secondary& child = work.waves[std::size_t(depth) + 1][std::size_t(secondary.child)];
        radiance += child.weight * Vec3d(child.color);
      }
      secondary.color = Color(radiance);
    }
  }
  for (const Secondary& secondary : work.waves[1]) {
    PendingShading::Pixel& pixel = pending.pixels[std::size_t(secondary.parent)];
    pixel.reflection = secondary.weight * Vec3d(secondary.color);
    pixel.has_reflection = true;
  }
}

}  // namespace rt
