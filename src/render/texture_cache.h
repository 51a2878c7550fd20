#pragma once
// Decoded PNG and JPEG textures, shared by every TextureSampler of the process (rt view's passes,
// a farm worker's frames) and kept between them up to a byte budget. Private to rt_lib.

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "rt/io/decode_image.h"
#include "rt/scene/scene.h"

namespace rt {

// One texture image, decoded on its first lookup: one thread decodes while the others that need
// it wait, and threads that need different textures decode them in parallel.
class DecodedTexture {
 public:
  DecodedTexture(const Texture& texture, const ImageLayout& layout);

  const ImageLayout& layout() const { return layout_; }

  // True until the first image() call has finished.
  bool pending() const { return state_.load(std::memory_order_acquire) == kPending; }

  // The image, decoded on the first call; nullptr when it cannot be decoded (damaged after its
  // header), which callers sample as white, as they did under OpenImageIO.
  const DecodedImage* image() const {
    const int state = state_.load(std::memory_order_acquire);
    if (state == kReady) return &*image_;
    return state == kFailed ? nullptr : decode_once();
  }

 private:
  static constexpr int kPending = 0, kReady = 1, kFailed = 2;
  const DecodedImage* decode_once() const;

  std::string path_;                             // read at the first lookup when `encoded_` is null
  mutable std::shared_ptr<const std::string> encoded_;  // the embedded bytes, released once decoded
  ImageLayout layout_;                           // from the header, for the cache's budget
  mutable std::mutex mutex_;
  mutable std::atomic<int> state_{kPending};
  mutable std::optional<DecodedImage> image_;
};

// Texel index `index` (any integer, as a double) wrapped into [0, size) by `wrap`, with glTF's
// (and OpenGL's) modes: repeat is periodic, mirrored_repeat has period 2 size and reflects about
// texel edges, clamp_to_edge clamps.
int wrap_texel_index(double index, int size, TextureWrap wrap);

// Bilinear lookup at texture coordinates `uv` of `image`'s first three channels (grey
// replicated), texel (i, j) centred at ((i + 0.5) / width, (j + 0.5) / height) as in OpenImageIO,
// with the wraps along u and v. False (`rgb` untouched) when `uv` is not finite.
bool sample_bilinear(const DecodedImage& image, TextureWrap wrap_s, TextureWrap wrap_t, Vec2f uv, float rgb[3]);

// The process's decoded texture for `texture`, shared with earlier callers when it names the same
// bytes (the same file, unchanged since; or embedded bytes of the same hash); nullptr when it is
// not a PNG or JPEG readable as such (OpenImageIO's concern). Drops textures no caller holds, the
// least recently requested first, while all it keeps total more than `budget_bytes`.
std::shared_ptr<const DecodedTexture> find_decoded_texture(const Texture& texture, std::uint64_t budget_bytes);

}  // namespace rt
