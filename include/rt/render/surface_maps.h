#pragma once
// The per-hit maps of a material (Material::has_surface_maps) and the mesh's vertex colours:
// metallic-roughness mapped to Blinn-Phong per texel, occlusion, specular and shininess maps,
// and normal or bump maps bending the shading normal (docs/scene-formats.md, "Texture maps").
// Kept out of shade.cpp's fast path: a scene without them runs the shader as before.

#include <cstdint>
#include <optional>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/render/texture.h"
#include "rt/scene/scene.h"

namespace rt {

// The terms shade_surface lights with: linear RGB colours and the shading normal (world space,
// unit, double).
struct SurfaceTerms {
  Vec3d ambient{0.0};
  Vec3d diffuse{0.0};
  Vec3d specular{0.0};
  Vec3d reflective{0.0};  // the mirror reflection's weight
  double shininess = 1.0;
  Vec3d normal{0.0, 0.0, 1.0};
  double metallic = 0.0;  // a metallic-roughness material's metallic at the hit (0 otherwise)
};

// Whether apply_surface_maps changes anything for `material` in a scene flattened to `flat`.
inline bool needs_surface_maps(const FlatScene& flat, const Material& material) {
  return material.has_surface_maps() || !flat.colors.empty();
}

// Updates `terms`, which hold the material's constant terms with the diffuse texture's colour
// `texel` applied (diffuse and ambient), for hit `hit` on triangle hit.primitive of material
// `material_id`: vertex colours multiply the base colour; a metallic-roughness material's terms
// are remapped from its factors x textures; occlusion scales the ambient term; specular and
// shininess maps scale theirs; a normal map (with the mesh's tangents) or a bump map bends the
// normal. `textures` may be null (maps ignored); `texcoord` is null when the scene has none.
void apply_surface_maps(const FlatScene& flat, const TextureSampler* textures, std::uint32_t material_id,
                        const Material& material, const Hit& hit, const std::optional<TexCoords>& texcoord,
                        const Vec3d& texel, SurfaceTerms& terms);

// The shading normal of a tangent-space normal map texel `texel` (as stored, in [0, 1]) scaled by
// `scale` (glTF normalTexture.scale), in the frame of interpolated normal `normal` and tangent
// `tangent` (world space, not normalised, as MikkTSpace's pixel shader takes them) with
// handedness `sign`: normalize(x T + y B + z N), B = sign x cross(N, T). Unit, world space.
Vec3d normal_from_map(const Vec3d& texel, double scale, const Vec3d& normal, const Vec3d& tangent, double sign);

}  // namespace rt
