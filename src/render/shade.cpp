#include "rt/render/shade.h"

#include <algorithm>
#include <bit>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>
#include <optional>

#include <x86intrin.h>

#include <fmt/format.h>

#include "rt/render/alpha.h"
#include "rt/render/dielectric.h"
#include "rt/render/sampling.h"
#include "rt/render/surface_maps.h"
#include "area_light_terms.h"
#include "light_sample_lanes.h"
#include "shading_margins.h"
#include "shadow_records.h"

namespace rt {

namespace {

// counts[index] += amount, growing the vector as needed.
void add_at(std::vector<std::uint64_t>& counts, std::size_t index, std::uint64_t amount = 1) {
  if (counts.size() <= index) counts.resize(index + 1, 0);
  counts[index] += amount;
}

void add_all(std::vector<std::uint64_t>& into, const std::vector<std::uint64_t>& from) {
  for (std::size_t i = 0; i < from.size(); ++i) add_at(into, i, from[i]);
}

double max_channel(const Vec3d& c) { return std::max({c.r, c.g, c.b}); }

std::string format_vec(const Vec3d& v) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x, v.y, v.z); }

std::string format_ray(const Ray& ray) {
  return fmt::format("origin {} direction {} t in [{:.6g}, {:.6g}]", format_vec(Vec3d(ray.origin)),
                     format_vec(Vec3d(ray.direction)), ray.tnear, ray.tfar);
}

