#pragma once
// The part of rt that needs OpenImageIO, kept in a module (rt-oiio.so) that is loaded the first
// time it is needed. Linking libOpenImageIO pulls in some 260 shared libraries (OpenCV, FFmpeg,
// GDAL, ...) whose loading and initialisation take 0.6 s of every process; most renders need none
// of them, as rt writes PNG and PPM itself (docs/performance.md). Private to rt_lib.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rt/core/image.h"
#include "rt/io/image_io.h"
#include "rt/scene/scene.h"

namespace rt {

// Textures opened for sampling from many threads at once (one OIIO TextureSystem).
class TextureFiles {
 public:
  virtual ~TextureFiles() = default;

  // Registers the image file `path` for lookups with the given wraps; returns its slot, or -1 if
  // it cannot be registered.
  virtual int open(const std::string& path, TextureWrap wrap_s, TextureWrap wrap_t) = 0;

  // Bilinear lookup at level 0 (no MIP-mapping) of slot `slot` at texture coordinates `uv`; the
  // first three channels as stored (grey replicated). False when the lookup fails.
  virtual bool sample(int slot, Vec2f uv, float rgb[3]) const = 0;
};

// What rt asks of OpenImageIO. Errors are returned as text, never thrown across the module
// boundary; callers turn them into InputError or RuntimeError.
class OiioModule {
 public:
  virtual ~OiioModule() = default;

  // True when OpenImageIO has a writer for the format named by `path`'s extension.
  virtual bool has_writer(const std::string& path) const = 0;

  // The extensions (lower case, with the dot) of every format OpenImageIO writes to a file, sorted.
  virtual std::vector<std::string> writable_extensions() const = 0;

  // Encodes `image` in memory for `path`'s format, as float when `as_float`, else as 8-bit RGB
  // `rgb8` (to_rgb8 of the image). EXR gets zip compression and `header`. Empty `error` on success.
  virtual std::vector<unsigned char> encode(const std::string& path, const Image& image, bool as_float,
                                            const std::vector<std::uint8_t>& rgb8, const ImageHeader& header,
                                            std::string& error) const = 0;

  // Reads any readable image as float RGB, as rt::read_image documents. nullopt and `error` on failure.
  virtual std::optional<Image> read(const std::string& path, ImageHeader* header, std::string& error) const = 0;

  // Whether `texture` (a file, or its encoded bytes) opens as an image; `reason` says why not.
  virtual bool texture_is_readable(const Texture& texture, std::string& reason) const = 0;

  // As rt::texture_mean (rt/render/texture.h).
  virtual std::optional<Vec4f> texture_mean(const Texture& texture) const = 0;

  // The alpha of `texture` per texel, row 0 at the top, unassociated (colour is never divided or
  // multiplied by it): its alpha channel, else with `grey_is_alpha` its first channel; nullopt
  // when it has neither or cannot be read.
  struct AlphaImage {
    int width = 0, height = 0;
    std::vector<float> alpha;  // width x height, row-major
  };
  virtual std::optional<AlphaImage> read_alpha(const Texture& texture, bool grey_is_alpha) const = 0;

  // A new, empty set of texture files, in the process's one TextureSystem. With a nonzero
  // `max_memory_bytes`, its cache holds at most that many bytes of 64x64 tiles (untiled images
  // too); with 0, each image is one tile and the cache is OpenImageIO's default size.
  virtual std::unique_ptr<TextureFiles> new_texture_files(std::uint64_t max_memory_bytes) const = 0;
};

// The extension OpenImageIO recognises encoded image bytes by (it also sniffs the content).
inline std::string encoded_image_extension(const std::string& bytes) {
  if (bytes.rfind("\x89PNG", 0) == 0) return ".png";
  if (bytes.rfind("\xFF\xD8", 0) == 0) return ".jpg";
  return ".img";
}

// The module, loaded on first use and kept for the life of the process. Throws RuntimeError if it
// cannot be found or loaded (the message names every place searched).
const OiioModule& oiio_module();

}  // namespace rt

// The module's one exported symbol.
extern "C" const rt::OiioModule* rt_oiio_module();
