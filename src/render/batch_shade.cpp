#include "batch_shade.h"

#include <algorithm>
#include <cmath>
#include <type_traits>

#include "rt/render/dielectric.h"
#include "area_light_terms.h"
#include "batch_lanes.h"
#include "shading_margins.h"
#include "shadow_records.h"

// The arithmetic over lanes is in batch_lanes.cpp, which mirrors shade_surface's expressions
// (and glm's: dot(a, b) = (ax bx + ay by) + az bz, normalize(v) = v * (1 / sqrt(dot(v, v))), v / s
// divides each component) operation for operation in SIMD. This file gathers the lanes' inputs,
// calls libm's pow lane by lane, and applies shade_surface's rules and records hit by hit.

namespace rt {

namespace {

using batch_lanes::Gathered;
using batch_lanes::LightLanes;

// ++counts[index], the vector grown first if needed (once per depth per thread: out of line).
[[gnu::noinline, gnu::cold]] void grow_and_count(std::vector<std::uint64_t>& counts, std::size_t index) {
  counts.resize(index + 1, 0);
  ++counts[index];
}
[[gnu::always_inline]] inline void count_at(std::vector<std::uint64_t>& counts, std::size_t index) {
  if (index < counts.size()) [[likely]]
    ++counts[index];
  else
    grow_and_count(counts, index);
}

double max_channel(const Vec3d& c) { return std::max({c.r, c.g, c.b}); }

template <class V>
Vec3d lane(const V& v, int i) {
  return Vec3d(v.x.v[i], v.y.v[i], v.z.v[i]);
}

}  // namespace

BatchShader::BatchShader(const ShadingContext& context)
    : context_(context),
      light_count_(context.scene.lights.size()),
      kernels_(batch_lanes::best_kernels()),
      origin_policy_{context.ray_offset.mode == RayOffset::Mode::fixed, context.ray_offset.epsilon},
      background_(context.scene.settings.background) {
  const Scene& scene = context.scene;
  const EffectsPlan& plan = context.plan;
  if (context.trace) return;
  for (std::size_t j = 0; j < scene.lights.size(); ++j) {
    const Light& light = scene.lights[j];
    const LightPlan& light_plan = plan.lights[j];
    LightLanes& lanes = lights_.emplace_back();
    lanes.directional = light.is_directional();
    lanes.spot = light.is_spot();
    const Vec3d position(light.position);
    const auto put = [](double (&to)[3], const Vec3d& from) { to[0] = from.x, to[1] = from.y, to[2] = from.z; };
    put(lanes.position, position);
    put(lanes.to_light, light_plan.to_light);
    put(lanes.color, light_plan.color);
    put(lanes.attenuation, light.attenuation);
    put(lanes.spot_direction, light.spot_direction);
    lanes.spot_cos_outer = light.spot_cos_outer;
    lanes.cone_width = std::max(light.spot_cos_inner - light.spot_cos_outer, 1e-3);
    lanes.extent = std::max({std::abs(position.x), std::abs(position.y), std::abs(position.z)});
  }
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
    plain.reflects_light = plain.reflects && plain.reflective != Vec3d(0.0);
    plain.emission = Vec3d(material.emission);
    enabled_ = enabled_ || plain.batched;
  }
  if (plan.area_lights && plan.options.light_sampling != LightSampling::area)
    for (std::size_t e = 0; e < std::min(kViewedEmitters, plan.area_lights->emitters.size()); ++e)
      if (plan.emitters[e].contributes && plan.area_lights->emitters[e].triangles.size() <= kViewedTriangles)
        small_emitters_.push_back(e);
  const std::vector<std::uint32_t>& ids = context.flat.material_ids;
  for (std::size_t t = 0; t < ids.size() && run_first_.size() <= kMaxRuns; ++t)
    if (t == 0 || ids[t] != ids[t - 1]) {
      run_first_.push_back(static_cast<std::uint32_t>(t));
      run_material_.push_back(ids[t]);
    }
  if (run_first_.size() > kMaxRuns) run_first_.clear(), run_material_.clear();
}

