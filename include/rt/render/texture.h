#pragma once
// Texture lookups for shading, through one OpenImageIO TextureSystem per render.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "rt/core/math.h"
#include "rt/scene/scene.h"

namespace rt {

// The diffuse and emission textures of a scene's materials, ready to sample from many threads at once.
// Lookups are bilinear on the full-resolution image with no derivatives and no MIP-mapping: a
// Whitted renderer traces one ray per pixel, so there is no footprint to filter over.
class TextureSampler {
 public:
  // Opens every material's diffuse_texture, emitters' emission_texture and glTF glass's
  // transmission_texture. Embedded (encoded) images are written to a private
  // temporary directory, removed again by the destructor. A texture that cannot be read samples
  // as white (loaders check readability and report it; see load_gltf.h).
  explicit TextureSampler(const Scene& scene);
  ~TextureSampler();
  TextureSampler(const TextureSampler&) = delete;
  TextureSampler& operator=(const TextureSampler&) = delete;

  // True when material `material` has a diffuse texture.
  bool has_diffuse(std::uint32_t material) const;

  // Linear RGB of material `material`'s diffuse texture at texture coordinates `uv` (see Texture),
  // with the material's wrap modes; sRGB texel values are decoded after filtering. White when the
  // material has no texture or the lookup fails.
  Color diffuse(std::uint32_t material, Vec2f uv) const;

  // The same for the emission texture of emitter material `material` (Material::emits_light).
  bool has_emission(std::uint32_t material) const;
  Color emission(std::uint32_t material, Vec2f uv) const;

  // The red channel of material `material`'s transmission texture (Material::transmission_mix),
  // linear, at `uv`; 1 without one or when the lookup fails.
  bool has_transmission(std::uint32_t material) const;
  float transmission(std::uint32_t material, Vec2f uv) const;

 private:
  struct Impl;  // keeps OpenImageIO out of this header
  std::unique_ptr<Impl> impl_;
};

// Whether OpenImageIO can open `texture` (a file, or the embedded bytes) as an image; on failure
// `reason` says why.
bool texture_is_readable(const Texture& texture, std::string& reason);

// Mean of the first four channels of `texture` over all its pixels, as stored in the file (no
// sRGB decoding), grey replicated to RGB and alpha 1 where the image has none; nullopt if it
// cannot be read. Loaders use it to stand in for textures shading does not sample.
std::optional<Vec4f> texture_mean(const Texture& texture);

}  // namespace rt
