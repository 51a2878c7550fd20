#pragma once
// FindColor: the seed's Phong / Blinn-Phong shading with shadow rays and recursive mirror
// reflection, on top of either Accel backend.

#include <cstdint>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/render/ray_offset.h"
#include "rt/render/texture.h"
#include "rt/scene/scene.h"

namespace rt {

// Rays traced, per kind. Each render thread owns one; they are summed afterwards.
struct RayCounts {
  std::uint64_t camera = 0;
  std::uint64_t shadow = 0;
  std::uint64_t reflection = 0;

  std::uint64_t total() const { return camera + shadow + reflection; }
  RayCounts& operator+=(const RayCounts& other);
};

// Everything FindColor reads. All references must outlive the shader; it is cheap to copy and
// thread-safe to use from many threads (each with its own RayCounts).
struct ShadingContext {
  const Scene& scene;      // materials, lights, settings (max_depth, background)
  const FlatScene& flat;   // world-space geometry the accel was built on
  const Accel& accel;
  RayOffset ray_offset{};  // self-intersection policy of shadow and reflection rays
  const TextureSampler* textures = nullptr;  // diffuse textures; nullptr: materials' textures are ignored
};

// The seed's FindColor for a ray whose origin and direction are world space:
//   R = E + sum_j V_j L_j (C_ambient + C_diffuse max(n.l_j, 0) + C_specular max(n.h_j, 0)^sigma)
//       + C_reflective FindColor(reflected ray)
// where C_reflective is Material::reflective when set, else C_specular (the seed's formula); an
// explicitly zero C_reflective traces no reflection ray.
// with Blinn-Phong half vectors h_j = normalize(l_j + v), V_j the 0/1 shadow-ray visibility and
// L_j the light colour divided by the point-light attenuation (and scaled by the spot falloff).
// C_diffuse and C_ambient are multiplied by the material's diffuse texture at the hit; the
// reflection is weighted by Material::reflective when set instead of C_specular. depth 0 is the primary hit; the
// reflection recurses while depth < max_depth. A miss returns settings.background.
// Computed in double, returned as float32 linear RGB.
Color find_color(const ShadingContext& context, const Ray& ray, int depth, RayCounts& counts);

}  // namespace rt
