#pragma once
// PNG and JPEG decoding for textures with libpng and libjpeg-turbo, without OpenImageIO: glTF
// allows only these two formats, and loading OpenImageIO's module costs some 0.3 s of a process
// (docs/performance.md). Texels come out as stored: no gamma or colour-space conversion (as
// OpenImageIO's readers, whose values the texture lookups used to get), alpha unassociated.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <memory>
#include <vector>

namespace rt {

enum class ImageCodec : std::uint8_t { png, jpeg, other };

// The codec `bytes` (a file's first bytes suffice) are encoded with, by their signature.
ImageCodec codec_of(std::string_view bytes);

// The layout decode_image gives an image: `channels` interleaved per texel (1 grey, 2 grey and
// alpha, 3 RGB, 4 RGBA; palettes expanded to RGB, tRNS transparency to an alpha channel), `bits`
// 8 or 16 per channel.
struct ImageLayout {
  int width = 0, height = 0, channels = 0, bits = 8;
  std::uint64_t decoded_bytes() const {
    return std::uint64_t(width) * std::uint64_t(height) * std::uint64_t(channels) * std::uint64_t(bits / 8);
  }
};

// Memory for texels: at least `bytes`, from transparent huge pages when that large (a 2k RGBA
// texture is 16 MB: 4096 page faults in 4 KiB pages, 8 in 2 MiB ones).
void* allocate_texels(std::size_t bytes);
void free_texels(void* texels, std::size_t bytes) noexcept;

// A vector whose resize leaves new elements uninitialised (the decoder writes every texel, and
// zeroing 16 MB first would cost a pass over memory per 2k texture), in allocate_texels memory.
template <typename T>
struct UninitialisedAllocator : std::allocator<T> {
  using value_type = T;
  UninitialisedAllocator() = default;
  template <typename U>
  UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}
  template <typename U>
  struct rebind {
    using other = UninitialisedAllocator<U>;
  };
  T* allocate(std::size_t n) { return static_cast<T*>(allocate_texels(n * sizeof(T))); }
  void deallocate(T* p, std::size_t n) noexcept { free_texels(p, n * sizeof(T)); }
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
template <typename T>
using TexelVector = std::vector<T, UninitialisedAllocator<T>>;

// A decoded image: rows from the top, texels row-major, in `texels8` (8-bit) or `texels16`
// (16-bit, host byte order).
struct DecodedImage {
  ImageLayout layout;
  TexelVector<std::uint8_t> texels8;
  TexelVector<std::uint16_t> texels16;

  // Channel `c` of texel (x, y) in [0, 1] (value / 255 or / 65535, as OpenImageIO converts).
  float channel(int x, int y, int c) const {
    const std::size_t i = (std::size_t(y) * std::size_t(layout.width) + std::size_t(x)) * std::size_t(layout.channels) +
                          std::size_t(c);
    return layout.bits == 8 ? float(texels8[i]) * (1.0f / 255.0f) : float(texels16[i]) * (1.0f / 65535.0f);
  }
};

// The layout of the PNG or JPEG image in `bytes`, from its header alone (for a JPEG: the markers
// before the first scan). nullopt, with the decoder's reason in `error`, when `bytes` are not a
// PNG or JPEG, are damaged before the image data, or are a CMYK JPEG (left to OpenImageIO).
std::optional<ImageLayout> read_image_layout(std::string_view bytes, std::string& error);

// Decodes the PNG or JPEG image in `bytes`; nullopt, with the decoder's one-line reason in
// `error`, when read_image_layout fails or the image data are damaged or truncated.
std::optional<DecodedImage> decode_image(std::string_view bytes, std::string& error);

}  // namespace rt
