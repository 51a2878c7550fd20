// The OpenImageIO module (rt-oiio.so): every call rt makes into OpenImageIO. See oiio_module.h.

#include "io/oiio_module.h"

#include <algorithm>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>
#include <OpenImageIO/texture.h>

namespace rt {

namespace {

std::string first_line(std::string text) {
  const std::size_t newline = text.find('\n');
  if (newline != std::string::npos) text.resize(newline);
  return text;
}

OIIO::TextureOpt::Wrap oiio_wrap(TextureWrap wrap) {
  switch (wrap) {
    case TextureWrap::clamp_to_edge: return OIIO::TextureOpt::WrapClamp;
    case TextureWrap::mirrored_repeat: return OIIO::TextureOpt::WrapMirror;
    case TextureWrap::repeat: break;
  }
  return OIIO::TextureOpt::WrapPeriodic;
}

class OiioTextureFiles final : public TextureFiles {
 public:
  ~OiioTextureFiles() override {
    for (const Slot& slot : slots_) system_->invalidate(slot.file);
  }

  explicit OiioTextureFiles(std::uint64_t max_memory_bytes) : max_memory_bytes_(max_memory_bytes) {}

  int open(const std::string& path, TextureWrap wrap_s, TextureWrap wrap_t) override {
    if (!system_) {
      // The process-wide shared TextureSystem: OIIO 2.4's TextureSystem::destroy frees a private
      // one with a mismatched sized delete (AddressSanitizer: new-delete-type-mismatch inside
      // libOpenImageIO), while the shared one is never freed by destroy(). The files opened here
      // are invalidated on teardown, so a later set re-reads them if they changed on disk.
      system_ = OIIO::TextureSystem::create(/*shared=*/true);
      system_->attribute("automip", 0);      // lookups never leave MIP level 0
      system_->attribute("gray_to_rgb", 1);  // grey (+ alpha) images give grey RGB
      // Colour as stored, not multiplied by alpha: glTF and MTL keep the two apart (issue 20).
      system_->attribute("unassociatedalpha", 1);
      // Bounded: untiled images (PNG, JPEG) are cached in 64x64 tiles read from their scanlines,
      // at most max_memory_bytes_ of them. Unbounded: each is one tile, of OpenImageIO's default
      // 256 MB cache.
      system_->attribute("autotile", max_memory_bytes_ ? 64 : 0);
      system_->attribute("max_memory_MB", max_memory_bytes_ ? float(double(max_memory_bytes_) / (1 << 20)) : 256.0f);
    }
    const OIIO::ustring file(path);
    OIIO::TextureSystem::TextureHandle* handle = system_->get_texture_handle(file);
    if (!handle) return -1;
    // gray_to_rgb expands one-channel images only: grey + alpha would give (grey, alpha, 0).
    int channels = 0;
    system_->get_texture_info(handle, nullptr, 0, OIIO::ustring("channels"), OIIO::TypeDesc::INT, &channels);
    slots_.push_back({file, handle, oiio_wrap(wrap_s), oiio_wrap(wrap_t), channels == 2});
    return static_cast<int>(slots_.size()) - 1;
  }

  bool sample(int slot, Vec2f uv, float rgb[3]) const override {
    const Slot& s = slots_[static_cast<std::size_t>(slot)];
    OIIO::TextureOpt options;
    options.swrap = s.wrap_s;
    options.twrap = s.wrap_t;
    options.mipmode = OIIO::TextureOpt::MipModeNoMIP;
    options.interpmode = OIIO::TextureOpt::InterpBilinear;
    if (!s.grey_alpha) return system_->texture(s.handle, nullptr, options, uv.x, uv.y, 0, 0, 0, 0, 3, rgb);
    if (!system_->texture(s.handle, nullptr, options, uv.x, uv.y, 0, 0, 0, 0, 1, rgb)) return false;
    rgb[1] = rgb[2] = rgb[0];
    return true;
  }

 private:
  struct Slot {
    OIIO::ustring file;
    OIIO::TextureSystem::TextureHandle* handle;
    OIIO::TextureOpt::Wrap wrap_s, wrap_t;
    bool grey_alpha;  // two channels: the grey one is replicated
  };
  std::uint64_t max_memory_bytes_;
  OIIO::TextureSystem* system_ = nullptr;
  std::vector<Slot> slots_;
};

class Oiio final : public OiioModule {
 public:
  bool has_writer(const std::string& path) const override {
    const bool known = OIIO::ImageOutput::create(path) != nullptr;
    if (!known) OIIO::geterror();  // clear OIIO's pending message; the caller says it better
    return known;
  }

