#include "rt/io/image_io.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include <fmt/format.h>
#include <png.h>

#include "rt/core/error.h"
#include "io/oiio_module.h"
#include "rt/io/atomic_file.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace

std::uint8_t quantize_8bit(float c) {
  // NaN fails both comparisons and maps to 0.
  const float clamped = c > 0.0f ? std::min(c, 1.0f) : 0.0f;
  return static_cast<std::uint8_t>(std::floor(255.0f * clamped));
}

std::vector<std::uint8_t> to_rgb8(const Image& image) {
  std::vector<std::uint8_t> bytes(image.pixels.size() * 3);
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) bytes[3 * i + c] = quantize_8bit(image.pixels[i][c]);
  return bytes;
}

bool writes_float(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".exr" || ext == ".hdr";
}

namespace {

// Formats rt encodes itself, without loading OpenImageIO (oiio_module.h says why).
bool is_native_format(const std::string& ext) { return ext == ".png" || ext == ".ppm"; }

// 8-bit RGB PNG through libpng's simplified API (default zlib compression; libpng tags 8-bit
// output as sRGB, which is how the quantised values are meant to be displayed).
std::vector<unsigned char> encode_png(const Image& image, const std::vector<std::uint8_t>& rgb8, const std::string& path) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  std::vector<unsigned char> encoded;
  if (png_image_write_to_memory(&png, nullptr, &size, 0, rgb8.data(), 0, nullptr)) {
    encoded.resize(size);
    if (png_image_write_to_memory(&png, encoded.data(), &size, 0, rgb8.data(), 0, nullptr)) {
      encoded.resize(size);
      return encoded;
    }
  }
  const std::string message = png.message;
  png_image_free(&png);
  throw RuntimeError(fmt::format("{}: cannot encode the image: {}", path, message));
}

// Binary PPM (P6), maxval 255.
std::vector<unsigned char> encode_ppm(const Image& image, const std::vector<std::uint8_t>& rgb8) {
  const std::string header = fmt::format("P6\n{} {}\n255\n", image.width, image.height);
  std::vector<unsigned char> encoded(header.begin(), header.end());
  encoded.insert(encoded.end(), rgb8.begin(), rgb8.end());
  return encoded;
}

// Throws InputError unless rt or OpenImageIO can write `path`'s format.
void check_format(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext.empty()) throw InputError(path, "", "output file has no extension to choose an image format by");
  if (!is_native_format(ext) && !oiio_module().has_writer(path))
    throw InputError(path, "", fmt::format("unknown image format '{}'", ext));
}

}  // namespace

void check_output_path(const std::string& path) {
  check_format(path);
  check_parent_directory_writable(path);
}

void write_image(const Image& image, const std::string& path, const ImageHeader& header) {
  check_format(path);
  const std::string ext = lower_extension(path);
  const bool as_float = writes_float(path);
  const std::vector<std::uint8_t> rgb8 = as_float ? std::vector<std::uint8_t>{} : to_rgb8(image);
  std::vector<unsigned char> encoded;
  if (ext == ".png") {
    encoded = encode_png(image, rgb8, path);
  } else if (ext == ".ppm") {
    encoded = encode_ppm(image, rgb8);
  } else {
    std::string error;
    encoded = oiio_module().encode(path, image, as_float, rgb8, header, error);
    if (!error.empty()) throw RuntimeError(fmt::format("{}: cannot encode the image: {}", path, error));
  }
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(encoded.data()), encoded.size()));
}

Image read_image(const std::string& path, ImageHeader* header) {
  std::string error;
  std::optional<Image> image = oiio_module().read(path, header, error);
  if (!image) throw InputError(path, "", fmt::format("cannot read image ({})", error));
  return std::move(*image);
}

}  // namespace rt
