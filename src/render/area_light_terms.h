#pragma once
// The area lights' terms at a hit (shade.cpp's add_area_light_terms), for shade_surface and the
// batch shader (batch_shade.cpp): what they read of the surface and the two ways their shadow
// queries go.

#include <cstdint>
#include <span>

#include "rt/render/area_lights.h"
#include "rt/render/ray_offset.h"
#include "rt/render/sampling.h"
#include "rt/render/shade.h"
#include "shadow_records.h"

namespace rt {

// What the area-light terms at a hit read: the surface (world space, double) and its colours.
struct LitSurface {
  const SurfacePoint& surface;
  const Vec3d& normal;   // shading normal, unit
  const Vec3d& to_eye;   // unit, towards the ray's origin
  const Vec3d& diffuse;  // C_d, texture applied
  const Vec3d& specular;
  double shininess;
  const MaterialPlan& terms;
  // Per emitter e < spherical.size(): its first triangles' spherical triangles seen from the point
  // (EmitterSampler's `spherical`), or nullptr to set them up when needed.
  std::span<const SphericalTriangle* const> spherical;
};

// The emitter-level rule that makes every term of `emitter` zero at a point with shading normal
// `normal` (world space) of a material with `terms`: unlit_material, emitter_behind or
// emitter_below_horizon, checked in that order; sample_zero when none applies. Pruned, no sample
// of the emitter is drawn where one applies.
SkipRule emitter_zero_rule(const Emitter& emitter, const Vec3d& point, const Vec3d& normal, const MaterialPlan& terms);

// The area lights' terms at a camera hit (depth 0) or deeper hit, recorded in `recorder` with their
// shadow rays, as shade_camera_hit records them.
void record_area_light_terms(const ShadingContext& context, const LitSurface& lit, int depth, std::uint64_t path_seed,
                             RayCounts& counts, ShadowRecorder& recorder);

// The same terms with each shadow ray traced at once, the unblocked ones added to `radiance` one by
// one in shade_hit's order (so the sum has shade_hit's bits).
void trace_area_light_terms(const ShadingContext& context, const LitSurface& lit, int depth, std::uint64_t path_seed,
                            RayCounts& counts, Vec3d& radiance);

}  // namespace rt
