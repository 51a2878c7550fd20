#include "rt/io/decode_image.h"

#include <sys/mman.h>

#include <algorithm>
#include <csetjmp>
#include <cstdlib>
#include <new>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>
#include <jpeglib.h>
#include <png.h>

#include "rt/core/memory.h"

namespace rt {

namespace {

// --- PNG (libpng 1.6) ------------------------------------------------------------------------
// libpng reports errors through a callback that must not return: it jumps back to the setjmp in
// the frame that called libpng, which therefore holds no object with a destructor.

struct PngSource {
  const unsigned char* data;
  std::size_t size, offset;
  char error[200];
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  auto* source = static_cast<PngSource*>(png_get_error_ptr(png));
  std::snprintf(source->error, sizeof source->error, "%s", message);
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

void read_png_bytes(png_structp png, png_bytep out, png_size_t count) {
  auto* source = static_cast<PngSource*>(png_get_io_ptr(png));
  if (count > source->size - source->offset) png_error(png, "the file ends inside the image data (truncated)");
  std::memcpy(out, source->data + source->offset, count);
  source->offset += count;
}

// Reads the header and sets the expansions ImageLayout documents (16-bit kept, in host order).
bool read_png_header(png_structp png, png_infop info, ImageLayout& layout) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_info(png, info);
  const int colour = png_get_color_type(png, info), depth = png_get_bit_depth(png, info);
  if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (colour == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (depth == 16) png_set_swap(png);  // PNG stores 16-bit samples big-endian
  // zlib's Adler-32 of the image data is not verified (libpng still checks every chunk's CRC):
  // it is some 6% of decoding a 2k texture, spent again on every render of it. Debian 13's
  // libpng 1.6.48 is built without the option (PNG_DISABLE_ADLER32_CHECK_SUPPORTED).
#ifdef PNG_IGNORE_ADLER32
  png_set_option(png, PNG_IGNORE_ADLER32, PNG_OPTION_ON);
#endif
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  layout = {int(png_get_image_width(png, info)), int(png_get_image_height(png, info)), int(png_get_channels(png, info)),
            int(png_get_bit_depth(png, info))};
  return true;
}

bool read_png_rows(png_structp png, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  return true;
}

// Allocates `image`'s texels for `layout`; false with `error` when they do not fit in memory.
bool allocate(const ImageLayout& layout, DecodedImage& image, std::string& error) {
  if (const auto shortfall = memory_shortfall(layout.decoded_bytes())) {
    error = fmt::format("the decoded {}x{} image {}", layout.width, layout.height, *shortfall);
    return false;
  }
  image.layout = layout;
  const std::size_t values = std::size_t(layout.decoded_bytes()) / std::size_t(layout.bits / 8);
  if (layout.bits == 8)
    image.texels8.resize(values);
  else
    image.texels16.resize(values);
  return true;
}

// The PNG in `bytes`: its layout, and with `image` its texels.
bool decode_png(std::string_view bytes, ImageLayout& layout, DecodedImage* image, std::string& error) {
  PngSource source{reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), 0, {}};
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &source, on_png_error, on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    error = "out of memory";
    return false;
  }
  png_set_read_fn(png, &source, read_png_bytes);
  bool ok = read_png_header(png, info, layout);
  if (ok && layout.bits != 8 && layout.bits != 16) {
    std::snprintf(source.error, sizeof source.error, "unsupported bit depth %d", layout.bits);
    ok = false;
  }
  std::vector<png_bytep> rows;
  if (ok && image) {
    ok = allocate(layout, *image, error);
    if (ok) {
      rows.resize(std::size_t(layout.height));
      const std::size_t row_bytes = std::size_t(layout.width) * std::size_t(layout.channels) * std::size_t(layout.bits / 8);
      auto* base = layout.bits == 8 ? image->texels8.data() : reinterpret_cast<std::uint8_t*>(image->texels16.data());
      for (std::size_t y = 0; y < rows.size(); ++y) rows[y] = base + y * row_bytes;
      ok = read_png_rows(png, rows.data());
    }
  }
  png_destroy_read_struct(&png, &info, nullptr);
  if (!ok && error.empty()) error = source.error[0] ? source.error : "not a readable PNG";
  return ok;
}

// --- JPEG (libjpeg-turbo, libjpeg 6.2 API) ---------------------------------------------------
// libjpeg's error_exit must not return either; the same setjmp discipline applies.

struct JpegErrors {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void on_jpeg_error(j_common_ptr cinfo) {
  auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, errors->message);
  std::longjmp(errors->jump, 1);
}

void on_jpeg_message(j_common_ptr, int) {}  // warnings (e.g. "premature end of data") are not errors

// Reads the markers up to the first scan; libjpeg's default output is then as OpenImageIO's
// reader leaves it (islow DCT, fancy upsampling), grey kept as one channel, YCbCr as RGB.
bool read_jpeg_header(jpeg_decompress_struct& cinfo, JpegErrors& errors, ImageLayout& layout) {
  if (setjmp(errors.jump)) return false;
  jpeg_read_header(&cinfo, TRUE);
  if (cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK) {
    std::snprintf(errors.message, sizeof errors.message, "a CMYK JPEG");
    return false;
  }
  cinfo.out_color_space = cinfo.num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  layout = {int(cinfo.image_width), int(cinfo.image_height), cinfo.num_components == 1 ? 1 : 3, 8};
  return true;
}

bool read_jpeg_rows(jpeg_decompress_struct& cinfo, JpegErrors& errors, std::uint8_t* texels) {
  if (setjmp(errors.jump)) return false;
  jpeg_start_decompress(&cinfo);
  const std::size_t row_bytes = std::size_t(cinfo.output_width) * std::size_t(cinfo.output_components);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = texels + std::size_t(cinfo.output_scanline) * row_bytes;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  return true;
}

bool decode_jpeg(std::string_view bytes, ImageLayout& layout, DecodedImage* image, std::string& error) {
  jpeg_decompress_struct cinfo{};
  JpegErrors errors{};
  cinfo.err = jpeg_std_error(&errors.manager);
  errors.manager.error_exit = on_jpeg_error;
  errors.manager.emit_message = on_jpeg_message;
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, reinterpret_cast<const unsigned char*>(bytes.data()), static_cast<unsigned long>(bytes.size()));
  bool ok = read_jpeg_header(cinfo, errors, layout);
  if (ok && image) {
    ok = allocate(layout, *image, error) && read_jpeg_rows(cinfo, errors, image->texels8.data());
    // A truncated scan is only a warning to libjpeg, which fills the rest with grey; so is it to
    // OpenImageIO, whose values the lookups match.
  }
  jpeg_destroy_decompress(&cinfo);
  if (!ok && error.empty()) error = errors.message[0] ? errors.message : "not a readable JPEG";
  return ok;
}

