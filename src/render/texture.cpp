#include "rt/render/texture.h"

#include <stdlib.h>  // mkdtemp

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "io/oiio_module.h"
#include "render/texture_cache.h"
#include "rt/core/memory.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

// The sRGB transfer function's inverse (IEC 61966-2-1), per channel.
float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// Whether `role`'s texels are sRGB-encoded colours.
bool is_colour(TextureRole role) {
  return role == TextureRole::diffuse || role == TextureRole::emission || role == TextureRole::specular;
}

}  // namespace

struct TextureSampler::Impl {
  struct Lookup {
    const DecodedTexture* decoded = nullptr;  // held in `decoded`; else
    int slot = -1;                            // in `files`; both unset: none
    Texture texture;  // its wraps, coordinate set and transform (Texture::lookup_uv), without the bytes
  };
  std::vector<std::shared_ptr<const DecodedTexture>> decoded;  // what `lookups` point into
  std::unique_ptr<TextureFiles> files;  // OpenImageIO's, for other formats or over the budget; else null
  std::vector<std::array<Lookup, kTextureRoleCount>> lookups;  // per material and role
  // Per material: whether its textures' decoding has been started (prefetch).
  std::unique_ptr<std::atomic<bool>[]> prefetched;
  fs::path temp_dir;                    // empty unless an embedded image needed a file
  TextureUse use;

  ~Impl() {
    files.reset();  // closes the files before they are removed
    std::error_code ignored;
    if (!temp_dir.empty()) fs::remove_all(temp_dir, ignored);
  }

  // A file holding the embedded image `bytes`, written once per distinct buffer.
  std::string file_for(const std::shared_ptr<const std::string>& bytes, std::map<const std::string*, std::string>& written) {
    if (auto it = written.find(bytes.get()); it != written.end()) return it->second;
    if (temp_dir.empty()) {
      std::string pattern = (fs::temp_directory_path() / "rt_textures_XXXXXX").string();
      if (!mkdtemp(pattern.data())) return "";
      temp_dir = pattern;
    }
    const std::string path = (temp_dir / (std::to_string(written.size()) + encoded_image_extension(*bytes))).string();
    std::ofstream(path, std::ios::binary).write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
    return written[bytes.get()] = path;
  }

  // Opens `texture` in OpenImageIO's TextureSystem, as slot of `lookup`.
  void open_in_oiio(const Texture& texture, Lookup& lookup, std::map<const std::string*, std::string>& written) {
    std::error_code error;
    if (!texture.encoded && !fs::is_regular_file(texture.path, error)) return;  // samples as absent
    if (!files) files = oiio_module().new_texture_files(use.tiled ? use.budget_bytes : 0);
    const std::string path = texture.encoded ? file_for(texture.encoded, written) : texture.path;
    if (!path.empty()) lookup.slot = files->open(path, texture.wrap_s, texture.wrap_t);
    if (lookup.slot >= 0) ++use.through_oiio;
  }

  // On the first lookup of a texture of `material`, decodes all of the material's pending
  // textures in parallel (the render's other threads join in) and returns when they are done:
  // the hit that needs one needs the others next, and decoding them one after the other on one
  // thread would hold up the first tile (time to first pixel). Isolated, so that this thread
  // runs only these decodes while it waits, not another tile.
  void prefetch(std::uint32_t material) {
    if (prefetched[material].exchange(true)) return;
    std::vector<const DecodedTexture*> pending;
    for (const Lookup& lookup : lookups[material])
      if (lookup.decoded && lookup.decoded->pending()) pending.push_back(lookup.decoded);
    tbb::this_task_arena::isolate([&] {
      tbb::parallel_for(std::size_t(0), pending.size(), [&](std::size_t i) { pending[i]->image(); });
    });
  }

  const Lookup* find(std::uint32_t material, TextureRole role) const {
    if (material >= lookups.size()) return nullptr;
    const Lookup& lookup = lookups[material][static_cast<std::size_t>(role)];
    return lookup.decoded || lookup.slot >= 0 ? &lookup : nullptr;
  }
};

const Texture* texture_for(const Material& m, TextureRole role) {
  switch (role) {
    case TextureRole::diffuse: return &m.diffuse_texture;
    case TextureRole::emission: return m.emits_light ? &m.emission_texture : nullptr;
    case TextureRole::transmission: return m.is_dielectric() && m.transmission_mix ? &m.transmission_texture : nullptr;
    case TextureRole::metallic_roughness: return m.metallic_roughness ? &m.metallic_roughness->texture : nullptr;
    case TextureRole::normal: return &m.normal_texture;
    case TextureRole::occlusion: return m.ambient != Color(0.0f) ? &m.occlusion_texture : nullptr;  // it scales ambient
    case TextureRole::specular: return &m.specular_texture;
    case TextureRole::shininess: return &m.shininess_texture;
    case TextureRole::bump: return &m.bump_texture;
  }
  return nullptr;
}

