#pragma once
// FindColor: the seed's Phong / Blinn-Phong shading with shadow rays and recursive mirror
// reflection, on top of either Accel backend.

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/render/effects.h"
#include "rt/render/ray_offset.h"
#include "rt/render/texture.h"
#include "rt/scene/scene.h"

namespace rt {

class SceneAlpha;  // rt/render/alpha.h

// The ray budget: rays traced per kind, hits, rays skipped per rule and, when timing is on, the
// time spent in intersection queries. Each render thread owns one; they are summed afterwards.
// Per-depth and per-light vectors grow on demand (depth d: 0 = camera rays, d >= 1 = reflections).
struct RayCounts {
  std::uint64_t camera = 0;
  std::uint64_t shadow = 0;      // towards point, spot and directional lights
  std::uint64_t reflection = 0;
  std::uint64_t refraction = 0;  // transmitted through dielectrics
  std::uint64_t see_through = 0;  // on through blended (alpha) surfaces, unbent
  std::uint64_t area_light = 0;  // shadow rays towards samples on emitters
  std::vector<std::uint64_t> shadow_per_light;      // [j]: shadow rays traced towards light j
  std::vector<std::uint64_t> area_light_per_emitter;  // [e]: shadow rays towards samples of emitter e
  std::vector<std::uint64_t> reflection_per_depth;  // [d]: reflection rays of depth d (index 0 unused)
  std::vector<std::uint64_t> refraction_per_depth;  // [d]: refraction rays of depth d (index 0 unused)
  std::vector<std::uint64_t> see_through_per_depth;  // [d]: see-through rays of depth d (index 0 unused)
  std::vector<std::uint64_t> hits_per_depth;        // [d]: rays of depth d that hit a surface
  std::array<std::uint64_t, kSkipRuleCount> skipped{};  // [SkipRule]: rays not traced, per rule
  // Timestamp-counter ticks (ShadingContext::time_queries only): closest-hit queries per ray depth,
  // shadow queries per light, and the whole find_color of the timed pixels (set by render_image);
  // only ratios of these are meaningful.
  std::vector<std::uint64_t> intersect_ticks_per_depth;
  std::vector<std::uint64_t> shadow_ticks_per_light;
  std::vector<std::uint64_t> area_light_ticks_per_emitter;
  std::uint64_t loop_ticks = 0;