  std::vector<std::string> writable_extensions() const override {
    // output_format_list: "bmp,dpx,...;" extension_list: "tiff:tif,tiff;jpeg:jpg,jpe,jpeg;..."
    std::vector<std::string> writers;
    OIIO::Strutil::split(OIIO::get_string_attribute("output_format_list"), writers, ",");
    std::vector<std::string> extensions;
    std::vector<std::string> formats;
    OIIO::Strutil::split(OIIO::get_string_attribute("extension_list"), formats, ";");
    for (const std::string& entry : formats) {
      const std::size_t colon = entry.find(':');
      const std::string name = entry.substr(0, colon);
      // "null" and "term" write no file (nothing, or the terminal).
      if (colon == std::string::npos || name == "null" || name == "term" ||
          std::find(writers.begin(), writers.end(), name) == writers.end())
        continue;
      std::vector<std::string> names;
      OIIO::Strutil::split(entry.substr(colon + 1), names, ",");
      for (const std::string& ext : names) {
        std::string dotted(1, '.');  // not "." + ext: GCC 12 -Wrestrict false positive
        dotted += OIIO::Strutil::lower(ext);
        if (has_writer("x" + dotted)) extensions.push_back(dotted);  // the list names some it cannot write (.pfm)
      }
    }
    std::sort(extensions.begin(), extensions.end());
    extensions.erase(std::unique(extensions.begin(), extensions.end()), extensions.end());
    return extensions;
  }

  std::vector<unsigned char> encode(const std::string& path, const Image& image, bool as_float,
                                    const std::vector<std::uint8_t>& rgb8, const ImageHeader& header,
                                    std::string& error) const override {
    std::vector<unsigned char> encoded;
    auto output = OIIO::ImageOutput::create(path);
    if (!output) {
      error = first_line(OIIO::geterror());
      return encoded;
    }
    OIIO::ImageSpec spec(image.width, image.height, 3, as_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
    if (header.data_window) {
      spec.x = header.data_window->x0;
      spec.y = header.data_window->y0;
      spec.full_width = header.full_width;
      spec.full_height = header.full_height;
    }
    for (const auto& [name, value] : header.attributes) spec.attribute(name, value);
    // Lossless, so that merged regions equal a whole render bit for bit (OIIO's default is zip too).
    if (std::string(output->format_name()) == "openexr") spec.attribute("compression", "zip");
    // Encoded in memory; the caller writes the file with checked system calls, as OIIO's file
    // writers can miss a failed write (the PNG writer leaves a truncated file and reports success
    // when the disk fills).
    if (!output->supports("ioproxy")) {
      error = "the '" + std::string(output->format_name()) + "' writer cannot encode to memory";
      return encoded;
    }
    OIIO::Filesystem::IOVecOutput proxy(encoded);
    output->set_ioproxy(&proxy);
    const void* data = as_float ? static_cast<const void*>(image.pixels.data()) : rgb8.data();
    if (!(output->open(path, spec) && output->write_image(spec.format, data) && output->close()))
      error = first_line(output->geterror());
    return encoded;
  }

  std::optional<Image> read(const std::string& path, ImageHeader* header, std::string& error) const override {
    // Colour as stored: the alpha channel is dropped, so it must not darken the colour either.
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto input = OIIO::ImageInput::open(path, &config);
    if (!input) {
      error = first_line(OIIO::geterror());
      return std::nullopt;
    }
    const OIIO::ImageSpec& spec = input->spec();
    if (header) {
      *header = ImageHeader{};
      const PixelRegion data{spec.x, spec.y, spec.x + spec.width, spec.y + spec.height};
      header->full_width = spec.full_width;
      header->full_height = spec.full_height;
      if (data != PixelRegion{spec.full_x, spec.full_y, spec.full_x + spec.full_width, spec.full_y + spec.full_height})
        header->data_window = data;
      for (const OIIO::ParamValue& p : spec.extra_attribs)
        if (p.name().string().starts_with("rt:") && p.type() == OIIO::TypeDesc::STRING)
          header->attributes.emplace_back(p.name().string(), p.get_string());
    }
    const int channels = spec.nchannels;
    std::vector<float> data(static_cast<std::size_t>(spec.width) * spec.height * channels);
    if (!input->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, data.data())) {
      error = first_line(input->geterror());
      return std::nullopt;
    }
    Image image(spec.width, spec.height);
    for (std::size_t i = 0; i < image.pixels.size(); ++i)
      for (int c = 0; c < 3; ++c)  // grey (and grey + alpha): grey replicated
        image.pixels[i][c] = data[i * channels + (channels <= 2 ? 0 : c)];
    return image;
  }

