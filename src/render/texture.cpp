#include "rt/render/texture.h"

#include <stdlib.h>  // mkdtemp

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>

namespace rt {

namespace fs = std::filesystem;

namespace {

OIIO::TextureOpt::Wrap oiio_wrap(TextureWrap wrap) {
  switch (wrap) {
    case TextureWrap::clamp_to_edge: return OIIO::TextureOpt::WrapClamp;
    case TextureWrap::mirrored_repeat: return OIIO::TextureOpt::WrapMirror;
    case TextureWrap::repeat: break;
  }
  return OIIO::TextureOpt::WrapPeriodic;
}

// The sRGB transfer function's inverse (IEC 61966-2-1), per channel.
float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// Extension OpenImageIO recognises the encoded bytes by (it also sniffs the content).
std::string image_extension(const std::string& bytes) {
  if (bytes.rfind("\x89PNG", 0) == 0) return ".png";
  if (bytes.rfind("\xFF\xD8", 0) == 0) return ".jpg";
  return ".img";
}

}  // namespace

struct TextureSampler::Impl {
  struct Slot {
    OIIO::TextureSystem::TextureHandle* handle = nullptr;
    OIIO::TextureOpt::Wrap wrap_s = OIIO::TextureOpt::WrapPeriodic, wrap_t = OIIO::TextureOpt::WrapPeriodic;
  };
  // The process-wide shared TextureSystem: OIIO 2.4's TextureSystem::destroy frees a private one with a
  // mismatched sized delete (AddressSanitizer: new-delete-type-mismatch inside libOpenImageIO), while the
  // shared one is never freed by destroy(). Files this sampler opened are invalidated on teardown, so a
  // later sampler re-reads them if they changed on disk.
  OIIO::TextureSystem* system = nullptr;
  std::vector<Slot> slots;            // one per material
  std::vector<std::string> files;     // every file this sampler looked up
  fs::path temp_dir;                  // empty unless an embedded image needed a file

  ~Impl() {
    for (const std::string& file : files) system->invalidate(OIIO::ustring(file));
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
    const std::string path = (temp_dir / (std::to_string(written.size()) + image_extension(*bytes))).string();
    std::ofstream(path, std::ios::binary).write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
    return written[bytes.get()] = path;
  }
};

TextureSampler::TextureSampler(const Scene& scene) : impl_(std::make_unique<Impl>()) {
  impl_->slots.resize(scene.materials.size());
  std::map<const std::string*, std::string> written;
  for (std::size_t i = 0; i < scene.materials.size(); ++i) {
    const Texture& texture = scene.materials[i].diffuse_texture;
    if (texture.empty()) continue;
    if (!impl_->system) {
      impl_->system = OIIO::TextureSystem::create(/*shared=*/true);
      impl_->system->attribute("automip", 0);      // lookups never leave MIP level 0
      impl_->system->attribute("gray_to_rgb", 1);  // grey (+ alpha) images give grey RGB
    }
    const std::string path = texture.encoded ? impl_->file_for(texture.encoded, written) : texture.path;
    if (path.empty()) continue;
    impl_->files.push_back(path);
    Impl::Slot& slot = impl_->slots[i];
    slot.handle = impl_->system->get_texture_handle(OIIO::ustring(path));
    slot.wrap_s = oiio_wrap(texture.wrap_s);
    slot.wrap_t = oiio_wrap(texture.wrap_t);
  }
}

TextureSampler::~TextureSampler() = default;

bool TextureSampler::has_diffuse(std::uint32_t material) const {
  return material < impl_->slots.size() && impl_->slots[material].handle;
}

Color TextureSampler::diffuse(std::uint32_t material, Vec2f uv) const {
  if (!has_diffuse(material)) return Color(1.0f);
  const Impl::Slot& slot = impl_->slots[material];
  OIIO::TextureOpt options;
  options.swrap = slot.wrap_s;
  options.twrap = slot.wrap_t;
  options.mipmode = OIIO::TextureOpt::MipModeNoMIP;
  options.interpmode = OIIO::TextureOpt::InterpBilinear;
  float rgb[3] = {1.0f, 1.0f, 1.0f};
  if (!impl_->system->texture(slot.handle, nullptr, options, uv.x, uv.y, 0, 0, 0, 0, 3, rgb)) return Color(1.0f);
  return {srgb_to_linear(rgb[0]), srgb_to_linear(rgb[1]), srgb_to_linear(rgb[2])};
}

bool texture_is_readable(const Texture& texture, std::string& reason) {
  bool readable = false;
  if (texture.encoded) {
    OIIO::Filesystem::IOMemReader reader(texture.encoded->data(), texture.encoded->size());
    readable = OIIO::ImageInput::open("embedded" + image_extension(*texture.encoded), nullptr, &reader) != nullptr;
  } else {
    std::error_code error;
    if (!fs::is_regular_file(texture.path, error)) {
      reason = "no such file";
      return false;
    }
    readable = OIIO::ImageInput::open(texture.path) != nullptr;
  }
  if (!readable) {
    reason = OIIO::geterror();
    if (reason.empty()) reason = "not a readable image";
    const std::size_t newline = reason.find('\n');
    if (newline != std::string::npos) reason.resize(newline);
  }
  return readable;
}

std::optional<Vec4f> texture_mean(const Texture& texture) {
  std::optional<OIIO::Filesystem::IOMemReader> reader;
  std::string name = texture.path;
  if (texture.encoded) {
    reader.emplace(texture.encoded->data(), texture.encoded->size());
    name = "embedded" + image_extension(*texture.encoded);
  }
  OIIO::ImageBuf image(name, 0, 0, nullptr, nullptr, reader ? &*reader : nullptr);
  if (!image.read(0, 0, /*force=*/true, OIIO::TypeDesc::FLOAT)) return std::nullopt;
  const OIIO::ImageBufAlgo::PixelStats stats = OIIO::ImageBufAlgo::computePixelStats(image);
  const int channels = image.nchannels();
  if (channels < 1 || stats.avg.size() < static_cast<std::size_t>(channels)) return std::nullopt;
  const auto avg = [&](int c) { return static_cast<float>(stats.avg[c]); };
  if (channels <= 2) return Vec4f(avg(0), avg(0), avg(0), channels == 2 ? avg(1) : 1.0f);
  return Vec4f(avg(0), avg(1), avg(2), channels >= 4 ? avg(3) : 1.0f);
}

}  // namespace rt
