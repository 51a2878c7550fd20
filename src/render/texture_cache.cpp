#include "render/texture_cache.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <cmath>
#include <map>
#include <tuple>
#include <vector>

#include <xxhash.h>

namespace rt {

namespace fs = std::filesystem;

namespace {

// Up to `limit` bytes of the file at `path` (all of it when 0); nullopt when it cannot be read.
std::optional<std::string> read_file_bytes(const std::string& path, std::size_t limit = 0) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::error_code error;
  const std::uintmax_t size = fs::file_size(path, error);
  if (error) return std::nullopt;
  std::string bytes(limit ? std::min<std::size_t>(limit, size) : std::size_t(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  bytes.resize(static_cast<std::size_t>(in.gcount()));
  return bytes;
}

// What identifies a texture's bytes: embedded ones by size and hash, a file by its path, size
// and modification time (so an edited file is decoded again).
struct TextureKey {
  std::string path;
  std::uint64_t size = 0, stamp = 0;
  bool operator<(const TextureKey& o) const {
    return std::tie(path, size, stamp) < std::tie(o.path, o.size, o.stamp);
  }
};

std::optional<TextureKey> key_of(const Texture& texture) {
  if (texture.encoded) return TextureKey{"", texture.encoded->size(), XXH3_64bits(texture.encoded->data(), texture.encoded->size())};
  std::error_code error;
  const std::uintmax_t size = fs::file_size(texture.path, error);
  if (error) return std::nullopt;
  const auto time = fs::last_write_time(texture.path, error);
  if (error) return std::nullopt;
  return TextureKey{fs::absolute(texture.path, error).string(), size, std::uint64_t(time.time_since_epoch().count())};
}

struct Cache {
  struct Entry {
    std::shared_ptr<const DecodedTexture> texture;
    std::uint64_t last_request = 0;
  };
  std::mutex mutex;
  std::map<TextureKey, Entry> entries;
  std::uint64_t requests = 0;

  // Drops entries only the cache holds, least recently requested first, while more than
  // `budget_bytes` are decoded (or due to be).
  void trim(std::uint64_t budget_bytes) {
    std::uint64_t total = 0;
    std::vector<std::map<TextureKey, Entry>::iterator> unheld;
    for (auto it = entries.begin(); it != entries.end(); ++it) {
      total += it->second.texture->layout().decoded_bytes();
      if (it->second.texture.use_count() == 1) unheld.push_back(it);
    }
    std::sort(unheld.begin(), unheld.end(), [](auto a, auto b) { return a->second.last_request < b->second.last_request; });
    for (auto it : unheld) {
      if (total <= budget_bytes) break;
      total -= it->second.texture->layout().decoded_bytes();
      entries.erase(it);
    }
  }
};

Cache& cache() {
  static Cache instance;
  return instance;
}

// The layout of `texture`'s image from its header when it is a PNG or JPEG rt decodes; nullopt
// with the decoder's reason otherwise.
std::optional<ImageLayout> read_texture_layout(const Texture& texture, std::string& reason) {
  // The header of a JPEG with large EXIF or ICC blocks can run past the first 256 KiB: then the
  // whole file is read.
  constexpr std::size_t kHeaderBytes = 256 * 1024;
  std::optional<std::string> file;
  if (!texture.encoded) file = read_file_bytes(texture.path, kHeaderBytes);
  if (!texture.encoded && !file) {
    reason = "cannot be read";
    return std::nullopt;
  }
  std::string_view bytes = texture.encoded ? std::string_view(*texture.encoded) : std::string_view(*file);
  std::optional<ImageLayout> layout = read_image_layout(bytes, reason);
  if (!layout && file && file->size() == kHeaderBytes && (file = read_file_bytes(texture.path)))
    layout = read_image_layout(*file, reason);
  return layout;
}

}  // namespace

DecodedTexture::DecodedTexture(const Texture& texture, const ImageLayout& layout)
    : path_(texture.encoded ? "" : texture.path), encoded_(texture.encoded), layout_(layout) {}

const DecodedImage* DecodedTexture::decode_once() const {
  std::lock_guard lock(mutex_);
  if (const int state = state_.load(std::memory_order_relaxed); state != kPending) return state == kReady ? &*image_ : nullptr;
  std::string error;
  std::optional<std::string> file;
  if (!encoded_) file = read_file_bytes(path_);
  if (encoded_ || file) image_ = decode_image(encoded_ ? std::string_view(*encoded_) : std::string_view(*file), error);
  // The header may have changed since it was read (a file rewritten in between): trust only it.
  if (image_ && (image_->layout.width != layout_.width || image_->layout.height != layout_.height)) image_.reset();
  encoded_.reset();
  state_.store(image_ ? kReady : kFailed, std::memory_order_release);
  return image_ ? &*image_ : nullptr;
}

int wrap_texel_index(double index, int size, TextureWrap wrap) {
  switch (wrap) {
    case TextureWrap::clamp_to_edge: return int(std::clamp(index, 0.0, double(size - 1)));
    case TextureWrap::mirrored_repeat: {
      const double period = 2.0 * size;
      const double m = index - period * std::floor(index / period);  // [0, 2 size)
      return int(std::clamp(m < size ? m : period - 1.0 - m, 0.0, double(size - 1)));  // clamped: rounding at 1e16
    }
    case TextureWrap::repeat: break;
  }
  return int(std::clamp(index - size * std::floor(index / size), 0.0, double(size - 1)));
}

namespace {

template <typename Texel>
void bilinear(const Texel* texels, const ImageLayout& l, int x0, int x1, int y0, int y1, float tx, float ty, float scale,
              float rgb[3]) {
  const std::size_t channels = std::size_t(l.channels), width = std::size_t(l.width);
  const Texel* row0 = texels + std::size_t(y0) * width * channels;
  const Texel* row1 = texels + std::size_t(y1) * width * channels;
  const std::size_t i0 = std::size_t(x0) * channels, i1 = std::size_t(x1) * channels;
  for (std::size_t c = 0; c < 3; ++c) {
    const std::size_t k = channels <= 2 ? 0 : c;  // grey (and alpha): grey replicated
    const float a = float(row0[i0 + k]) * scale, b = float(row0[i1 + k]) * scale;
    const float d = float(row1[i0 + k]) * scale, e = float(row1[i1 + k]) * scale;
    const float top = (1.0f - tx) * a + tx * b, bottom = (1.0f - tx) * d + tx * e;
    rgb[c] = (1.0f - ty) * top + ty * bottom;
  }
}

}  // namespace

bool sample_bilinear(const DecodedImage& image, TextureWrap wrap_s, TextureWrap wrap_t, Vec2f uv, float rgb[3]) {
  const ImageLayout& l = image.layout;
  // Texel space in double, so that coordinates far outside [0, 1] still resolve to a texel.
  const double x = double(uv.x) * l.width - 0.5, y = double(uv.y) * l.height - 0.5;
  if (!std::isfinite(x) || !std::isfinite(y)) return false;
  const double fx = std::floor(x), fy = std::floor(y);
  const float tx = float(x - fx), ty = float(y - fy);
  const int x0 = wrap_texel_index(fx, l.width, wrap_s), x1 = wrap_texel_index(fx + 1.0, l.width, wrap_s);
  const int y0 = wrap_texel_index(fy, l.height, wrap_t), y1 = wrap_texel_index(fy + 1.0, l.height, wrap_t);
  if (l.bits == 8)
    bilinear(image.texels8.data(), l, x0, x1, y0, y1, tx, ty, 1.0f / 255.0f, rgb);
  else
    bilinear(image.texels16.data(), l, x0, x1, y0, y1, tx, ty, 1.0f / 65535.0f, rgb);
  return true;
}

std::shared_ptr<const DecodedTexture> find_decoded_texture(const Texture& texture, std::uint64_t budget_bytes) {
  const std::optional<TextureKey> key = key_of(texture);
  if (!key) return nullptr;
  Cache& c = cache();
  {
    std::lock_guard lock(c.mutex);
    if (auto it = c.entries.find(*key); it != c.entries.end()) {
      it->second.last_request = ++c.requests;
      return it->second.texture;
    }
  }
  std::string reason;
  const std::optional<ImageLayout> layout = read_texture_layout(texture, reason);
  if (!layout) return nullptr;
  auto decoded = std::make_shared<const DecodedTexture>(texture, *layout);
  std::lock_guard lock(c.mutex);
  auto [it, added] = c.entries.try_emplace(*key, Cache::Entry{decoded, 0});
  it->second.last_request = ++c.requests;
  std::shared_ptr<const DecodedTexture> result = it->second.texture;
  c.trim(budget_bytes);
  return result;
}

}  // namespace rt
