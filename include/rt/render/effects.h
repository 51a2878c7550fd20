#pragma once
// The effects plan: which parts of FindColor a scene can need (lights, shadow rays, reflection
// rays, shading terms), decided once after flattening, and the per-hit rules that skip rays whose
// result cannot change the image. Exact rules are on by default; approximations are opt-in.

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "rt/flatten/flatten.h"
#include "rt/render/area_lights.h"
#include "rt/render/ray_offset.h"
#include "rt/scene/scene.h"

namespace rt {

// What the renderer may skip. The exact rules never change the image (tests render every scene
// both ways and compare bytes); the two thresholds trade a documented error for rays.
struct EffectsOptions {
  bool prune = true;  // false: every shadow and reflection ray is traced (--no-prune)
  // Approximation: no reflection ray where the path's throughput (product of the reflective
  // colours so far, largest channel, times the reflective colour at this hit) is below this.
  // Error per pixel <= min_throughput * EffectsPlan::radiance_bound. 0 = off.
  double min_throughput = 0.0;
  // Approximation: a light whose unshadowed contribution at a hit (largest channel) is below this
  // is dropped there, without a shadow ray. Error per pixel <= min_light_contribution * lights *
  // EffectsPlan::path_weight_bound. 0 = off.
  double min_light_contribution = 0.0;
  // Area lights (emissive triangles): shadow-ray samples per emitter per hit, and how each picks
  // its point (docs/area-lights.md).
  int light_samples = kDefaultLightSamples;
  LightSampling light_sampling = LightSampling::automatic;

  static constexpr int kDefaultLightSamples = 16;
  static constexpr int kMaxLightSamples = 1 << 16;
};

// Why a shadow or reflection ray was not traced, one counter per rule (RayCounts::skipped).
enum class SkipRule : int {
  light_off,          // exact: the light contributes nothing anywhere (black, zero-width cone)
  zero_contribution,  // exact: its unshadowed term is exactly zero at this hit (e.g. n.l <= 0, no ambient/specular)
  light_at_eye,       // exact: primary hit and the light is at the camera eye (the camera ray's own segment)
  convex_facing,      // exact: the scene is one convex object and the surface faces the light
  light_on_surface,   // always: the light is closer than the offset margin (nothing in between)
  black_reflection,   // exact: the reflection weight is black
  black_refraction,   // exact: a dielectric's refraction weight is black here (e.g. an opaque texel of glTF glass)
  dim_light,          // approximation: the light's term is below min_light_contribution
  low_throughput,     // approximation: the path's throughput is below min_throughput
  // Area-light samples (one count per sample, so an emitter skipped at a hit counts light_samples):
  emitter_off,            // exact: the emitter lights nothing anywhere (no material can reflect its light)
  unlit_material,         // exact: the hit's material has no diffuse or specular colour
  emitter_behind,         // exact: the point is on or behind a planar one-sided emitter
  emitter_below_horizon,  // exact: the whole emitter is on or below the surface's tangent plane
  sample_zero,            // exact: the sample's unshadowed term is zero (triangle's back, n.l <= 0, black texel)
  sample_on_surface,      // always: no direction to the sample, or it is closer than the offset margin
};
// The number of rules, the size of every per-rule array: sample_on_surface must stay the last. (It
// was once 14, one short: GCC 14's -Warray-bounds found the count of sample_on_surface written
// past RayCounts::skipped.)
inline constexpr int kSkipRuleCount = static_cast<int>(SkipRule::sample_on_surface) + 1;
std::string to_string(SkipRule rule);

// One light as the shader uses it: constants hoisted out of the per-hit loop (world space, double).
struct LightPlan {
  bool contributes = true;  // false: no term and no shadow ray anywhere
  bool at_eye = false;      // point light exactly at the camera eye
  std::string why;          // one phrase: why it is on/off, which shadow rules apply
  Vec3d color{0.0};         // linear RGB
  Vec3d to_light{0.0};      // directional lights: unit direction towards the light
};

// One emitter of EffectsPlan::area_lights as the shader uses it.
struct EmitterPlan {
  bool contributes = true;  // false: no sample anywhere (SkipRule::emitter_off)
  std::string why;          // one phrase: its size and power, why it is on/off, which rules apply
};

// Which terms of FindColor a material can produce (a term whose colour is black is zero).
struct MaterialPlan {
  bool ambient = false;
  bool diffuse = false;
  bool specular = false;
  bool reflection = false;  // its reflection weight (Material::reflective, else specular; glass: Fresnel) is not black
  bool refraction = false;  // a dielectric (Material::is_dielectric): refracted rays are traced
  bool surface_maps = false;  // its hits run apply_surface_maps (needs_surface_maps, rt/render/surface_maps.h)
};

// The plan for one scene and one set of options; built by plan_effects, read by find_color.
struct EffectsPlan {
  EffectsOptions options;
  std::vector<LightPlan> lights;        // parallel to Scene::lights
  std::vector<MaterialPlan> materials;  // parallel to Scene::materials
  // The scene's emitters (null when it has none) and what the shader does with each.
  std::shared_ptr<const AreaLights> area_lights;
  std::vector<EmitterPlan> emitters;    // parallel to area_lights->emitters
  bool shadows = false;                 // some shadow ray can be traced
  // The whole scene is one convex object with outward normals, so a surface point whose geometric
  // normal faces the light cannot be shadowed (needs robust ray offsets, see plan_effects).
  bool convex = false;
  std::string convex_why;
  bool reflections = false;             // some reflection ray can be traced
  // Deepest ray that can matter: the scene's max_depth when some material reflects, else 0 (primary
  // hits only).
  int useful_depth = 0;
  // Upper bounds used by the approximations' error bounds (linear RGB, +inf when unbounded, e.g. a
  // point light without constant attenuation, or any area light, whose Monte Carlo estimates have no
  // a-priori bound): the largest radiance find_color can return, and the
  // largest sum over a path of the products of reflection weights (1 + r + r^2 + ... to the depth).
  double radiance_bound = 0.0;
  double path_weight_bound = 0.0;

  // Largest error per pixel and channel (linear RGB) the enabled approximations can introduce; 0 when off.
  double approximation_error_bound() const;
};

// Decides the plan after loading and flattening. `ray_offset` matters because the convex rule
// argues about the half-space a shadow ray stays in, which holds for the traced ray only when its
// origin cannot fall behind the surface: it is used with robust offsets only.
// `textures` (optional) steers the area lights' samples towards the bright parts of emission
// textures (collect_area_lights); it changes the noise, not the expected image.
EffectsPlan plan_effects(const Scene& scene, const FlatScene& flat, const RayOffset& ray_offset,
                         const EffectsOptions& options, const TextureSampler* textures = nullptr);

// The plan as short human-readable lines (rt info, --explain).
std::vector<std::string> describe_plan(const EffectsPlan& plan, const Scene& scene);

// True when every vertex of the triangles lies on or behind every triangle's plane (geometric
// normal (p1 - p0) x (p2 - p0)) for certain: each orientation test is decided by a double-precision
// determinant and Shewchuk's error bound, and an undecided one counts as not convex. Empty: false.
bool is_convex_for_certain(const FlatScene& flat);

}  // namespace rt
