#include "rt/render/alpha.h"

#include <algorithm>
#include <cmath>

#include "io/oiio_module.h"
#include "render/texture_cache.h"
#include "rt/core/memory.h"

namespace rt {

namespace {

// Texel index along one axis of `size` texels for texture coordinate `c`, under `wrap` (glTF's
// sampler modes, OpenImageIO's conventions: texel i covers [i, i + 1) / size).
int texel_index(float c, int size, TextureWrap wrap) {
  const double x = std::floor(double(c) * size);
  return std::isfinite(x) ? wrap_texel_index(x, size, wrap) : 0;
}

// `texture`'s alpha per texel (OiioModule::read_alpha's contract), decoded by rt when it is a
// PNG or JPEG (sharing the decode with the colour lookups), else by OpenImageIO.
std::optional<OiioModule::AlphaImage> read_alpha(const Texture& texture, bool grey_is_alpha) {
  const auto decoded = find_decoded_texture(texture, available_memory_bytes() / 2);
  if (!decoded) return oiio_module().read_alpha(texture, grey_is_alpha);
  const DecodedImage* image = decoded->image();
  if (!image) return std::nullopt;
  const ImageLayout& l = image->layout;
  const int channel = l.channels == 2 || l.channels == 4 ? l.channels - 1 : grey_is_alpha ? 0 : -1;
  if (channel < 0) return std::nullopt;
  OiioModule::AlphaImage alpha{l.width, l.height, std::vector<float>(std::size_t(l.width) * std::size_t(l.height))};
  for (int y = 0; y < l.height; ++y)
    for (int x = 0; x < l.width; ++x) alpha.alpha[std::size_t(y) * std::size_t(l.width) + std::size_t(x)] = image->channel(x, y, channel);
  return alpha;
}

}  // namespace

SceneAlpha::SceneAlpha(const Scene& scene, const FlatScene& flat) : flat_(flat), materials_(scene.materials.size()) {
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    const Material& material = scene.materials[m];
    if (!material.has_alpha()) continue;
    MaterialAlpha& alpha = materials_[m];
    alpha.mode = material.alpha_mode;
    alpha.constant = std::clamp(material.alpha, 0.0f, 1.0f);
    alpha.cutoff = material.alpha_cutoff;
    alpha.lookup = material.alpha_texture;
    alpha.lookup.encoded = nullptr;  // only the wrap modes, the coordinate set and the transform are read
    if (!material.alpha_texture.empty() && has_texcoords(flat))
      if (auto image = read_alpha(material.alpha_texture, material.alpha_from_grey)) {
        alpha.width = image->width;
        alpha.height = image->height;
        alpha.texels = std::move(image->alpha);
      }
    // Nothing to test where alpha is 1 everywhere.
    alpha.tested = alpha.constant < 1.0f || std::any_of(alpha.texels.begin(), alpha.texels.end(), [](float a) { return a < 1.0f; });
  }
  if (std::none_of(materials_.begin(), materials_.end(), [](const MaterialAlpha& m) { return m.tested; })) return;
  for (std::uint32_t t = 0; t < flat.triangle_count() && !any_; ++t) any_ = materials_[flat.material_ids[t]].tested;
}

double SceneAlpha::alpha_at(std::uint32_t primitive, float b1, float b2) const {
  const MaterialAlpha& alpha = materials_[flat_.material_of(primitive)];
  return flat_.is_sphere(primitive) ? alpha.constant : triangle_alpha(alpha, primitive, b1, b2);
}

double SceneAlpha::triangle_alpha(const MaterialAlpha& alpha, std::uint32_t triangle, float b1, float b2) const {
  if (alpha.width == 0) return alpha.constant;
  // Texture space, float, interpolated as the shader interpolates the hit's coordinates.
  const double b0 = 1.0 - double(b1) - double(b2);
  const Vec2f uv = alpha.lookup.lookup_uv(texcoords_at(flat_, triangle, float(b0), b1, b2));
  const int x = texel_index(uv.x, alpha.width, alpha.lookup.wrap_s), y = texel_index(uv.y, alpha.height, alpha.lookup.wrap_t);
  return std::clamp(double(alpha.constant) * alpha.texels[std::size_t(y) * std::size_t(alpha.width) + std::size_t(x)],
                    0.0, 1.0);
}

bool SceneAlpha::hit_counts(std::uint32_t triangle, float b1, float b2) const {
  calls_.fetch_add(1, std::memory_order_relaxed);
  const MaterialAlpha& alpha = materials_[flat_.material_ids[triangle]];
  const double a = triangle_alpha(alpha, triangle, b1, b2);
  return alpha.mode == AlphaMode::mask ? a >= alpha.cutoff : a > 0.0;
}

bool SceneAlpha::blocks(std::uint32_t triangle, float b1, float b2) const {
  calls_.fetch_add(1, std::memory_order_relaxed);
  const MaterialAlpha& alpha = materials_[flat_.material_ids[triangle]];
  return triangle_alpha(alpha, triangle, b1, b2) >= (alpha.mode == AlphaMode::mask ? alpha.cutoff : 0.5);
}

}  // namespace rt
