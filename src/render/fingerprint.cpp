#include "rt/render/fingerprint.h"

#include <cstdint>
#include <fstream>
#include <iterator>
#include <string_view>
#include <type_traits>

#include <fmt/format.h>
#include <xxhash.h>
#include <glm/gtc/type_ptr.hpp>

namespace rt {

namespace {

// XXH64 chained: each piece is hashed with the digest so far as its seed. Values are hashed as
// their bytes, which is exact for the padding-free float, double and integer types used here.
class Digest {
 public:
  void bytes(const void* data, std::size_t size) { value_ = XXH64(data, size, value_); }
  template <class T>
  void value(const T& v) {
    static_assert(std::is_arithmetic_v<T>);
    bytes(&v, sizeof v);
  }
  template <class T>  // T: arithmetic, or glm vectors of them (tightly packed)
  void values(const std::vector<T>& v) {
    value(v.size());
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  void text(std::string_view s) {
    value(s.size());
    bytes(s.data(), s.size());
  }
  void color(const Color& c) { bytes(glm::value_ptr(c), sizeof(float) * 3); }
  template <int N>
  void vec(const glm::vec<N, double>& v) { bytes(glm::value_ptr(v), sizeof(double) * N); }
  template <int C, int R>
  void mat(const glm::mat<C, R, double>& m) { bytes(glm::value_ptr(m), sizeof(double) * C * R); }
  std::string hex() const { return fmt::format("{:016x}", value_); }

 private:
  std::uint64_t value_ = 0;
};

// The texture's encoded image: embedded bytes, else the file's bytes, else (unreadable) its path,
// which the renderer reports and renders without.
void add_texture(Digest& digest, const Texture& texture) {
  digest.value(int(texture.empty()));
  if (texture.empty()) return;
  digest.value(int(texture.wrap_s));
  digest.value(int(texture.wrap_t));
  if (texture.encoded) return digest.text(*texture.encoded);
  std::ifstream in(texture.path, std::ios::binary);
  const std::string bytes(std::istreambuf_iterator<char>(in), {});
  digest.text(in ? bytes : texture.path);
}

}  // namespace

std::string scene_fingerprint(const Scene& scene, const FlatScene& flat) {
  Digest digest;
  digest.values(flat.positions);
  digest.values(flat.normals);
  digest.values(flat.texcoords);
  digest.values(flat.triangles);
  digest.values(flat.material_ids);
  digest.value(flat.spheres.size());
  for (const FlatSphere& sphere : flat.spheres) {
    digest.mat(sphere.world_from_object);
    digest.value(sphere.material);
  }
  digest.value(scene.materials.size());
  for (const Material& m : scene.materials) {
    for (const Color& c : {m.ambient, m.diffuse, m.specular, m.emission, m.reflective.value_or(Color(-1.0f))})
      digest.color(c);
    digest.value(m.shininess);
    add_texture(digest, m.diffuse_texture);
    if (m.emits_light) {  // only then, so that the fingerprints of scenes without emitters stay as they were
      digest.text("emits light");
      add_texture(digest, m.emission_texture);
    }
  }
  digest.value(scene.lights.size());
  for (const Light& l : scene.lights) {
    digest.vec(l.position);
    digest.color(l.color);
    digest.vec(l.attenuation);
    digest.vec(l.spot_direction);
    digest.value(l.spot_cos_inner);
    digest.value(l.spot_cos_outer);
  }
  digest.vec(scene.camera.eye);
  digest.vec(scene.camera.target);
  digest.vec(scene.camera.up);
  digest.value(scene.camera.fovy_degrees);
  digest.value(scene.settings.width);
  digest.value(scene.settings.height);
  digest.value(scene.settings.max_depth);
  digest.color(scene.settings.background);
  return digest.hex();
}

}  // namespace rt