  // Files: a format OpenImageIO reads, judged by the file's signature (ImageInput::valid_file);
  // embedded bytes: a JPEG by its signature, anything else by opening it (a header read). Opening
  // a JPEG would decode it: OpenImageIO's JPEG reader calls jpeg_start_decompress, which for a
  // progressive file (DamagedHelmet's) reads every scan, ~25 ms per 2k texture. An image damaged
  // past its signature samples as white when the render first touches it.
  bool texture_is_readable(const Texture& texture, std::string& reason) const override {
    bool readable = false;
    if (texture.encoded) {
      const std::string extension = encoded_image_extension(*texture.encoded);
      OIIO::Filesystem::IOMemReader reader(texture.encoded->data(), texture.encoded->size());
      readable = extension == ".jpg" ? texture.encoded->size() > 3
                                     : OIIO::ImageInput::open("embedded" + extension, nullptr, &reader) != nullptr;
    } else {
      auto input = OIIO::ImageInput::create(texture.path, /*do_open=*/false);
      readable = input && input->valid_file(texture.path);
    }
    if (!readable) {
      reason = first_line(OIIO::geterror());
      if (reason.empty()) reason = "not a readable image";
    }
    return readable;
  }

  // `texture`'s pixels as float, colour unassociated from alpha; false when it cannot be read.
  // `reader` holds embedded bytes for as long as `image` may read them.
  static bool read_texture_pixels(const Texture& texture, OIIO::ImageBuf& image,
                                  std::optional<OIIO::Filesystem::IOMemReader>& reader) {
    std::string name = texture.path;
    if (texture.encoded) {
      reader.emplace(texture.encoded->data(), texture.encoded->size());
      name = "embedded" + encoded_image_extension(*texture.encoded);
    }
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    image.reset(name, 0, 0, nullptr, &config, reader ? &*reader : nullptr);
    return image.read(0, 0, /*force=*/true, OIIO::TypeDesc::FLOAT);
  }

  std::optional<AlphaImage> read_alpha(const Texture& texture, bool grey_is_alpha) const override {
    std::optional<OIIO::Filesystem::IOMemReader> reader;
    OIIO::ImageBuf image;
    if (!read_texture_pixels(texture, image, reader)) return std::nullopt;
    const OIIO::ImageSpec& spec = image.spec();
    int channel = spec.alpha_channel;
    if (channel < 0 && (spec.nchannels == 2 || spec.nchannels == 4)) channel = spec.nchannels - 1;
    if (channel < 0 && grey_is_alpha) channel = 0;
    if (channel < 0 || spec.width < 1 || spec.height < 1) return std::nullopt;
    AlphaImage result{spec.width, spec.height, std::vector<float>(std::size_t(spec.width) * std::size_t(spec.height))};
    if (!image.get_pixels(OIIO::ROI(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height, 0, 1, channel, channel + 1),
                          OIIO::TypeDesc::FLOAT, result.alpha.data()))
      return std::nullopt;
    return result;
  }

  std::optional<Vec4f> texture_mean(const Texture& texture) const override {
    std::optional<OIIO::Filesystem::IOMemReader> reader;
    OIIO::ImageBuf image;
    if (!read_texture_pixels(texture, image, reader)) return std::nullopt;
    const OIIO::ImageBufAlgo::PixelStats stats = OIIO::ImageBufAlgo::computePixelStats(image);
    const int channels = image.nchannels();
    if (channels < 1 || stats.avg.size() < static_cast<std::size_t>(channels)) return std::nullopt;
    const auto avg = [&](int c) { return static_cast<float>(stats.avg[c]); };
    if (channels <= 2) return Vec4f(avg(0), avg(0), avg(0), channels == 2 ? avg(1) : 1.0f);
    return Vec4f(avg(0), avg(1), avg(2), channels >= 4 ? avg(3) : 1.0f);
  }

  std::unique_ptr<TextureFiles> new_texture_files(std::uint64_t max_memory_bytes) const override {
    return std::make_unique<OiioTextureFiles>(max_memory_bytes);
  }
};

}  // namespace

}  // namespace rt

extern "C" __attribute__((visibility("default"))) const rt::OiioModule* rt_oiio_module() {
  static const rt::Oiio module;
  return &module;
}
