#include "rt/render/texture.h"

#include <stdlib.h>  // mkdtemp

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "io/oiio_module.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

// The sRGB transfer function's inverse (IEC 61966-2-1), per channel.
float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

}  // namespace

struct TextureSampler::Impl {
  std::unique_ptr<TextureFiles> files;  // null until a material has a texture
  std::vector<int> diffuse_slots;       // per material: the slot in `files`, -1 for none
  std::vector<int> emission_slots;
  std::vector<int> transmission_slots;
  fs::path temp_dir;                    // empty unless an embedded image needed a file

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
};

TextureSampler::TextureSampler(const Scene& scene) : impl_(std::make_unique<Impl>()) {
  impl_->diffuse_slots.assign(scene.materials.size(), -1);
  impl_->emission_slots.assign(scene.materials.size(), -1);
  impl_->transmission_slots.assign(scene.materials.size(), -1);
  std::map<const std::string*, std::string> written;
  const auto open = [&](const Texture& texture, int& slot) {
    if (texture.empty()) return;
    if (!impl_->files) impl_->files = oiio_module().new_texture_files();
    const std::string path = texture.encoded ? impl_->file_for(texture.encoded, written) : texture.path;
    if (!path.empty()) slot = impl_->files->open(path, texture.wrap_s, texture.wrap_t);
  };
  for (std::size_t i = 0; i < scene.materials.size(); ++i) {
    open(scene.materials[i].diffuse_texture, impl_->diffuse_slots[i]);
    if (scene.materials[i].emits_light) open(scene.materials[i].emission_texture, impl_->emission_slots[i]);
    if (scene.materials[i].is_dielectric() && scene.materials[i].transmission_mix)
      open(scene.materials[i].transmission_texture, impl_->transmission_slots[i]);
  }
}

TextureSampler::~TextureSampler() = default;

namespace {

bool has_slot(const std::vector<int>& slots, std::uint32_t material) {
  return material < slots.size() && slots[material] >= 0;
}

// Linear RGB of texture slot `slot` at `uv`: sRGB texel values decoded after filtering; white when
// the lookup fails.
Color sample_srgb(TextureFiles& files, int slot, Vec2f uv) {
  float rgb[3] = {1.0f, 1.0f, 1.0f};
  if (!files.sample(slot, uv, rgb)) return Color(1.0f);
  return {srgb_to_linear(rgb[0]), srgb_to_linear(rgb[1]), srgb_to_linear(rgb[2])};
}

}  // namespace

bool TextureSampler::has_diffuse(std::uint32_t material) const { return has_slot(impl_->diffuse_slots, material); }

Color TextureSampler::diffuse(std::uint32_t material, Vec2f uv) const {
  if (!has_diffuse(material)) return Color(1.0f);
  return sample_srgb(*impl_->files, impl_->diffuse_slots[material], uv);
}

bool TextureSampler::has_emission(std::uint32_t material) const { return has_slot(impl_->emission_slots, material); }

Color TextureSampler::emission(std::uint32_t material, Vec2f uv) const {
  if (!has_emission(material)) return Color(1.0f);
  return sample_srgb(*impl_->files, impl_->emission_slots[material], uv);
}

bool TextureSampler::has_transmission(std::uint32_t material) const {
  return has_slot(impl_->transmission_slots, material);
}

float TextureSampler::transmission(std::uint32_t material, Vec2f uv) const {
  float rgb[3] = {1.0f, 1.0f, 1.0f};
  if (!has_transmission(material) || !impl_->files->sample(impl_->transmission_slots[material], uv, rgb)) return 1.0f;
  return rgb[0];
}

bool texture_is_readable(const Texture& texture, std::string& reason) {
  std::error_code error;
  if (!texture.encoded && !fs::is_regular_file(texture.path, error)) {
    reason = "no such file";
    return false;
  }
  return oiio_module().texture_is_readable(texture, reason);
}

std::optional<Vec4f> texture_mean(const Texture& texture) { return oiio_module().texture_mean(texture); }

}  // namespace rt