std::uint32_t BatchShader::material_of_triangle(std::uint32_t triangle) const {
  if (run_first_.empty()) return context_.flat.material_ids[triangle];
  std::uint32_t material = run_material_[0];
  for (std::size_t r = 1; r < run_first_.size(); ++r)
    if (triangle >= run_first_[r]) material = run_material_[r];
  return material;
}

bool BatchShader::batchable(const Hit& hit) const {
  const FlatScene& flat = context_.flat;
  return hit.found() && !flat.is_sphere(hit.primitive) && materials_[material_of_triangle(hit.primitive)].batched;
}

void BatchShader::compute_lanes(Lanes& lanes, const Ray* rays, const Hit* hits, int depth) const {
  if (lanes.count == 0) return;
  compute_surfaces(lanes, rays, hits, depth);
  lanes.lights.resize(context_.scene.lights.size());
  for (std::size_t j = 0; j < context_.scene.lights.size(); ++j)
    if (context_.plan.lights[j].contributes) compute_light(lanes, j);
  if (!small_emitters_.empty()) compute_emitter_views(lanes);
}

void BatchShader::compute_emitter_views(Lanes& lanes) const {
  const EffectsPlan& plan = context_.plan;
  lanes.emitter_views.resize(small_emitters_.size());
  std::array<Vec3d, kViewedTriangles * kLanes> points;
  std::array<std::array<Vec3d, 3>, kViewedTriangles * kLanes> corners;
  for (std::size_t v = 0; v < small_emitters_.size(); ++v) {
    const Emitter& emitter = plan.area_lights->emitters[small_emitters_[v]];
    Lanes::EmitterViews& views = lanes.emitter_views[v];
    int n = 0;
    for (int i = 0; i < lanes.count; ++i) {
      const Vec3d point = lane(lanes.point, i);
      const bool drawn = !plan.options.prune ||
                         emitter_zero_rule(emitter, point, lane(lanes.normal, i),
                                           plan.materials[lanes.material[std::size_t(i)]]) == SkipRule::sample_zero;
      views.first[std::size_t(i)] = static_cast<std::int16_t>(drawn ? n : -1);
      if (!drawn) continue;
      for (const EmitterTriangle& t : emitter.triangles) {
        points[std::size_t(n)] = point;
        corners[std::size_t(n++)] = {t.p0, t.p1, t.p2};
      }
    }
    SphericalTriangle::set_up_many(std::span(points).first(std::size_t(n)), std::span(corners).first(std::size_t(n)),
                                   views.spherical);
  }
}

void BatchShader::prepare(std::span<const Ray> rays, std::span<const Hit> hits, std::span<const bool> unbatched,
                          Workspace& work) const {
  int count = 0;
  for (std::size_t k = 0; k < hits.size(); ++k) {
    const bool batched = !unbatched[k] && batchable(hits[k]);
    work.lane_of[k] = static_cast<std::int8_t>(batched ? count++ : -1);
  }
  work.lanes.count = count;
  if (count == 0) return;
  if (std::size_t(count) == hits.size()) {  // every hit batched: the lanes are the packet's own
    compute_lanes(work.lanes, rays.data(), hits.data(), 0);
    return;
  }
  std::array<Ray, kLanes> lane_rays;
  std::array<Hit, kLanes> lane_hits;
  for (std::size_t k = 0; k < hits.size(); ++k)
    if (const int lane = work.lane_of[k]; lane >= 0) {
      lane_rays[std::size_t(lane)] = rays[k];
      lane_hits[std::size_t(lane)] = hits[k];
    }
  compute_lanes(work.lanes, lane_rays.data(), lane_hits.data(), 0);
}