// One line of the --debug-pixel trace, indented by ray depth; nothing when tracing is off.
template <typename... Args>
void note(const ShadingContext& context, int depth, fmt::format_string<Args...> format, Args&&... args) {
  if (context.trace)
    context.trace->push_back(std::string(2 * std::size_t(depth), ' ') + fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace

std::uint64_t RayCounts::skipped_total() const { return std::accumulate(skipped.begin(), skipped.end(), std::uint64_t{0}); }

RayCounts& RayCounts::operator+=(const RayCounts& other) {
  camera += other.camera;
  shadow += other.shadow;
  reflection += other.reflection;
  refraction += other.refraction;
  see_through += other.see_through;
  area_light += other.area_light;
  add_all(shadow_per_light, other.shadow_per_light);
  add_all(area_light_per_emitter, other.area_light_per_emitter);
  add_all(reflection_per_depth, other.reflection_per_depth);
  add_all(refraction_per_depth, other.refraction_per_depth);
  add_all(see_through_per_depth, other.see_through_per_depth);
  add_all(hits_per_depth, other.hits_per_depth);
  for (int r = 0; r < kSkipRuleCount; ++r) skipped[r] += other.skipped[r];
  add_all(intersect_ticks_per_depth, other.intersect_ticks_per_depth);
  add_all(shadow_ticks_per_light, other.shadow_ticks_per_light);
  add_all(area_light_ticks_per_emitter, other.area_light_ticks_per_emitter);
  loop_ticks += other.loop_ticks;
  return *this;
}

void RayCounts::add_shadow_ticks(std::size_t light_count, std::size_t slot, std::uint64_t ticks) {
  if (slot < light_count)
    add_at(shadow_ticks_per_light, slot, ticks);
  else
    add_at(area_light_ticks_per_emitter, slot - light_count, ticks);
}

std::uint64_t pixel_path_seed(int x, int y, int sample) {
  return mix64((std::uint64_t(std::uint32_t(y)) << 32 | std::uint32_t(x)) ^ mix64(std::uint64_t(std::uint32_t(sample)) + 1));
}

namespace {

Hit intersect_timed(const ShadingContext& context, const Ray& ray, int depth, RayCounts& counts) {
  const std::uint64_t intersect_start = context.time_queries ? __rdtsc() : 0;
  const Hit hit = context.accel.intersect(ray);
  if (context.time_queries) add_at(counts.intersect_ticks_per_depth, std::size_t(depth), __rdtsc() - intersect_start);
  return hit;
}

}  // namespace

Color find_color(const ShadingContext& context, const Ray& ray, int depth, RayCounts& counts,
                 const Vec3d& throughput, std::uint64_t path_seed) {
  return shade_hit(context, ray, intersect_timed(context, ray, depth, counts), depth, counts, throughput, path_seed);
}

namespace {

// find_color for a ray travelling inside `medium` (a dielectric's volume): what it brings back is
// attenuated by Beer–Lambert over its length to the next surface (all of it on a miss).
Vec3d find_color_inside(const ShadingContext& context, const Ray& ray, int depth, RayCounts& counts,
                        const Vec3d& throughput, std::uint64_t path_seed, const Material& medium) {
  const Hit hit = intersect_timed(context, ray, depth, counts);
  const Vec3d radiance(shade_hit(context, ray, hit, depth, counts, throughput, path_seed));
  if (!std::isfinite(medium.attenuation_distance)) return radiance;
  // Ray directions are unit length, so t is the distance in scene units.
  return radiance * beer_lambert_transmittance(Vec3d(medium.attenuation_color), medium.attenuation_distance,
                                               hit.found() ? double(hit.t) : double(kInfinity));
}

// "light 2" or "area light 0 sample 5" for the trace: light slots past the scene's lights are
// emitters' samples.
std::string light_label(const ShadingContext& context, std::size_t slot, int sample) {
  const std::size_t lights = context.scene.lights.size();
  return slot < lights ? fmt::format("light {}", slot) : fmt::format("area light {} sample {}", slot - lights, sample);
}

// What shade_surface does with each light's unshadowed term: `lit` adds a term that needs no shadow
// query, `query` one that is added only if `shadow_ray` is unblocked, in light order; `finish`
// receives the emission and the reflection term (added last; `has_reflection` false when no
// reflection ray was traced). ImmediateShadows traces each query at once; DeferredShadows (the
// camera blocks of render_image) records them to be traced as packets, then sums in the same order.
struct ImmediateShadows {
  const ShadingContext& context;
  RayCounts& counts;
  int depth;
  Vec3d radiance{0.0};

  void begin(const Vec3d& emission) { radiance = emission; }
  // `slot`: the light (see RayCounts::add_shadow_query); `sample`: the area-light sample, for the trace.
  void lit(std::size_t slot, const Vec3d& term, int sample = 0) {
    if (context.trace) note(context, depth, "  {}: visible, term {}", light_label(context, slot, sample), format_vec(term));
    radiance += term;
  }
  [[gnu::always_inline]] void query(std::size_t slot, const Vec3d& term, const Ray& shadow_ray, int sample = 0) {
    const std::size_t light_count = context.scene.lights.size();
    counts.add_shadow_query(light_count, slot);
    const std::uint64_t start = context.time_queries ? __rdtsc() : 0;
    const bool blocked = context.accel.occluded(shadow_ray);
    if (context.time_queries) counts.add_shadow_ticks(light_count, slot, __rdtsc() - start);
    if (context.trace) {
      const std::string label = light_label(context, slot, sample);
      note(context, depth, "  {}: shadow ray {}: {}", label, format_ray(shadow_ray), blocked ? "blocked" : "clear");
      note(context, depth, "  {}: {}, term {}", label, blocked ? "in shadow" : "visible", format_vec(term));
    }
    if (!blocked) radiance += term;
  }
  void add_reflection(const Vec3d& reflection) { radiance += reflection; }
};

struct DeferredShadows : ShadowRecorder {
  PendingShading::Pixel pixel{};

  void begin(const Vec3d& emission) {
    pixel.emission = emission;
    pixel.first_term = static_cast<std::uint32_t>(pending.terms.size());
  }
  void add_reflection(const Vec3d& reflection) {  // the reflection, then a blended surface's see-through ray
    pixel.reflection = pixel.has_reflection ? pixel.reflection + reflection : reflection;
    pixel.has_reflection = true;
  }
};

// What the area-light lanes read of the hit (LitSurface, the offset policy), for N samples per
// hit (scale = 1 / (pi N)).
light_sample_lanes::Shading lanes_shading(const LitSurface& lit, const RayOffset& ray_offset, double scale, bool prune) {
  light_sample_lanes::Shading shading;
  for (int axis = 0; axis < 3; ++axis) {
    shading.normal[axis] = lit.normal[axis];
    shading.to_eye[axis] = lit.to_eye[axis];
    shading.point[axis] = lit.surface.point[axis];
    shading.geometric_normal[axis] = lit.surface.geometric_normal[axis];
    shading.diffuse[axis] = lit.diffuse[axis];
    shading.specular[axis] = lit.specular[axis];
  }
  shading.error_bound = lit.surface.error_bound;
  shading.shininess = lit.shininess;
  shading.scale = scale;
  shading.highlights = lit.terms.specular || !prune;
  shading.fixed_offset = ray_offset.mode == RayOffset::Mode::fixed;
  shading.epsilon = ray_offset.epsilon;
  return shading;
}

// The emission texture times the radiance of the chunk's samples whose term can be non-zero
// (valid, the emitter's front facing them, n.l > 0): the lookups the others would waste.
void apply_emission_texture(const EmitterSampler& sampler, const light_sample_lanes::FacingOutput& factors,
                            light_sample_lanes::Chunk& chunk) {
  light_sample_lanes::Vec3& radiance = chunk.out.radiance_over_pdf;
  for (int k = 0; k < chunk.count; ++k)
    if (chunk.out.valid[k] && chunk.out.front[k] && factors.n_dot_l.v[k] > 0.0) {
      const Vec3d textured = Vec3d(radiance.x.v[k], radiance.y.v[k], radiance.z.v[k]) * sampler.emission_texel(chunk, k);
      radiance.x.v[k] = textured.x;
      radiance.y.v[k] = textured.y;
      radiance.z.v[k] = textured.z;
    }
}

// The set bits of x: std::popcount without the library call it compiles to where the baseline
// build lacks the POPCNT instruction.
std::uint32_t count_bits(std::uint32_t x) {
  x -= (x >> 1) & 0x55555555u;
  x = (x & 0x33333333u) + ((x >> 2) & 0x33333333u);
  return (((x + (x >> 4)) & 0x0F0F0F0Fu) * 0x01010101u) >> 24;
}

// The rules add_area_light_terms applies to each sample of a chunk, for all its lanes at once as
// bit masks (lane k: bit k; in_use: k < chunk.count): a sample is valid, its term is kept where it
// is valid and, pruned, not exactly (0, 0, 0), and traced where in addition its float32 tfar is
// positive. The counts are of the samples each rule skips (sample_on_surface: invalid, or kept
// without a ray; sample_zero).
struct SampleMasks {
  std::uint32_t in_use = 0, valid = 0, kept = 0, traced = 0;
  std::uint32_t kept_count = 0, traced_count = 0;  // their set bits
  std::uint64_t on_surface = 0, zero = 0;
};
SampleMasks sample_masks(const light_sample_lanes::Chunk& chunk, const light_sample_lanes::EmitOutput& emitted,
                         bool prune) {
  static_assert(light_sample_lanes::kLanes % 4 == 0 && light_sample_lanes::kLanes <= 32);
  // Lanes past chunk.count are read (the arrays hold kLanes) but masked off.
  std::uint32_t valid = 0, nonzero = 0, positive = 0;
  const __m128d zero = _mm_setzero_pd();
  for (int k = 0; k < chunk.count; k += 2) {
    valid |= std::uint32_t(_mm_movemask_pd(_mm_load_pd(reinterpret_cast<const double*>(&chunk.out.valid[k])))) << k;
    // Not equal, unordered: a NaN component counts as non-zero, as !(term == Vec3d(0.0)) has it.
    const __m128d any = _mm_or_pd(_mm_or_pd(_mm_cmpneq_pd(_mm_load_pd(&emitted.term.x.v[k]), zero),
                                            _mm_cmpneq_pd(_mm_load_pd(&emitted.term.y.v[k]), zero)),
                                  _mm_cmpneq_pd(_mm_load_pd(&emitted.term.z.v[k]), zero));
    nonzero |= std::uint32_t(_mm_movemask_pd(any)) << k;
  }
  for (int k = 0; k < chunk.count; k += 4)
    positive |= std::uint32_t(_mm_movemask_ps(_mm_cmpgt_ps(_mm_load_ps(&emitted.tfar[k]), _mm_setzero_ps()))) << k;
  SampleMasks masks;
  masks.in_use = chunk.count == 32 ? ~0u : (1u << chunk.count) - 1;
  masks.valid = valid & masks.in_use;
  masks.kept = prune ? masks.valid & nonzero : masks.valid;
  masks.traced = masks.kept & positive;
  const std::uint32_t valid_count = count_bits(masks.valid);
  masks.kept_count = count_bits(masks.kept);
  masks.traced_count = count_bits(masks.traced);
  masks.on_surface = std::uint32_t(chunk.count) - valid_count + masks.kept_count - masks.traced_count;
  masks.zero = valid_count - masks.kept_count;
  return masks;
}

// Sample k's shadow ray (world space, float32), as add_area_light_terms traces it.
Ray sample_shadow_ray(const light_sample_lanes::EmitOutput& emitted, int k) {
  Ray ray;
  ray.origin = {emitted.origin.x[k], emitted.origin.y[k], emitted.origin.z[k]};
  ray.direction = {emitted.direction.x[k], emitted.direction.y[k], emitted.direction.z[k]};
  ray.tfar = emitted.tfar[k];
  return ray;
}

// What ShadowRecorder's query and lit append for the samples of one chunk (`masks` its rules),
// with the same records in the same order and the same counts, written in one pass: the buffers
// grow once for the chunk rather than once per record.
void record_chunk(ShadowRecorder& recorder, std::size_t slot, const light_sample_lanes::EmitOutput& emitted,
                  const SampleMasks& masks) {
  const std::uint32_t kept = masks.kept, traced = masks.traced, kept_count = masks.kept_count,
                      ray_count = masks.traced_count;

  PendingShading& pending = recorder.pending;
  const std::size_t first_term = pending.terms.size(), first_ray = pending.shadow_rays.size();
  pending.terms.resize(first_term + kept_count);
  pending.shadow_rays.resize(first_ray + ray_count);
  pending.shadow_lights.resize(first_ray + ray_count, static_cast<std::uint32_t>(slot));
  PendingShading::Term* term = pending.terms.data() + first_term;
  Ray* ray = pending.shadow_rays.data() + first_ray;
  auto query = static_cast<std::uint32_t>(first_ray);
  for (std::uint32_t lanes = kept; lanes != 0; lanes &= lanes - 1, ++term) {
    const int k = std::countr_zero(lanes);
    term->term = Vec3d(emitted.term.x.v[k], emitted.term.y.v[k], emitted.term.z.v[k]);
    if (((traced >> k) & 1u) == 0) {
      term->query = PendingShading::kNoQuery;
      continue;
    }
    term->query = query++;
    ray->origin = {emitted.origin.x[k], emitted.origin.y[k], emitted.origin.z[k]};
    ray->direction = {emitted.direction.x[k], emitted.direction.y[k], emitted.direction.z[k]};
    ray->tnear = 0.0f;
    ray->tfar = emitted.tfar[k];
    ++ray;
  }
  RayCounts& counts = recorder.counts;
  counts.skipped[static_cast<int>(SkipRule::sample_on_surface)] += masks.on_surface;
  counts.skipped[static_cast<int>(SkipRule::sample_zero)] += masks.zero;
  if (ray_count > 0) counts.add_shadow_query(recorder.light_count, slot, ray_count);
}

// The area lights' terms at a hit, in emitter order, each emitter's light_samples samples in
// pattern order: term_k = L_e,k / pdf_k (C_d n.l_k + C_s max(n.h_k, 0)^sigma) / (pi N) where
// n.l_k > 0, shadowed by its own ray. The emitter-level rules (unlit material, behind a planar
// emitter, below the horizon) make every term of the emitter zero in both modes: pruned, no
// sample is drawn; unpruned, the samples are drawn and traced and add zero. The pow is the lanes'
// (lane_libm.h: binary powering for a whole shininess, else within 1 ulp of glibc's; what that
// does to images is in docs/performance.md).
// Kept out of line, so that scenes without emitters run shade_surface as it was compiled before
// area lights.
template <class Shadows>
[[gnu::noinline]] void add_area_light_terms(const ShadingContext& context, const LitSurface& lit, int depth, std::uint64_t path_seed,
                          RayCounts& counts, Shadows& shadows) {
  const EffectsPlan& plan = context.plan;
  const AreaLights& area_lights = *plan.area_lights;
  const bool prune = plan.options.prune;
  const auto samples = static_cast<std::uint32_t>(plan.options.light_samples);
  const double scale = 1.0 / (std::numbers::pi * double(samples));
  const Vec3d& point = lit.surface.point;
  const auto skip = [&](SkipRule rule, std::size_t emitter, std::uint32_t amount) {
    counts.skipped[static_cast<int>(rule)] += amount;
    if (context.trace)
      note(context, depth, "  area light {}: {} sample{} not traced ({})", emitter, amount, amount == 1 ? "" : "s",
           to_string(rule));
  };
  // The pattern's points and their light samples, drawn a chunk at a time in lanes, where their
  // n.l, highlights max(n.h, 0)^sigma, terms and shadow rays are computed too.
  namespace lanes = light_sample_lanes;
  static const lanes::Kernels& kernels = lanes::best_kernels();
  constexpr std::uint32_t kChunk = lanes::kLanes;
  std::array<Vec2d, kChunk> points;
  lanes::Shading shading = lanes_shading(lit, context.ray_offset, scale, prune);
  bool origins_set = false;  // set_origins, once an emitter needs them
  lanes::Chunk chunk;
  lanes::FacingOutput factors;
  lanes::EmitOutput emitted;
  for (std::size_t e = 0; e < area_lights.emitters.size(); ++e) {
    const Emitter& emitter = area_lights.emitters[e];
    const std::size_t slot = context.scene.lights.size() + e;
    if (!plan.emitters[e].contributes) {
      skip(SkipRule::emitter_off, e, samples);
      continue;
    }
    const SkipRule zero_rule = emitter_zero_rule(emitter, point, lit.normal, lit.terms);
    const bool all_zero = zero_rule != SkipRule::sample_zero;
    if (prune && all_zero) {
      skip(zero_rule, e, samples);
      continue;
    }
    const auto pattern = static_cast<std::uint32_t>(mix64(path_seed ^ mix64((std::uint64_t(depth) << 32) + e)));
    EmitterSampler sampler(emitter, context.flat, context.scene, context.textures, point, plan.options.light_sampling,
                           e < lit.spherical.size() ? lit.spherical[e] : nullptr);
    if (!origins_set) {
      kernels.set_origins(shading);
      origins_set = true;
    }
    for (std::uint32_t first = 0; first < samples; first += kChunk) {
      const auto chunk_points = std::span(points).first(std::min(kChunk, samples - first));
      cmj_samples(first, chunk_points, samples, pattern);
      sampler.draw(chunk_points, chunk);
      kernels.facing(shading, chunk, factors);
      if (!all_zero && sampler.has_emission_texture()) apply_emission_texture(sampler, factors, chunk);
      kernels.emit(shading, chunk, factors, !all_zero, emitted);
      const SampleMasks masks = sample_masks(chunk, emitted, prune);
      const bool tracing = context.trace;
      if constexpr (std::is_base_of_v<ShadowRecorder, Shadows>)
        if (!tracing) {
          record_chunk(shadows, slot, emitted, masks);
          continue;
        }
      if (!tracing) {
        counts.skipped[static_cast<int>(SkipRule::sample_on_surface)] += masks.on_surface;
        counts.skipped[static_cast<int>(SkipRule::sample_zero)] += masks.zero;
      }
      // The kept samples in pattern order; when tracing, every sample, the skipped ones counted
      // (and noted) one by one in that order.
      for (std::uint32_t lanes = tracing ? masks.in_use : masks.kept; lanes != 0; lanes &= lanes - 1) {
        const int k = std::countr_zero(lanes);
        if (((masks.kept >> k) & 1u) == 0) {
          skip((masks.valid >> k) & 1u ? SkipRule::sample_zero : SkipRule::sample_on_surface, e, 1);
          continue;
        }
        const Vec3d term(emitted.term.x.v[k], emitted.term.y.v[k], emitted.term.z.v[k]);
        if ((masks.traced >> k) & 1u) {
          shadows.query(slot, term, sample_shadow_ray(emitted, k), int(first) + k);
        } else {
          if (tracing) skip(SkipRule::sample_on_surface, e, 1);
          shadows.lit(slot, term, int(first) + k);
        }
      }
    }
  }
}

// The radiance a ray sees leaving an emitter's surface (Material::emits_light): its emission (times
// its texture) from its front side only.
Vec3d emitted_radiance(const ShadingContext& context, const Material& material, std::uint32_t material_id,
                       const SurfacePoint& surface, const Vec3d& to_eye, const std::optional<TexCoords>& texcoord) {
  if (!(glm::dot(surface.geometric_normal, to_eye) > 0.0)) return Vec3d(0.0);
  if (texcoord && context.textures && context.textures->has_emission(material_id))
    return Vec3d(material.emission) * Vec3d(context.textures->emission(material_id, *texcoord));
  return Vec3d(material.emission);
}

// What a point of a dielectric material refracts (Material::is_dielectric): the share of the
// point that is glass (1 unless Material::transmission_mix) and the tint of transmitted light.
struct GlassAtPoint {
  double share = 0.0;
  Vec3d tint{0.0};
};

GlassAtPoint glass_at(const ShadingContext& context, std::uint32_t material_id, const Material& material,
                      const std::optional<TexCoords>& texcoord, const Vec3d& texel, double metallic) {
  if (!material.transmission_mix) return {1.0, Vec3d(material.transmission)};
  double share = material.transmission_factor * (1.0 - metallic);  // metals transmit nothing
  if (texcoord && context.textures && context.textures->has_transmission(material_id))
    share *= context.textures->transmission(material_id, *texcoord);
  return {std::clamp(share, 0.0, 1.0), Vec3d(material.transmission) * texel};
}

// The secondary rays of a smooth dielectric: a mirror reflection weighted by the Fresnel
// reflectance F and a refracted ray weighted by (1 - F) x tint, both one level deeper
// (docs/glass.md); on glTF's mix, glass.share of each and the opaque rest's mirror reflection.
// The geometric normal decides whether the ray enters (it arrives on the side the normal points
// to) or leaves; the shading normal, turned to the side the ray arrives from, bends it. Under
// total internal reflection F = 1 and only the reflection is traced. Rays inside a volume are
// attenuated by Beer–Lambert. `skip(rule)` counts a ray not traced.
template <class Shadows, class Skip>
void add_dielectric_rays(const ShadingContext& context, const SurfacePoint& surface, const Vec3d& normal,
                         const Vec3d& direction, const Material& material, const GlassAtPoint& glass,
                         const Vec3d& reflective, double coverage, int depth, RayCounts& counts, const Vec3d& throughput,
                         std::uint64_t path_seed, Shadows& shadows, const Skip& skip) {
  const bool entering = glm::dot(direction, surface.geometric_normal) < 0.0;
  const Vec3d facing = entering ? normal : -normal;  // shading normal on the side the ray comes from
  const double ior = double(material.ior);
  const double eta = entering ? ior : 1.0 / ior;  // n_transmitted / n_incident; outside is vacuum (1)
  const double cos_incident = -glm::dot(direction, facing);
  // A thin wall has no inside: the ray goes straight on, and both faces reflect.
  const std::optional<Vec3d> transmitted = material.thin_walled ? std::optional<Vec3d>(direction)
                                                                : refract_direction(direction, facing, eta);
  const double reflectance = material.thin_walled ? fresnel_thin_dielectric(cos_incident, ior)
                             : transmitted        ? fresnel_dielectric(cos_incident, eta)
                                                  : 1.0;
  const bool volume = !material.thin_walled;
  // `coverage`: the alpha of a blended surface (1 otherwise), weighting everything it shows.
  const Vec3d reflection_weight = coverage * (material.transmission_mix
                                                  ? glass.share * reflectance + (1.0 - glass.share) * reflective
                                                  : Vec3d(reflectance));
  const Vec3d refraction_weight = coverage * glass.share * (1.0 - reflectance) * glass.tint;  // black under TIR (F = 1)

  const EffectsOptions& options = context.plan.options;
  Vec3d radiance(0.0);
  const auto trace = [&](const Vec3d& along, const Vec3d& weight, bool inside, bool refraction) {
    const Vec3d next_throughput = throughput * weight;
    if (options.prune && weight == Vec3d(0.0))
      return skip(refraction ? SkipRule::black_refraction : SkipRule::black_reflection);
    if (options.min_throughput > 0.0 && max_channel(next_throughput) < options.min_throughput)
      return skip(SkipRule::low_throughput);
    Ray secondary;
    secondary.origin = offset_ray_origin(context.ray_offset, surface, along);
    secondary.direction = Vec3f(along);
    ++(refraction ? counts.refraction : counts.reflection);
    add_at(refraction ? counts.refraction_per_depth : counts.reflection_per_depth, std::size_t(depth) + 1);
    if (context.trace)
      note(context, depth, "  {}, weight {}{}:", refraction ? "refraction" : "reflection", format_vec(weight),
           inside ? " (inside)" : "");
    radiance += weight * (inside ? find_color_inside(context, secondary, depth + 1, counts, next_throughput, path_seed, material)
                                 : Vec3d(find_color(context, secondary, depth + 1, counts, next_throughput, path_seed)));
  };
  trace(reflect_direction(direction, facing), reflection_weight, volume && !entering, false);
  if (transmitted) trace(*transmitted, refraction_weight, volume && entering, true);
  shadows.add_reflection(radiance);
}

// The alpha of a blend material at `hit`: per texel through the scene's alpha test when the
// accel has one, else the material's constant.
double blend_coverage(const ShadingContext& context, const Material& material, const Hit& hit) {
  if (context.alpha) return context.alpha->alpha_at(hit.primitive, hit.u, hit.v);
  return std::clamp(double(material.alpha), 0.0, 1.0);
}

// shade_hit's work for a hit, with the shadow queries left to `shadows`. The batch shader
// (batch_shade.cpp) repeats this for plain materials operation for operation: change both.
template <class Shadows>
void shade_surface(const ShadingContext& context, const Ray& ray, const Hit& hit, int depth, RayCounts& counts,
                   const Vec3d& throughput, std::uint64_t path_seed, Shadows& shadows) {
  add_at(counts.hits_per_depth, std::size_t(depth));

  // Surface at the hit, world space, double. The point is interpolated from the triangle's
  // vertices (or projected onto the sphere) rather than taken as o + t d: it then lies on the
  // surface up to rounding, whatever error t carries.
  const FlatScene& flat = context.flat;
  SurfacePoint surface;
  Vec3d normal;                    // shading normal, unit length
  std::optional<TexCoords> texcoord;  // interpolated texture coordinates, when the scene has them
  if (flat.is_sphere(hit.primitive)) {
    surface = make_sphere_surface_point(flat.sphere_of(hit.primitive), Vec3d(ray.origin), Vec3d(ray.direction), hit.t);
    normal = surface.geometric_normal;
  } else {
    const Vec3u tri = flat.triangles[hit.primitive];
    const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
    const double b1 = hit.u, b2 = hit.v, b0 = 1.0 - b1 - b2;
    surface = make_surface_point(p0, p1, p2, b1, b2);
    normal = shading_normal(b0 * Vec3d(flat.normals[tri.x]) + b1 * Vec3d(flat.normals[tri.y]) +
                                b2 * Vec3d(flat.normals[tri.z]),
                            surface.geometric_normal);
    if (has_texcoords(flat)) texcoord = texcoords_at(flat, hit.primitive, float(b0), float(b1), float(b2));
  }
  const Vec3d& point = surface.point;
  const Vec3d direction = glm::normalize(Vec3d(ray.direction));
  const Vec3d to_eye = -direction;
  const std::uint32_t material_id = flat.material_of(hit.primitive);
  const Material& material = context.scene.materials[material_id];
  // Texture space, float: the diffuse texture's colour at the hit (white without one; spheres
  // carry no texture coordinates).
  const Vec3d texel = texcoord && context.textures && context.textures->has_diffuse(material_id)
                          ? Vec3d(context.textures->diffuse(material_id, *texcoord))
                          : Vec3d(1.0);
  Vec3d ambient = Vec3d(material.ambient) * texel, diffuse = Vec3d(material.diffuse) * texel;
  Vec3d specular(material.specular);
  Vec3d material_reflective(material.reflective.value_or(material.specular));
  double shininess = material.shininess;
  double metallic = 0.0;  // per hit, of a metallic-roughness material
  if (context.plan.materials[material_id].surface_maps) {
    SurfaceTerms terms{ambient, diffuse, specular, material_reflective, shininess, normal, 0.0};
    apply_surface_maps(flat, context.textures, material_id, material, hit, texcoord, texel, terms);
    ambient = terms.ambient;
    diffuse = terms.diffuse;
    specular = terms.specular;
    material_reflective = terms.reflective;
    shininess = terms.shininess;
    normal = terms.normal;
    metallic = terms.metallic;
  }
  // A two-sided surface seen from behind is lit as its front (glTF doubleSided): the shading
  // normal turns towards the viewer. The geometric normal stays as it is, for the rules that
  // need the outward side (emitters' front, the convex rule); ray origins take their side from
  // the ray's direction.
  if (material.back_face == BackFace::flipped && !material.is_dielectric() &&
      glm::dot(surface.geometric_normal, to_eye) < 0.0)
    normal = -normal;
  GlassAtPoint glass;
  if (material.is_dielectric()) {
    glass = glass_at(context, material_id, material, texcoord, texel, metallic);
    if (material.transmission_mix) {  // the opaque material covers the rest
      ambient *= 1.0 - glass.share;
      diffuse *= 1.0 - glass.share;
    }
  }
  Vec3d reflective = material_reflective;  // the mirror weight, of a blended surface too
  // A blend surface is seen with weight alpha, the ray going on through it for the rest
  // (docs/alpha.md). The see-through ray is one level deeper; with no level left the surface is
  // drawn fully.
  const double coverage = material.alpha_mode == AlphaMode::blend && material.has_alpha() &&
                                  depth < context.scene.settings.max_depth
                              ? blend_coverage(context, material, hit)
                              : 1.0;
  if (coverage < 1.0) {
    ambient *= coverage;
    diffuse *= coverage;
    specular *= coverage;
    reflective *= coverage;
  }

  if (context.trace)
    note(context, depth, "{} ray {}: hit {} {} at t = {:.9g}, point {}, shading normal {}, material {} '{}'",
       depth == 0 ? "camera" : "reflection", format_ray(ray), flat.is_sphere(hit.primitive) ? "sphere" : "triangle",
       hit.primitive, hit.t, format_vec(point), format_vec(normal), material_id, material.name);

  const EffectsPlan& plan = context.plan;
  const MaterialPlan& terms = plan.materials[material_id];
  const bool prune = plan.options.prune;
  // `light`: index of the light whose shadow ray is skipped, or -1 for the reflection ray.
  const auto skip = [&](SkipRule rule, int light) {
    ++counts.skipped[static_cast<int>(rule)];
    if (context.trace)
      note(context, depth, "  {}: not traced ({})", light < 0 ? "reflection" : fmt::format("light {}", light),
           to_string(rule));
  };
  // An emitter's radiance, else the seed's self-emission (seen from either side).
  shadows.begin(coverage * (material.emits_light ? emitted_radiance(context, material, material_id, surface, to_eye, texcoord)
                                                 : Vec3d(material.emission)));
  for (std::size_t j = 0; j < context.scene.lights.size(); ++j) {
    const Light& light = context.scene.lights[j];
    const LightPlan& light_plan = plan.lights[j];
    const int light_index = int(j);
    if (!light_plan.contributes) {
      skip(SkipRule::light_off, light_index);
      continue;
    }
    Vec3d to_light;
    Vec3d intensity = light_plan.color;
    if (light.is_directional()) {
      to_light = light_plan.to_light;
    } else {
      const Vec3d offset = Vec3d(light.position) - point;
      const double d = glm::length(offset);
      if (!(d > 0.0)) {  // a light exactly at the point has no direction
        skip(SkipRule::light_on_surface, light_index);
        continue;
      }
      to_light = offset / d;
      intensity /= light.attenuation.x + light.attenuation.y * d + light.attenuation.z * d * d;
      if (light.is_spot()) {
        const double cone = std::clamp((glm::dot(light.spot_direction, -to_light) - light.spot_cos_outer) /
                                           std::max(light.spot_cos_inner - light.spot_cos_outer, 1e-3),
                                       0.0, 1.0);
        intensity *= cone * cone;
      }
    }

    // The unshadowed term. l + v vanishes when the light is exactly behind the surface point as
    // seen from the eye; the half vector is then undefined and the highlight is taken as zero
    // (n.h = 0), not NaN.
    const Vec3d half_sum = to_light + to_eye;
    const double half_length = glm::length(half_sum);
    const double n_dot_l = std::max(glm::dot(normal, to_light), 0.0);
    const double n_dot_h = half_length > 0.0 ? std::max(glm::dot(normal, half_sum) / half_length, 0.0) : 0.0;
    // A black specular colour makes the highlight exactly zero (pow of [0, 1] is finite).
    const Vec3d highlight = terms.specular || !prune ? specular * std::pow(n_dot_h, shininess) : Vec3d(0.0);
    const Vec3d term = intensity * (ambient + diffuse * n_dot_l + highlight);

    // Exact rules first, then the opt-in approximation; the first rule that applies is counted.
    if (prune && term == Vec3d(0.0)) {
      skip(SkipRule::zero_contribution, light_index);
      continue;
    }
    if (plan.options.min_light_contribution > 0.0 && max_channel(term) < plan.options.min_light_contribution) {
      skip(SkipRule::dim_light, light_index);
      continue;
    }
    if (depth == 0 && light_plan.at_eye) {
      // From a primary hit, the segment to a light at the eye is the camera ray's own, and the
      // camera ray found nothing closer. Pruned, the shadow ray is skipped; unpruned, it retraces
      // the camera ray's float32 line up to just before the hit, so that both modes answer the
      // same question (a ray from the offset hit point can disagree with the camera ray by
      // rounding where it grazes a silhouette edge).
      if (prune) {
        skip(SkipRule::light_at_eye, light_index);
        shadows.lit(j, term);
      } else {
        Ray shadow_ray = ray;
        shadow_ray.tfar = hit.t * (1.0f - kRetraceMargin);
        shadows.query(j, term, shadow_ray);
      }
    } else if (plan.convex && glm::dot(surface.geometric_normal, to_light) > kConvexFacingMargin) {
      skip(SkipRule::convex_facing, light_index);  // the ray stays in the open half-space in front of the surface
      shadows.lit(j, term);
    } else {
      Ray shadow_ray;
      shadow_ray.origin = offset_ray_origin(context.ray_offset, surface, to_light);
      const double light_distance = light.is_directional() ? double(kInfinity)
                                                           : shadow_ray_tfar(context.ray_offset, Vec3d(shadow_ray.origin),
                                                                             Vec3d(light.position));
      if (light_distance > 0.0) {
        shadow_ray.direction = Vec3f(to_light);
        shadow_ray.tfar = static_cast<float>(light_distance);
        shadows.query(j, term, shadow_ray);
      } else {
        skip(SkipRule::light_on_surface, light_index);  // closer than the margin: nothing can be in between
        shadows.lit(j, term);
      }
    }
  }

  if (plan.area_lights)
    add_area_light_terms(context, LitSurface{surface, normal, to_eye, diffuse, specular, shininess, terms, {}},
                         depth, path_seed, counts, shadows);

  if (depth < context.scene.settings.max_depth && glass.share > 0.0) {
    add_dielectric_rays(context, surface, normal, direction, material, glass, material_reflective, coverage, depth,
                        counts, throughput, path_seed, shadows, [&](SkipRule rule) { skip(rule, -1); });
  } else if (depth < context.scene.settings.max_depth) {
    const Vec3d next_throughput = throughput * reflective;
    if (prune && (!terms.reflection || reflective == Vec3d(0.0))) {  // black here (a texel's, a blend's alpha 0)
      skip(SkipRule::black_reflection, -1);
    } else if (plan.options.min_throughput > 0.0 && max_channel(next_throughput) < plan.options.min_throughput) {
      skip(SkipRule::low_throughput, -1);
    } else {
      const Vec3d reflected = reflect_direction(direction, normal);
      Ray reflection_ray;
      reflection_ray.origin = offset_ray_origin(context.ray_offset, surface, reflected);
      reflection_ray.direction = Vec3f(reflected);
      ++counts.reflection;
      add_at(counts.reflection_per_depth, std::size_t(depth) + 1);
      if (context.trace) note(context, depth, "  reflection, weight {}:", format_vec(reflective));
      shadows.add_reflection(
          reflective * Vec3d(find_color(context, reflection_ray, depth + 1, counts, next_throughput, path_seed)));
    }
  }

  if (coverage < 1.0) {  // what lies behind a blended surface, straight on (coverage is 1 at max depth)
    Ray onward;
    onward.origin = offset_ray_origin(context.ray_offset, surface, direction);
    onward.direction = ray.direction;
    ++counts.see_through;
    add_at(counts.see_through_per_depth, std::size_t(depth) + 1);
    if (context.trace) note(context, depth, "  see-through, weight {:.6g}:", 1.0 - coverage);
    shadows.add_reflection((1.0 - coverage) * Vec3d(find_color(context, onward, depth + 1, counts,
                                                               throughput * (1.0 - coverage), path_seed)));
  }
}

}  // namespace

SkipRule emitter_zero_rule(const Emitter& emitter, const Vec3d& point, const Vec3d& normal, const MaterialPlan& terms) {
  if (!terms.diffuse && !terms.specular) return SkipRule::unlit_material;
  if (!in_front_of_emitter(emitter, point)) return SkipRule::emitter_behind;
  if (emitter_below_horizon(emitter, point, normal)) return SkipRule::emitter_below_horizon;
  return SkipRule::sample_zero;
}

void record_area_light_terms(const ShadingContext& context, const LitSurface& lit, int depth, std::uint64_t path_seed,
                             RayCounts& counts, ShadowRecorder& recorder) {
  add_area_light_terms(context, lit, depth, path_seed, counts, recorder);
}

void trace_area_light_terms(const ShadingContext& context, const LitSurface& lit, int depth, std::uint64_t path_seed,
                            RayCounts& counts, Vec3d& radiance) {
  ImmediateShadows shadows{context, counts, depth, radiance};
  add_area_light_terms(context, lit, depth, path_seed, counts, shadows);
  radiance = shadows.radiance;
}

Color shade_hit(const ShadingContext& context, const Ray& ray, const Hit& hit, int depth, RayCounts& counts,
                const Vec3d& throughput, std::uint64_t path_seed) {
  if (!hit.found()) {
    if (context.trace)
      note(context, depth, "{} ray {}: miss, background {}", depth == 0 ? "camera" : "reflection", format_ray(ray),
           format_vec(Vec3d(context.scene.settings.background)));
    return context.scene.settings.background;
  }
  ImmediateShadows shadows{context, counts, depth};
  shade_surface(context, ray, hit, depth, counts, throughput, path_seed, shadows);
  if (context.trace) note(context, depth, "  colour {}", format_vec(shadows.radiance));
  return Color(shadows.radiance);
}

void PendingShading::clear() {
  pixels.clear();
  terms.clear();
  shadow_rays.clear();
  shadow_lights.clear();
}

void shade_camera_hit(const ShadingContext& context, const Ray& ray, const Hit& hit, std::uint64_t path_seed,
                      RayCounts& counts, PendingShading& pending) {
  DeferredShadows shadows{{pending, counts, context.scene.lights.size()}};
  if (hit.found()) {
    shade_surface(context, ray, hit, 0, counts, Vec3d(1.0), path_seed, shadows);
    shadows.pixel.term_count = static_cast<std::uint32_t>(pending.terms.size()) - shadows.pixel.first_term;
  } else {
    shadows.pixel.emission = Vec3d(context.scene.settings.background);
  }
  pending.pixels.push_back(shadows.pixel);
}

}  // namespace rt
