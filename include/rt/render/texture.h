#pragma once
// Texture lookups for shading: PNG and JPEG decoded by rt, other formats through OpenImageIO.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "rt/core/math.h"
#include "rt/scene/scene.h"

namespace rt {

// What a material's texture is for, which says how its texels are read: colour maps hold sRGB
// values, decoded to linear after filtering; data maps are read as stored.
enum class TextureRole : std::uint8_t {
  diffuse,             // colour: Material::diffuse_texture
  emission,            // colour: emission_texture (emitters only)
  transmission,        // data, red: transmission_texture (glTF glass only)
  metallic_roughness,  // data, green roughness and blue metallic: MetallicRoughness::texture
  normal,              // data: normal_texture, a tangent-space normal per texel
  occlusion,           // data, red: occlusion_texture
  specular,            // colour: specular_texture
  shininess,           // data, first channel: shininess_texture
  bump,                // data, first channel: bump_texture, a height map
};
inline constexpr int kTextureRoleCount = 9;

// Material `m`'s texture for `role` when the shader reads it (emission only for emitters,
// transmission only for glTF glass), else null; it may be empty.
const Texture* texture_for(const Material& m, TextureRole role);

// How a TextureSampler samples its textures.
struct TextureUse {
  int decoded = 0;                 // distinct PNG and JPEG images rt decodes itself, each on its first lookup
  int through_oiio = 0;            // lookups (material and role) sampled through OpenImageIO
  std::uint64_t decoded_bytes = 0; // what the PNG and JPEG images take decoded
  std::uint64_t budget_bytes = 0;  // the texture cache's size (--texture-cache)
  bool tiled = false;  // decoded_bytes > budget_bytes: every texture goes through OpenImageIO's tiled cache, bounded by the budget
};

// The textures of a scene's materials, ready to sample from many threads at once. Lookups are
// bilinear on the full-resolution image with no derivatives and no MIP-mapping: a Whitted
// renderer traces one ray per pixel, so there is no footprint to filter over. Each texture is
// looked up at its own coordinate set and transform (Texture::lookup_uv).
class TextureSampler {
 public:
  // Opens every material's textures (those the shader reads: emission only for emitters,
  // transmission only for glTF glass). Embedded (encoded) images are written to a private
  // temporary directory, removed again by the destructor. A texture that cannot be read samples
  // as if absent (loaders check readability and report it; see load_gltf.h).
  // PNG and JPEG textures are decoded by rt (rt/io/decode_image.h), once per process while they
  // stay in the cache of `cache_bytes` (0: half the available memory); other formats, and every
  // texture when the PNG and JPEG ones would not fit, are sampled through OpenImageIO's
  // TextureSystem, whose tiled cache is then bounded by `cache_bytes`.
  explicit TextureSampler(const Scene& scene, std::uint64_t cache_bytes = 0);
  ~TextureSampler();
  TextureSampler(const TextureSampler&) = delete;
  TextureSampler& operator=(const TextureSampler&) = delete;

  const TextureUse& use() const;

  // True when material `material` has a texture for `role`.
  bool has(std::uint32_t material, TextureRole role) const;

  // The first three channels of material `material`'s `role` texture at a point with
  // coordinates `uv`, with the texture's wrap modes: linear RGB for colour roles (sRGB decoded
  // after filtering), as stored for data roles. White (1, 1, 1) when there is no such texture or
  // the lookup fails.
  Vec3f sample(std::uint32_t material, TextureRole role, const TexCoords& uv) const;

  // The roles the shader's fast path reads.
  bool has_diffuse(std::uint32_t material) const { return has(material, TextureRole::diffuse); }
  Color diffuse(std::uint32_t material, const TexCoords& uv) const { return sample(material, TextureRole::diffuse, uv); }
  bool has_emission(std::uint32_t material) const { return has(material, TextureRole::emission); }
  Color emission(std::uint32_t material, const TexCoords& uv) const { return sample(material, TextureRole::emission, uv); }
  bool has_transmission(std::uint32_t material) const { return has(material, TextureRole::transmission); }
  float transmission(std::uint32_t material, const TexCoords& uv) const {
    return sample(material, TextureRole::transmission, uv).r;
  }

 private:
  struct Impl;  // keeps OpenImageIO out of this header
  std::unique_ptr<Impl> impl_;
};

// Whether `texture` (a file, or the embedded bytes) opens as an image: a PNG or JPEG by its header
// (rt's decoder), another format by OpenImageIO. On failure `reason` says why.
bool texture_is_readable(const Texture& texture, std::string& reason);

// Mean of the first four channels of `texture` over all its pixels, as stored in the file (no
// sRGB decoding), grey replicated to RGB and alpha 1 where the image has none; nullopt if it
// cannot be read. Loaders use it to stand in for textures shading does not sample.
std::optional<Vec4f> texture_mean(const Texture& texture);

}  // namespace rt