  std::uint64_t total() const { return camera + shadow + reflection + refraction + see_through + area_light; }
  // Counts `amount` shadow queries towards light slot `slot` (`ticks` of one when timed): slots
  // 0 .. light_count - 1 are Scene::lights, the next ones the emitters of EffectsPlan::area_lights.
  void add_shadow_query(std::size_t light_count, std::size_t slot, std::uint64_t amount = 1) {  // inline: per ray
    const bool point = slot < light_count;
    std::vector<std::uint64_t>& per = point ? shadow_per_light : area_light_per_emitter;
    const std::size_t index = point ? slot : slot - light_count;
    (point ? shadow : area_light) += amount;
    if (per.size() <= index) per.resize(index + 1, 0);
    per[index] += amount;
  }
  void add_shadow_ticks(std::size_t light_count, std::size_t slot, std::uint64_t ticks);
  std::uint64_t skipped_total() const;
  RayCounts& operator+=(const RayCounts& other);
};

// Everything FindColor reads. All references must outlive the shader; it is cheap to copy and
// thread-safe to use from many threads (each with its own RayCounts).
struct ShadingContext {
  const Scene& scene;      // materials, lights, settings (max_depth, background)
  const FlatScene& flat;   // world-space geometry the accel was built on
  const Accel& accel;
  const EffectsPlan& plan;  // what to skip; must come from plan_effects for this scene and ray_offset
  RayOffset ray_offset{};   // self-intersection policy of shadow and reflection rays
  const TextureSampler* textures = nullptr;  // diffuse textures; nullptr: materials' textures are ignored
  bool time_queries = false;  // fill RayCounts' tick counters (costs two timestamp reads per query)
  // When set, find_color appends a line per ray, light and result (the --debug-pixel trace);
  // single-threaded use only.
  std::vector<std::string>* trace = nullptr;
  // The scene's alpha (the accel's AlphaTest, rt/render/alpha.h): blended surfaces' alpha per
  // texel. Null: a blend material's constant alpha.
  const SceneAlpha* alpha = nullptr;
};

// The seed's FindColor for a ray whose origin and direction are world space:
//   R = E + sum_j V_j L_j (C_ambient + C_diffuse max(n.l_j, 0) + C_specular max(n.h_j, 0)^sigma)
//       + sum_e (1 / (pi N)) sum_k V_k L_e,k / pdf_k (C_diffuse (n.l_k) + C_specular max(n.h_k, 0)^sigma)
//       + C_reflective FindColor(reflected ray)
// the middle sum over emitters e and their N light samples k where n.l_k > 0 (area_lights.h;
// docs/area-lights.md), E the emission (an emitter's only from its front side)
// where C_reflective is Material::reflective when set, else C_specular (the seed's formula); an
// explicitly zero C_reflective traces no reflection ray.
// with Blinn-Phong half vectors h_j = normalize(l_j + v), V_j the 0/1 shadow-ray visibility and
// L_j the light colour divided by the point-light attenuation (and scaled by the spot falloff).
// C_diffuse and C_ambient are multiplied by the material's diffuse texture at the hit; the
// reflection is weighted by Material::reflective when set instead of C_specular. depth 0 is the
// primary hit (`ray` must then start at the camera eye: a light there retraces it); the
// reflection recurses while depth < max_depth. A miss returns settings.background.
// Rays the plan's rules skip are not traced (counted in RayCounts::skipped); the exact rules leave
// the result bit-identical. `throughput` (linear RGB) is the product of the reflection weights
// that lead to this ray, read only by the min_throughput approximation. `path_seed` makes the
// light samples of this path (render_image: pixel_path_seed of the pixel and camera sample).
// Computed in double, returned as float32 linear RGB.
Color find_color(const ShadingContext& context, const Ray& ray, int depth, RayCounts& counts,
                 const Vec3d& throughput = Vec3d(1.0), std::uint64_t path_seed = 0);

// Camera hits of neighbouring pixels whose shadow rays are traced together (render_image's blocks):
// shade_camera_hit records a pixel's unshadowed light terms and shadow rays, the caller answers
// every shadow ray (Accel::occluded_coherent), and finish_camera_hit sums each pixel's terms in
// the order shade_hit does, so the colour is bit for bit shade_hit's at depth 0. Buffers are
// reused across blocks (clear()), so no allocation per ray once they have grown.
struct PendingShading {
  static constexpr std::uint32_t kNoQuery = 0xFFFFFFFFu;
  struct Term {
    Vec3d term;                 // linear RGB, the light's unshadowed contribution
    std::uint32_t query = kNoQuery;  // index in shadow_rays; kNoQuery: added without a query
  };
  struct Pixel {
    Vec3d emission{0.0};        // the material's emission, or the background on a miss
    Vec3d reflection{0.0};      // the reflection term, added last when has_reflection
    bool has_reflection = false;
    std::uint32_t first_term = 0, term_count = 0;  // this pixel's range in terms
  };
  std::vector<Pixel> pixels;          // in shade_camera_hit's call order
  std::vector<Term> terms;
  std::vector<Ray> shadow_rays;       // world space, as shade_hit would trace them
  std::vector<std::uint32_t> shadow_lights;  // the light slot of each shadow ray (see RayCounts::add_shadow_query)
  void clear();
};

// Appends the camera ray `ray`'s pixel (closest hit `hit`) to `pending`; counts as shade_hit
// does at depth 0 (shadow rays counted when recorded; their ticks are the caller's). Reflection
// rays are traced at once, one by one.
void shade_camera_hit(const ShadingContext& context, const Ray& ray, const Hit& hit, std::uint64_t path_seed,
                      RayCounts& counts, PendingShading& pending);

// The colour of pending pixel `pixel`; blocked[i] answers pending.shadow_rays[i] (1: occluded).
// Inline: render_image calls it once per pixel.
inline Color finish_camera_hit(const PendingShading& pending, std::size_t pixel, std::span<const std::uint8_t> blocked) {
  const PendingShading::Pixel& p = pending.pixels[pixel];
  Vec3d radiance = p.emission;
  for (std::uint32_t i = p.first_term; i < p.first_term + p.term_count; ++i) {
    const PendingShading::Term& t = pending.terms[i];
    if (t.query == PendingShading::kNoQuery || !blocked[t.query]) radiance += t.term;
  }
  if (p.has_reflection) radiance += p.reflection;
  return Color(radiance);
}

// find_color for a ray whose closest hit `hit` is already known (camera rays traced together by
// Accel::intersect_coherent): the same colour, the same counts except the closest-hit query's ticks.
Color shade_hit(const ShadingContext& context, const Ray& ray, const Hit& hit, int depth, RayCounts& counts,
                const Vec3d& throughput = Vec3d(1.0), std::uint64_t path_seed = 0);

// The seed of the light samples of camera sample `sample` of pixel (x, y): a hash, so that an
// image does not depend on thread count, tile order or region.
std::uint64_t pixel_path_seed(int x, int y, int sample);

}  // namespace rt