bool decode(std::string_view bytes, ImageLayout& layout, DecodedImage* image, std::string& error) {
  switch (codec_of(bytes)) {
    case ImageCodec::png: return decode_png(bytes, layout, image, error);
    case ImageCodec::jpeg: return decode_jpeg(bytes, layout, image, error);
    case ImageCodec::other: break;
  }
  error = "neither a PNG nor a JPEG";
  return false;
}

constexpr std::size_t kHugePage = std::size_t(2) << 20;

}  // namespace

void* allocate_texels(std::size_t bytes) {
  if (bytes < 2 * kHugePage) {
    if (void* p = std::malloc(std::max<std::size_t>(bytes, 1))) return p;
    throw std::bad_alloc();
  }
  const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = std::aligned_alloc(kHugePage, rounded);
  if (!p) throw std::bad_alloc();
  madvise(p, rounded, MADV_HUGEPAGE);  // a hint: without THP (or with it off) plain pages
  return p;
}

void free_texels(void* texels, std::size_t) noexcept { std::free(texels); }

ImageCodec codec_of(std::string_view bytes) {
  if (bytes.size() >= 8 && bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) return ImageCodec::png;
  if (bytes.size() >= 3 && bytes.compare(0, 3, "\xFF\xD8\xFF") == 0) return ImageCodec::jpeg;
  return ImageCodec::other;
}

std::optional<ImageLayout> read_image_layout(std::string_view bytes, std::string& error) {
  ImageLayout layout;
  if (!decode(bytes, layout, nullptr, error)) return std::nullopt;
  return layout;
}

std::optional<DecodedImage> decode_image(std::string_view bytes, std::string& error) {
  ImageLayout layout;
  DecodedImage image;
  if (!decode(bytes, layout, &image, error)) return std::nullopt;
  return image;
}

}  // namespace rt