void BatchShader::prefetch_triangles(std::span<const Hit> hits) const {
  const FlatScene& flat = context_.flat;
  for (const Hit& hit : hits)
    if (hit.found() && !flat.is_sphere(hit.primitive)) {
      __builtin_prefetch(&flat.triangles[hit.primitive]);
      if (run_first_.empty()) __builtin_prefetch(&flat.material_ids[hit.primitive]);
    }
}

void BatchShader::prefetch_vertices(std::span<const Hit> hits) const {
  const FlatScene& flat = context_.flat;
  for (const Hit& hit : hits)
    if (hit.found() && !flat.is_sphere(hit.primitive)) {
      const Vec3u tri = flat.triangles[hit.primitive];
      for (const std::uint32_t v : {tri.x, tri.y, tri.z}) {
        __builtin_prefetch(&flat.positions[v]);
        __builtin_prefetch(&flat.normals[v]);
      }
    }
}

void BatchShader::start_block(Workspace& work) const {
  if (work.waves.size() < 2) work.waves.resize(2);
  work.waves[1].clear();
}

void BatchShader::compute_surfaces(Lanes& block, const Ray* rays, const Hit* hits, int depth) const {
  const FlatScene& flat = context_.flat;
  const int lanes = block.count;
  // The callers have requested the triangles and vertices some work before (prefetch_triangles,
  // prefetch_vertices).
  std::array<Vec3u, kLanes> triangles{};  // zeros past the count: never read, but the compiler cannot tell
  for (int i = 0; i < lanes; ++i) triangles[std::size_t(i)] = flat.triangles[hits[i].primitive];
  for (int i = 0; i < lanes; ++i) block.material[std::size_t(i)] = material_of_triangle(hits[i].primitive);
  Gathered in;
  kernels_.gather(batch_lanes::VertexArrays{flat.positions.data(), flat.normals.data(), flat.positions.size()},
                  triangles.data(), rays, hits, lanes, in);
  // The materials' values at each lane; lanes past the count (up to the next multiple of 4) copy
  // lane 0's. Most packets see one material: its values are then written to every lane at once.
  const int padded = (lanes + 3) / 4 * 4;
  const auto put_material = [&](int i, const PlainMaterial& plain) {
    in.flip[i] = plain.flip_back_face ? -1 : 0;
    block.ambient.x.v[i] = plain.ambient.x, block.ambient.y.v[i] = plain.ambient.y, block.ambient.z.v[i] = plain.ambient.z;
    block.diffuse.x.v[i] = plain.diffuse.x, block.diffuse.y.v[i] = plain.diffuse.y, block.diffuse.z.v[i] = plain.diffuse.z;
    block.specular.x.v[i] = plain.specular.x, block.specular.y.v[i] = plain.specular.y,
    block.specular.z.v[i] = plain.specular.z;
    block.shininess.v[i] = plain.shininess;
    block.highlight[i] = plain.highlight ? -1 : 0;
  };
  const std::uint32_t first_material = block.material[0];
  bool one_material = true;
  for (int i = 1; i < lanes; ++i) one_material = one_material && block.material[std::size_t(i)] == first_material;
  block.highlights = false;
  bool reflecting = false;
  if (one_material) {
    const PlainMaterial& plain = materials_[first_material];
    for (int i = 0; i < kLanes; ++i) put_material(i, plain);
    block.highlights = plain.highlight;
    reflecting = plain.reflects_light;
  } else {
    for (int i = 0; i < padded; ++i) {
      const PlainMaterial& plain = materials_[block.material[std::size_t(i < lanes ? i : 0)]];
      put_material(i, plain);
      block.highlights = block.highlights || plain.highlight;
      reflecting = reflecting || plain.reflects_light;
    }
  }
  // What shade_lane reads to make a reflection ray: computed unless no lane can make one.
  block.reflections = depth < context_.scene.settings.max_depth && (reflecting || !context_.plan.options.prune);
  kernels_.surfaces(in, origin_policy_, block);
}

