#include "rt/io/image_io.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include "rt/core/error.h"
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

std::unique_ptr<OIIO::ImageOutput> create_output(const std::string& path) {
  auto output = OIIO::ImageOutput::create(path);
  if (!output) {
    OIIO::geterror();  // clear OIIO's pending message; ours says it better
    const std::string ext = lower_extension(path);
    throw InputError(path, "", ext.empty() ? "output file has no extension to choose an image format by"
                                           : fmt::format("unknown image format '{}'", ext));
  }
  return output;
}

}  // namespace

void check_output_path(const std::string& path) {
  create_output(path);
  check_parent_directory_writable(path);
}

void write_image(const Image& image, const std::string& path, const ImageHeader& header) {
  auto output = create_output(path);
  const bool as_float = writes_float(path);
  OIIO::ImageSpec spec(image.width, image.height, 3, as_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
  if (header.data_window) {
    spec.x = header.data_window->x0;
    spec.y = header.data_window->y0;
    spec.full_width = header.full_width;
    spec.full_height = header.full_height;
  }
  for (const auto& [name, value] : header.attributes) spec.attribute(name, value);
  // Lossless, so that merged regions equal a whole render bit for bit (OIIO's default is zip too).
  if (lower_extension(path) == ".exr") spec.attribute("compression", "zip");
  std::vector<std::uint8_t> bytes;
  const void* data = image.pixels.data();
  if (!as_float) {
    bytes = to_rgb8(image);
    data = bytes.data();
  }
  // Encoded in memory, then written with checked system calls: OIIO's file writers can miss a
  // failed write (the PNG writer leaves a truncated file and reports success when the disk fills).
  if (!output->supports("ioproxy"))
    throw InputError(path, "", fmt::format("the '{}' writer cannot encode to memory", output->format_name()));
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput proxy(encoded);
  output->set_ioproxy(&proxy);
  if (!(output->open(path, spec) && output->write_image(spec.format, data) && output->close()))
    throw RuntimeError(fmt::format("{}: cannot encode the image: {}", path, output->geterror()));
  output.reset();
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(encoded.data()), encoded.size()));
}

Image read_image(const std::string& path, ImageHeader* header) {
  auto input = OIIO::ImageInput::open(path);
  if (!input) throw InputError(path, "", fmt::format("cannot read image ({})", OIIO::geterror()));
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
  if (!input->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, data.data()))
    throw InputError(path, "", fmt::format("cannot read image ({})", input->geterror()));
  Image image(spec.width, spec.height);
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) image.pixels[i][c] = data[i * channels + std::min(c, channels - 1)];
  return image;
}

}  // namespace rt