TextureSampler::TextureSampler(const Scene& scene, std::uint64_t cache_bytes) : impl_(std::make_unique<Impl>()) {
  Impl& impl = *impl_;
  impl.lookups.resize(scene.materials.size());
  impl.prefetched = std::make_unique<std::atomic<bool>[]>(scene.materials.size());
  impl.use.budget_bytes = cache_bytes ? cache_bytes : available_memory_bytes() / 2;
  // PNG and JPEG textures are decoded by rt itself (rt/io/decode_image.h) when all of them fit in
  // the budget; otherwise OpenImageIO's tiled cache, bounded by it, samples every texture.
  std::set<const DecodedTexture*> distinct;
  for (std::size_t m = 0; m < scene.materials.size(); ++m)
    for (int r = 0; r < kTextureRoleCount; ++r) {
      const Texture* texture = texture_for(scene.materials[m], static_cast<TextureRole>(r));
      if (!texture || texture->empty()) continue;
      Impl::Lookup& lookup = impl.lookups[m][static_cast<std::size_t>(r)];
      lookup.texture = *texture;
      lookup.texture.encoded = nullptr;
      if (auto decoded = find_decoded_texture(*texture, impl.use.budget_bytes)) {
        lookup.decoded = decoded.get();
        if (distinct.insert(decoded.get()).second) impl.use.decoded_bytes += decoded->layout().decoded_bytes();
        impl.decoded.push_back(std::move(decoded));
      }
    }
  impl.use.decoded = int(distinct.size());
  impl.use.tiled = impl.use.decoded_bytes > impl.use.budget_bytes;
  if (impl.use.tiled) {
    impl.decoded.clear();
    impl.use.decoded = 0;
  }
  std::map<const std::string*, std::string> written;
  for (std::size_t m = 0; m < scene.materials.size(); ++m)
    for (int r = 0; r < kTextureRoleCount; ++r) {
      Impl::Lookup& lookup = impl.lookups[m][static_cast<std::size_t>(r)];
      if (lookup.texture.empty() || (lookup.decoded && !impl.use.tiled)) continue;
      lookup.decoded = nullptr;
      impl.open_in_oiio(*texture_for(scene.materials[m], static_cast<TextureRole>(r)), lookup, written);
    }
}

TextureSampler::~TextureSampler() = default;

const TextureUse& TextureSampler::use() const { return impl_->use; }

bool TextureSampler::has(std::uint32_t material, TextureRole role) const { return impl_->find(material, role) != nullptr; }

Vec3f TextureSampler::sample(std::uint32_t material, TextureRole role, const TexCoords& uv) const {
  const Impl::Lookup* lookup = impl_->find(material, role);
  if (!lookup) return Vec3f(1.0f);
  float rgb[3] = {1.0f, 1.0f, 1.0f};
  const Vec2f at = lookup->texture.lookup_uv(uv);
  if (lookup->decoded) {
    if (lookup->decoded->pending()) impl_->prefetch(material);
    const DecodedImage* image = lookup->decoded->image();
    if (!image || !sample_bilinear(*image, lookup->texture.wrap_s, lookup->texture.wrap_t, at, rgb)) return Vec3f(1.0f);
  } else if (!impl_->files->sample(lookup->slot, at, rgb)) {
    return Vec3f(1.0f);
  }
  if (!is_colour(role)) return {rgb[0], rgb[1], rgb[2]};
  return {srgb_to_linear(rgb[0]), srgb_to_linear(rgb[1]), srgb_to_linear(rgb[2])};
}

bool texture_is_readable(const Texture& texture, std::string& reason) {
  std::error_code error;
  if (!texture.encoded && !fs::is_regular_file(texture.path, error)) {
    reason = "no such file";
    return false;
  }
  // A PNG or JPEG by its header, read by rt's own decoder into the process's texture cache, where
  // the render's sampler finds it without reading the file again; what that refuses (another
  // format, a CMYK or 12-bit JPEG, a damaged file) by OpenImageIO, which the sampler then uses.
  if (find_decoded_texture(texture, available_memory_bytes() / 2)) return true;
  return oiio_module().texture_is_readable(texture, reason);
}

std::optional<Vec4f> texture_mean(const Texture& texture) { return oiio_module().texture_mean(texture); }

}  // namespace rt
