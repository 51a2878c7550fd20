#include "rt/io/image_io.h"

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <filesystem>
#include <iterator>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>
#include <fmt/ranges.h>
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

std::vector<std::uint8_t> to_rgb8(const Image& image, const DisplayTransform& display) {
  std::vector<std::uint8_t> bytes(image.pixels.size() * 3);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) encode_8bit(image.pixels[i], display, &bytes[3 * i]);
  return bytes;
}

bool writes_float(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".exr" || ext == ".hdr";
}

namespace {

// Formats rt encodes itself, without loading OpenImageIO (oiio_module.h says why).
bool is_native_format(const std::string& ext) { return ext == ".png" || ext == ".ppm"; }

// libpng reports errors through a callback that must not return; it jumps back to write_png.
[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  *static_cast<std::string*>(png_get_error_ptr(png)) = message;
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

void append_png_bytes(png_structp png, png_bytep data, png_size_t size) {
  auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + size);
}

// The libpng calls that may fail, in a frame holding no object with a destructor, as setjmp asks.
bool write_png(png_structp png, png_infop info, std::vector<unsigned char>* out, png_bytepp rows, int width,
               int height) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_write_fn(png, out, &append_png_bytes, nullptr);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  // zlib level 3 and the Up filter on every row: libpng's default (level 6, the best of five
  // filters per row) took 0.15-0.28 s for a 1024x1024 render, this 0.04-0.07 s, for files 1-50%
  // larger (docs/performance.md).
  png_set_compression_level(png, 3);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

// 8-bit RGB PNG, tagged sRGB (how the quantised values are meant to be displayed).
std::vector<unsigned char> encode_png(int width, int height, const std::vector<std::uint8_t>& rgb8,
                                      const std::string& path) {
  std::string error = "out of memory";
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, &on_png_error, &on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  std::vector<png_bytep> rows(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y)
    rows[std::size_t(y)] = const_cast<png_bytep>(rgb8.data() + std::size_t(y) * std::size_t(width) * 3);
  std::vector<unsigned char> encoded;
  const bool ok = info && write_png(png, info, &encoded, rows.data(), width, height);
  png_destroy_write_struct(&png, &info);
  if (!ok) throw RuntimeError(fmt::format("{}: cannot encode the image: {}", path, error));
  return encoded;
}

// Binary PPM (P6), maxval 255.
std::vector<unsigned char> encode_ppm(int width, int height, const std::vector<std::uint8_t>& rgb8) {
  const std::string header = fmt::format("P6\n{} {}\n255\n", width, height);
  std::vector<unsigned char> encoded(header.begin(), header.end());
  encoded.insert(encoded.end(), rgb8.begin(), rgb8.end());
  return encoded;
}

}  // namespace

void check_image_format(const std::string& path) {
  const std::string ext = lower_extension(path);
  const auto formats = [] {
    // The formats most asked for by name, the rest (.dpx, .fits, .sgi, ...) by count.
    const std::vector<std::string> named = {".png", ".ppm", ".exr", ".hdr", ".tif", ".jpg", ".bmp", ".tga", ".webp", ".gif"};
    const std::vector<std::string> writable = oiio_module().writable_extensions();
    const auto writes = [&](const std::string& e) {
      return is_native_format(e) || std::find(writable.begin(), writable.end(), e) != writable.end();
    };
    std::vector<std::string> listed;
    std::copy_if(named.begin(), named.end(), std::back_inserter(listed), writes);
    const auto others = std::count_if(writable.begin(), writable.end(), [&](const std::string& e) {
      return std::find(named.begin(), named.end(), e) == named.end();
    });
    return fmt::format("writable: {} and {} more extensions of OpenImageIO; float: .exr .hdr", fmt::join(listed, " "),
                       others);
  };
  if (ext.empty())
    throw InputError(path, "", "output file has no extension to choose an image format by (" + formats() + ")");
  if (!is_native_format(ext) && !oiio_module().has_writer(path))
    throw InputError(path, "", fmt::format("unknown image format '{}' ({})", ext, formats()));
}

std::string lossy_format_note(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".gif") return "GIF keeps at most 256 colours; .png keeps every pixel exactly";
  if (ext == ".jpg" || ext == ".jpeg" || ext == ".jpe" || ext == ".webp" || ext == ".heic" || ext == ".heif" ||
      ext == ".avif" || ext == ".jp2" || ext == ".j2k")
    return fmt::format("{} is compressed lossily; .png keeps every pixel exactly", ext.substr(1));
  return "";
}

void check_output_path(const std::string& path) {
  check_image_format(path);
  check_parent_directory_writable(path);
}

namespace {

// Encodes by extension and writes atomically: `image`'s floats when as_float, else `rgb8`, with
// `image` giving only the size.
void encode_and_write(const std::string& path, const Image& image, bool as_float, const std::vector<std::uint8_t>& rgb8,
                      const ImageHeader& header) {
  const std::string ext = lower_extension(path);
  std::vector<unsigned char> encoded;
  if (ext == ".png") {
    encoded = encode_png(image.width, image.height, rgb8, path);
  } else if (ext == ".ppm") {
    encoded = encode_ppm(image.width, image.height, rgb8);
  } else {
    std::string error;
    encoded = oiio_module().encode(path, image, as_float, rgb8, header, error);
    if (!error.empty()) throw RuntimeError(fmt::format("{}: cannot encode the image: {}", path, error));
  }
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(encoded.data()), encoded.size()));
}

}  // namespace

void write_image(const Image& image, const std::string& path, const ImageHeader& header,
                 const DisplayTransform& display) {
  check_image_format(path);
  const bool as_float = writes_float(path);
  if (!as_float) {
    encode_and_write(path, image, false, to_rgb8(image, display), header);
    return;
  }
  ImageHeader recorded = header;
  recorded.attributes.emplace_back(kDisplayAttribute, to_string(display));
  encode_and_write(path, image, true, {}, recorded);
}

void write_rgb8(int width, int height, const std::vector<std::uint8_t>& rgb8, const std::string& path) {
  check_image_format(path);
  if (writes_float(path))
    throw InputError(path, "", "an 8-bit image cannot be written in a float format; use .png, .ppm or .tif");
  if (rgb8.size() != std::size_t(width) * std::size_t(height) * 3)
    throw std::invalid_argument(fmt::format("write_rgb8: {} bytes for {}x{} pixels", rgb8.size(), width, height));
  Image size_only;
  size_only.width = width;
  size_only.height = height;
  encode_and_write(path, size_only, false, rgb8, ImageHeader{});
}

Image read_image(const std::string& path, ImageHeader* header) {
  std::string error;
  std::optional<Image> image = oiio_module().read(path, header, error);
  if (!image) throw InputError(path, "", fmt::format("cannot read image ({})", error));
  return std::move(*image);
}

}  // namespace rt