void BatchShader::compute_light(Lanes& block, std::size_t j) const {
  Lanes::Light& out = block.lights[j];
  LaneArray<kLanes> n_dot_h, n_dot_l, power;
  Vec3Lanes<kLanes> intensity;
  kernels_.light(lights_[j], origin_policy_, block, out, intensity, n_dot_l, n_dot_h);
  // pow stays libm's scalar call, lane by lane.
  for (int i = 0; i < block.count; ++i)
    power.v[i] = block.highlight[i] != 0 ? std::pow(n_dot_h.v[i], block.shininess.v[i]) : 0.0;
  for (int i = block.count; i % 4 != 0; ++i) power.v[i] = 0.0;
  kernels_.terms(block, intensity, n_dot_l, power, out);
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
void BatchShader::add_area_lights(const Lanes& lanes, int i, int depth, std::uint64_t path_seed, RayCounts& counts,
                                  Sink& sink) const {
  const std::uint32_t material = lanes.material[std::size_t(i)];
  const PlainMaterial& plain = materials_[material];
  // shade_surface's values, bit for bit: its diffuse is the material's times a white texel (x * 1
  // is x) and its to_eye the negated unit direction.
  const SurfacePoint surface{lane(lanes.point, i), lane(lanes.geometric_normal, i), lanes.error_bound.v[i]};
  const Vec3d normal = lane(lanes.normal, i), to_eye = -lane(lanes.direction, i);
  std::array<const SphericalTriangle*, kViewedEmitters> spherical{};
  for (std::size_t v = 0; v < small_emitters_.size(); ++v) {
    const Lanes::EmitterViews& views = lanes.emitter_views[v];
    const std::int16_t first = views.first[std::size_t(i)];
    if (first >= 0) spherical[small_emitters_[v]] = &views.spherical[std::size_t(first)];
  }
  const std::size_t viewed = std::min(kViewedEmitters, context_.plan.area_lights->emitters.size());
  const LitSurface lit{surface, normal, to_eye, plain.diffuse, plain.specular, plain.shininess,
                       context_.plan.materials[material], std::span(spherical).first(viewed)};
  if constexpr (std::is_same_v<Sink, ShadowRecorder>)
    record_area_light_terms(context_, lit, depth, path_seed, counts, sink);
  else
    trace_area_light_terms(context_, lit, depth, path_seed, counts, sink.radiance);
}

template <class Sink>
std::int32_t BatchShader::shade_lane(const Lanes& lanes, int i, int depth, const Ray& ray, const Hit& hit,
                                     const Vec3d& throughput, std::uint64_t path_seed, std::int32_t parent,
                                     RayCounts& counts, Sink& sink, std::vector<Secondary>& next) const {
  const PlainMaterial& plain = materials_[lanes.material[std::size_t(i)]];
  const EffectsPlan& plan = context_.plan;
  const bool prune = plan.options.prune;
  const auto skip = [&](SkipRule rule) { ++counts.skipped[static_cast<int>(rule)]; };
  count_at(counts.hits_per_depth, std::size_t(depth));

  for (std::size_t j = 0; j < light_count_; ++j) {
    const LightPlan& light_plan = plan.lights[j];
    if (!light_plan.contributes) {
      skip(SkipRule::light_off);
      continue;
    }
    const Lanes::Light& light = lanes.lights[j];
    if (light.on_point[i] != 0) {
      skip(SkipRule::light_on_surface);
      continue;
    }
    if (prune && light.zero_term[i] != 0) {
      skip(SkipRule::zero_contribution);
      continue;
    }
    const Vec3d term = lane(light.term, i);
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

  if (plan.area_lights) add_area_lights(lanes, i, depth, path_seed, counts, sink);

  if (depth >= context_.scene.settings.max_depth) return -1;
  const Vec3d& reflective = plain.reflective;
  const Vec3d next_throughput = throughput * reflective;
  if (prune && !plain.reflects_light) {
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
  // Component by component: next_throughput may have been spilled by 8-byte stores, and a wider
  // load of it would stall store forwarding (as in ShadowRecorder).
  secondary.throughput.x = next_throughput.x;
  secondary.throughput.y = next_throughput.y;
  secondary.throughput.z = next_throughput.z;
  secondary.weight = reflective;
  secondary.path_seed = path_seed;
  secondary.parent = parent;
  secondary.child = -1;
  secondary.batched = false;
  ++counts.reflection;
  count_at(counts.reflection_per_depth, std::size_t(depth) + 1);
  return static_cast<std::int32_t>(next.size() - 1);
}

void BatchShader::finish_camera_hit(Workspace& work, int k, const Ray& ray, const Hit& hit, std::uint64_t path_seed,
                                    RayCounts& counts, PendingShading& pending) const {
  const int i = work.lane_of[std::size_t(k)];
  const auto index = static_cast<std::int32_t>(pending.pixels.size());
  PendingShading::Pixel& pixel = pending.pixels.emplace_back();  // in place: see PixelCentreRays::set_ray
  pixel.emission = materials_[work.lanes.material[std::size_t(i)]].emission;
  pixel.first_term = static_cast<std::uint32_t>(pending.terms.size());
  ShadowRecorder sink{pending, counts, light_count_};
  shade_lane(work.lanes, i, 0, ray, hit, Vec3d(1.0), path_seed, index, counts, sink, work.waves[1]);
  pixel.term_count = static_cast<std::uint32_t>(pending.terms.size()) - pixel.first_term;
}

void BatchShader::shade_wave(Workspace& work, int depth, RayCounts& counts) const {
  if (work.waves.size() < std::size_t(depth) + 2) work.waves.resize(std::size_t(depth) + 2);
  std::vector<Secondary>& wave = work.waves[std::size_t(depth)];
  std::vector<Secondary>& next = work.waves[std::size_t(depth) + 1];
  next.clear();
  // Each hit's triangle indices are requested while the next rays are traced, its vertices two
  // rays later (once the indices have arrived).
  constexpr std::size_t kLag = 2;
  const std::size_t count = wave.size();  // the wave does not change below (only `next` grows)
  for (std::size_t s = 0; s < count; ++s) {
    wave[s].hit = context_.accel.intersect(wave[s].ray);
    prefetch_triangles(std::span(&wave[s].hit, 1));
    if (s >= kLag) prefetch_vertices(std::span(&wave[s - kLag].hit, 1));
  }
  for (std::size_t s = count > kLag ? count - kLag : 0; s < count; ++s) prefetch_vertices(std::span(&wave[s].hit, 1));
  std::array<Ray, kLanes> lane_rays;
  std::array<Hit, kLanes> lane_hits;
  std::array<std::int32_t, kLanes> lane_index;
  const auto shade_lanes = [&] {
    compute_lanes(work.lanes, lane_rays.data(), lane_hits.data(), depth);
    for (int i = 0; i < work.lanes.count; ++i) {
      Secondary& secondary = wave[std::size_t(lane_index[std::size_t(i)])];
      ImmediateSink sink{context_.accel, counts, light_count_,
                         materials_[work.lanes.material[std::size_t(i)]].emission};
      secondary.child = shade_lane(work.lanes, i, depth, secondary.ray, secondary.hit, secondary.throughput,
                                   secondary.path_seed, lane_index[std::size_t(i)], counts, sink, next);
      secondary.local = sink.radiance;
    }
    work.lanes.count = 0;
  };
  work.lanes.count = 0;
  for (std::size_t s = 0; s < count; ++s) {
    Secondary& secondary = wave[s];
    secondary.batched = batchable(secondary.hit);
    if (!secondary.batched) {  // find_color's own way, its reflections included
      secondary.color = secondary.hit.found()
                            ? shade_hit(context_, secondary.ray, secondary.hit, depth, counts, secondary.throughput,
                                        secondary.path_seed)
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
