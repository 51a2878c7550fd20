#include "rt/io/load_gltf.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <type_traits>

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/render/texture.h"
#include "rt/scene/framing.h"
#include "rt/scene/metallic_roughness.h"
#include "rt/scene/tangents.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

constexpr double kPi = std::numbers::pi;
// Largest accessor element count accepted (keeps a malformed count from exhausting memory).
constexpr std::size_t kMaxAccessorCount = std::size_t(1) << 28;
// Image size used when a perspective camera gives an aspect ratio: height fixed, width follows.
constexpr int kCameraImageHeight = 480;

// A sparse accessor's byteOffset as a size: tinygltf 2.7 (Debian 12) stores it as int, which
// can be negative; 2.9 (Debian 13) as size_t.
template <class Offset>
std::size_t non_negative_size(Offset offset) {
  if constexpr (std::is_signed_v<Offset>)
    return static_cast<std::size_t>(std::max<Offset>(0, offset));
  else
    return offset;
}

// Encoded bytes of images, by image index. tinygltf hands them (external files too) to its image
// loader callback, which keeps them instead of decoding: OpenImageIO decodes. Only data: URIs are
// kept here; external files are read by path and bufferViews by GltfReader::read_texture.
using EmbeddedImages = std::map<int, std::shared_ptr<const std::string>>;

bool keep_encoded_image(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void* user_data) {
  // For a bufferView image, tinygltf 2.7.0 passes a pointer and length it never checked against
  // the buffer (fuzzing found the heap overflow): those bytes are not touched here.
  if (image->bufferView >= 0) return true;
  auto& images = *static_cast<EmbeddedImages*>(user_data);
  images[index] = std::make_shared<const std::string>(reinterpret_cast<const char*>(bytes), static_cast<std::size_t>(size));
  return true;
}

std::string child(const std::string& where, const std::string& key) { return where + "/" + key; }
std::string child(const std::string& where, std::size_t index) { return where + "/" + std::to_string(index); }

// A node instance met while walking the selected scene: the glTF node and where it is.
struct Placed {
  int node;
  Mat4d world_from_node;
};

// Turns a parsed tinygltf model into our scene, checking every index, count and byte range it
// uses and naming the JSON path of each problem.
class GltfReader {
 public:
  GltfReader(std::string path, const tinygltf::Model& model, EmbeddedImages embedded, const GltfOptions& options,
             LoadReport* report)
      : path_(std::move(path)), directory_(fs::path(path_).parent_path()), gltf_(model), embedded_(std::move(embedded)),
        options_(options), report_(report) {}

  Scene read();

 private:
  [[noreturn]] void fail(const std::string& where, const std::string& reason) const {
    throw InputError(path_, where, reason);
  }
  // A --gltf-scene or --camera value this file cannot satisfy: a usage error naming the flag.
  [[noreturn]] void fail_flag(const std::string& reason) const { throw UsageError(path_ + ": " + reason); }
  void count(const std::string& what) { ++skipped_[what]; }
  // " (cameras: 0 'Front', 1 'Side')": what --camera can name, for its error message.
  std::string camera_names() const {
    if (gltf_.cameras.empty()) return " (the file has no cameras)";
    std::string names;
    for (std::size_t i = 0; i < gltf_.cameras.size() && i < 8; ++i)
      names += fmt::format("{}{} '{}'", i == 0 ? "" : ", ", i, gltf_.cameras[i].name);
    return " (cameras: " + names + (gltf_.cameras.size() > 8 ? ", ...)" : ")");
  }

  template <class T>
  const T& element(const std::vector<T>& array, int index, const std::string& array_name, const std::string& where) const {
    if (index < 0 || static_cast<std::size_t>(index) >= array.size())
      fail(where, fmt::format("{} index {} is out of range (the file has {} {})", array_name, index, array.size(),
                              array_name == "mesh" ? "meshes" : array_name + "s"));
    return array[static_cast<std::size_t>(index)];
  }

  const unsigned char* view_bytes(int view_index, std::size_t offset, std::size_t n, std::size_t stride,
                                  std::size_t element_size, const std::string& where) const;
  std::vector<double> read_accessor(int index, const std::string& where, int components);
  std::vector<std::uint32_t> read_indices(int index, const std::string& where, std::size_t vertex_count);
  // The primitive's mesh with the attributes `material` reads (tangents generated when it is normal-mapped).
  std::shared_ptr<const TriangleMesh> read_primitive(int mesh, int primitive, const Material& material);
  const std::vector<Model>& models_of_mesh(int mesh);
  std::uint32_t material_index(int material);
  Material read_material(int index);
  void read_alpha(const tinygltf::Material& source, const std::string& at, Material& material);
  void read_transmission(const tinygltf::Material& source, const std::string& at, const Vec3d& base, double metallic,
                         double ior, Material& material);
  // Material `source`'s extension `extension`'s member `key`, or null when absent; numbers are
  // checked to be finite numbers (`at` is the material's JSON path).
  const tinygltf::Value* extension_value(const tinygltf::Material& source, const std::string& at,
                                         const std::string& extension, const std::string& key, bool number = true) const {
    const auto it = source.extensions.find(extension);
    if (it == source.extensions.end() || !it->second.Has(key)) return nullptr;
    const tinygltf::Value& value = it->second.Get(key);
    if (number && !(value.IsNumber() && std::isfinite(value.GetNumberAsDouble())))
      fail(child(child(child(at, "extensions"), extension), key), "expected a finite number");
    return &value;
  }
  Texture read_texture(const tinygltf::TextureInfo& info, const std::string& where);
  Mat4d read_transform(const tinygltf::Node& node, const std::string& where) const;
  std::vector<int> scene_roots();
  void read_camera(const std::vector<Placed>& placed, Scene& scene);
  void read_lights(const std::vector<Placed>& placed, Scene& scene);

  std::string path_;
  fs::path directory_;
  const tinygltf::Model& gltf_;
  EmbeddedImages embedded_;  // data: URI images from the callback, bufferView images as first read
  const GltfOptions& options_;
  std::map<int, std::vector<Model>> mesh_models_;
  std::map<int, std::uint32_t> material_of_;   // glTF material (-1: default) -> Scene::materials index
  std::vector<Material> materials_;
  std::map<int, bool> image_readable_;
  std::map<std::string, std::size_t> skipped_;  // notice text -> occurrences
  std::vector<std::string> notices_;
  LoadReport* report_ = nullptr;  // receives a made-up camera or headlight; may be null
  Vec3d lo_{std::numeric_limits<double>::infinity()}, hi_{-std::numeric_limits<double>::infinity()};
};

int component_size(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

// One component at `p`, converted as glTF says: normalized integers map to [0, 1] or [-1, 1].
double read_component(const unsigned char* p, int type, bool normalized) {
  auto get = [p]<class T>(T) {
    T value;
    std::memcpy(&value, p, sizeof(T));
    return value;
  };
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return normalized ? std::max(get(std::int8_t()) / 127.0, -1.0) : get(std::int8_t());
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? get(std::uint8_t()) / 255.0 : get(std::uint8_t());
    case TINYGLTF_COMPONENT_TYPE_SHORT: return normalized ? std::max(get(std::int16_t()) / 32767.0, -1.0) : get(std::int16_t());
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return normalized ? get(std::uint16_t()) / 65535.0 : get(std::uint16_t());
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return normalized ? get(std::uint32_t()) / 4294967295.0 : get(std::uint32_t());
    default: return get(float());
  }
}

// Bytes [offset, offset + (n - 1) stride + element_size) of bufferView `view_index`, after checking
// that they lie inside the view and the view inside its buffer; `where` names the JSON path that
// asked for them.
const unsigned char* GltfReader::view_bytes(int view_index, std::size_t offset, std::size_t n, std::size_t stride,
                                            std::size_t element_size, const std::string& where) const {
  const tinygltf::BufferView& view = element(gltf_.bufferViews, view_index, "bufferView", where);
  const std::string view_at = child("/bufferViews", static_cast<std::size_t>(view_index));
  const tinygltf::Buffer& buffer = element(gltf_.buffers, view.buffer, "buffer", child(view_at, "buffer"));
  if (view.byteOffset > buffer.data.size() || view.byteLength > buffer.data.size() - view.byteOffset)
    fail(view_at, fmt::format("bytes {}..{} lie outside buffer {} ({} bytes)", view.byteOffset,
                              view.byteOffset + view.byteLength, view.buffer, buffer.data.size()));
  const std::size_t needed = n == 0 ? 0 : offset + (n - 1) * stride + element_size;
  if (n > 0 && (offset > view.byteLength || needed > view.byteLength || (n - 1) * stride / stride != n - 1))
    fail(where, fmt::format("{} elements of {} bytes (stride {}) from byte {} need {} bytes; bufferView {} has {}", n,
                            element_size, stride, offset, needed, view_index, view.byteLength));
  return buffer.data.data() + view.byteOffset + offset;
}

// Reads accessor `index` (referenced from `where`) as `components` doubles per element, sparse
// substitutions applied. Every byte range is checked against its bufferView and buffer.
std::vector<double> GltfReader::read_accessor(int index, const std::string& where, int components) {
  const tinygltf::Accessor& accessor = element(gltf_.accessors, index, "accessor", where);
  const std::string at = child("/accessors", static_cast<std::size_t>(index));
  const int size = component_size(accessor.componentType);
  if (size == 0) fail(child(at, "componentType"), fmt::format("invalid component type {}", accessor.componentType));
  if (tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(accessor.type)) != components)
    fail(child(at, "type"), fmt::format("expected {} components per element (used by {})", components, where));
  if (accessor.count > kMaxAccessorCount) fail(child(at, "count"), fmt::format("count {} exceeds the supported maximum {} (2^28)", accessor.count, kMaxAccessorCount));
  const std::size_t count = accessor.count, element_size = static_cast<std::size_t>(size * components);

  std::vector<double> values(count * components, 0.0);
  if (accessor.bufferView >= 0) {
    const tinygltf::BufferView& view = element(gltf_.bufferViews, accessor.bufferView, "bufferView", child(at, "bufferView"));
    const std::size_t stride = view.byteStride == 0 ? element_size : view.byteStride;
    if (stride < element_size)
      fail(child(child("/bufferViews", static_cast<std::size_t>(accessor.bufferView)), "byteStride"),
           fmt::format("stride {} is smaller than the {}-byte elements of accessor {}", stride, element_size, index));
    const unsigned char* data = view_bytes(accessor.bufferView, accessor.byteOffset, count, stride, element_size, at);
    for (std::size_t i = 0; i < count; ++i)
      for (int c = 0; c < components; ++c)
        values[i * components + c] = read_component(data + i * stride + c * size, accessor.componentType, accessor.normalized);
  }
  if (accessor.sparse.isSparse) {
    const std::string sparse_at = child(at, "sparse");
    const auto& sparse = accessor.sparse;
    if (sparse.count < 0 || static_cast<std::size_t>(sparse.count) > count)
      fail(child(sparse_at, "count"), fmt::format("sparse count {} exceeds the accessor's count {}", sparse.count, count));
    const auto n = static_cast<std::size_t>(sparse.count);
    const int index_size = component_size(sparse.indices.componentType);
    if (index_size == 0 || sparse.indices.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
        sparse.indices.componentType == TINYGLTF_COMPONENT_TYPE_BYTE ||
        sparse.indices.componentType == TINYGLTF_COMPONENT_TYPE_SHORT)
      fail(child(child(sparse_at, "indices"), "componentType"), "sparse indices must be unsigned integers");
    const unsigned char* indices =
        view_bytes(sparse.indices.bufferView, non_negative_size(sparse.indices.byteOffset), n,
                   index_size, index_size, child(sparse_at, "indices"));
    const unsigned char* substitutes =
        view_bytes(sparse.values.bufferView, non_negative_size(sparse.values.byteOffset), n,
                   element_size, element_size, child(sparse_at, "values"));
    for (std::size_t k = 0; k < n; ++k) {
      const double target = read_component(indices + k * index_size, sparse.indices.componentType, false);
      if (target >= static_cast<double>(count))
        fail(child(sparse_at, "indices"), fmt::format("sparse index {} is out of range (count {})", target, count));
      const auto i = static_cast<std::size_t>(target);
      for (int c = 0; c < components; ++c)
        values[i * components + c] =
            read_component(substitutes + k * element_size + c * size, accessor.componentType, accessor.normalized);
    }
  }
  for (double v : values)
    if (!std::isfinite(v)) fail(at, "a value is not finite");
  return values;
}

std::vector<std::uint32_t> GltfReader::read_indices(int index, const std::string& where, std::size_t vertex_count) {
  const tinygltf::Accessor& accessor = element(gltf_.accessors, index, "accessor", where);
  if (accessor.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      accessor.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      accessor.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
    fail(where, fmt::format("accessor {} has component type {}; indices must be unsigned integers", index,
                            accessor.componentType));
  const std::vector<double> values = read_accessor(index, where, 1);
  std::vector<std::uint32_t> indices(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (values[i] >= static_cast<double>(vertex_count))
      fail(where, fmt::format("index {} (element {} of accessor {}) is out of range: POSITION has {} vertices",
                              values[i], i, index, vertex_count));
    indices[i] = static_cast<std::uint32_t>(values[i]);
  }
  return indices;
}

std::shared_ptr<const TriangleMesh> GltfReader::read_primitive(int mesh_index, int primitive_index,
                                                              const Material& material) {
  const tinygltf::Primitive& primitive =
      gltf_.meshes[static_cast<std::size_t>(mesh_index)].primitives[static_cast<std::size_t>(primitive_index)];
  const std::string where = child(child(child("/meshes", static_cast<std::size_t>(mesh_index)), "primitives"),
                                  static_cast<std::size_t>(primitive_index));
  const auto attribute = [&](const char* name) {
    const auto it = primitive.attributes.find(name);
    return it == primitive.attributes.end() ? -1 : it->second;
  };
  const int position_accessor = attribute("POSITION");
  if (position_accessor < 0) fail(child(where, "attributes"), "primitive has no POSITION attribute");
  const std::vector<double> positions = read_accessor(position_accessor, child(where, "attributes/POSITION"), 3);
  const std::size_t vertex_count = positions.size() / 3;
  // An attribute with `components` numbers per vertex, or nothing when absent.
  const auto read_vertex_attribute = [&](const char* name, int components) {
    std::vector<double> values;
    if (attribute(name) < 0) return values;
    const std::string at = child(where, std::string("attributes/") + name);
    values = read_accessor(attribute(name), at, components);
    if (values.size() / std::size_t(components) != vertex_count)
      fail(at, fmt::format("{} values for {} positions", values.size() / std::size_t(components), vertex_count));
    return values;
  };
  // Which coordinate sets the material's textures read (its alpha is the base colour texture's),
  // and whether it is normal-mapped.
  bool wants_set[2] = {false, false};
  for (int role = 0; role < kTextureRoleCount; ++role)
    if (const Texture* texture = texture_for(material, static_cast<TextureRole>(role)); texture && !texture->empty())
      wants_set[texture->texcoord] = true;
  const bool normal_mapped = !material.normal_texture.empty();

  const std::vector<double> normals = read_vertex_attribute("NORMAL", 3);
  const std::vector<double> texcoords = wants_set[0] ? read_vertex_attribute("TEXCOORD_0", 2) : std::vector<double>{};
  const std::vector<double> texcoords1 = wants_set[1] ? read_vertex_attribute("TEXCOORD_1", 2) : std::vector<double>{};
  // COLOR_0 is RGB or RGBA (linear; float or normalised integers).
  std::vector<double> colors;
  int color_components = 4;
  if (attribute("COLOR_0") >= 0) {
    const tinygltf::Accessor& accessor = element(gltf_.accessors, attribute("COLOR_0"), "accessor",
                                                 child(where, "attributes/COLOR_0"));
    color_components = accessor.type == TINYGLTF_TYPE_VEC3 ? 3 : 4;
    colors = read_vertex_attribute("COLOR_0", color_components);
  }
  // TANGENT only matters under a normal map, and only with the normals it was made for.
  const std::vector<double> tangents =
      normal_mapped && !normals.empty() ? read_vertex_attribute("TANGENT", 4) : std::vector<double>{};

  std::vector<std::uint32_t> indices;
  if (primitive.indices >= 0) {
    indices = read_indices(primitive.indices, child(where, "indices"), vertex_count);
  } else {
    indices.resize(vertex_count);
    for (std::size_t i = 0; i < vertex_count; ++i) indices[i] = static_cast<std::uint32_t>(i);
  }

  // Corner triples in the mode's order (glTF 2.0 section 3.7.2.1), counter-clockwise.
  std::vector<Vec3u> corners;
  const int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
  const std::size_t n = indices.size();
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    for (std::size_t i = 0; i + 2 < n; i += 3) corners.push_back({indices[i], indices[i + 1], indices[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    for (std::size_t i = 0; i + 2 < n; ++i)
      corners.push_back(i % 2 == 0 ? Vec3u(indices[i], indices[i + 1], indices[i + 2])
                                   : Vec3u(indices[i + 1], indices[i], indices[i + 2]));
  } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
    for (std::size_t i = 1; i + 1 < n; ++i) corners.push_back({indices[i], indices[i + 1], indices[0]});
  } else {
    fail(child(where, "mode"), fmt::format("invalid primitive mode {}", mode));
  }

  auto mesh = std::make_shared<TriangleMesh>();
  const auto position = [&](std::uint32_t i) { return Vec3f(Vec3d(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2])); };
  // Vertex i's optional attributes, appended to the mesh.
  const auto append_attributes = [&](std::uint32_t i) {
    if (!texcoords.empty()) mesh->texcoords.push_back(Vec2f(Vec2d(texcoords[2 * i], texcoords[2 * i + 1])));
    if (!texcoords1.empty()) mesh->texcoords1.push_back(Vec2f(Vec2d(texcoords1[2 * i], texcoords1[2 * i + 1])));
    if (!colors.empty()) {
      const std::size_t c = std::size_t(color_components) * i;
      const auto unit = [](double v) { return static_cast<float>(std::clamp(v, 0.0, 1.0)); };  // the spec's range
      mesh->colors.emplace_back(unit(colors[c]), unit(colors[c + 1]), unit(colors[c + 2]),
                                color_components == 4 ? unit(colors[c + 3]) : 1.0f);
    }
    if (!tangents.empty())
      mesh->tangents.emplace_back(float(tangents[4 * i]), float(tangents[4 * i + 1]), float(tangents[4 * i + 2]),
                                  tangents[4 * i + 3] < 0.0 ? -1.0f : 1.0f);
  };
  if (!normals.empty()) {
    for (std::uint32_t i = 0; i < vertex_count; ++i) {
      mesh->positions.push_back(position(i));
      const Vec3d normal(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]);
      const double length = glm::length(normal);
      mesh->normals.push_back(length > 0.0 ? Vec3f(normal / length) : Vec3f(0.0f, 0.0f, 1.0f));
      append_attributes(i);
    }
    mesh->triangles = std::move(corners);
  } else {
    // Without normals glTF asks for flat shading: each triangle gets its own corners and face normal.
    for (const Vec3u& t : corners) {
      const Vec3f p0 = position(t.x), p1 = position(t.y), p2 = position(t.z);
      const Vec3d face = glm::cross(Vec3d(p1) - Vec3d(p0), Vec3d(p2) - Vec3d(p0));
      const double length = glm::length(face);
      const Vec3f normal = length > 0.0 ? Vec3f(face / length) : Vec3f(0.0f, 0.0f, 1.0f);
      const auto base = static_cast<std::uint32_t>(mesh->positions.size());
      for (std::uint32_t corner : {t.x, t.y, t.z}) {
        mesh->positions.push_back(position(corner));
        mesh->normals.push_back(normal);
        append_attributes(corner);
      }
      mesh->triangles.push_back({base, base + 1, base + 2});
    }
  }
  // The spec: without TANGENT, MikkTSpace tangents from the normal texture's coordinates.
  if (normal_mapped && mesh->tangents.empty()) {
    const bool set1 = material.normal_texture.texcoord == 1;
    if ((set1 ? mesh->texcoords1 : mesh->texcoords).empty()) {
      count("normal maps on primitives without their texture coordinates ignored");
    } else {
      if (set1) std::swap(mesh->texcoords, mesh->texcoords1);
      if (generate_tangents(*mesh) > 0) count("triangles with degenerate texture coordinates left flat under normal maps");
      if (set1) std::swap(mesh->texcoords, mesh->texcoords1);
    }
  }
  return mesh;
}

const std::vector<Model>& GltfReader::models_of_mesh(int mesh_index) {
  if (auto it = mesh_models_.find(mesh_index); it != mesh_models_.end()) return it->second;
  std::vector<Model> models;
  const tinygltf::Mesh& mesh = gltf_.meshes[static_cast<std::size_t>(mesh_index)];
  for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
    const tinygltf::Primitive& primitive = mesh.primitives[p];
    const int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
    if (mode == TINYGLTF_MODE_POINTS || mode == TINYGLTF_MODE_LINE || mode == TINYGLTF_MODE_LINE_LOOP ||
        mode == TINYGLTF_MODE_LINE_STRIP) {
      count("primitive(s) of points or lines skipped (not surfaces)");
      continue;
    }
    if (primitive.material >= 0)
      element(gltf_.materials, primitive.material, "material",
              child(child(child(child("/meshes", static_cast<std::size_t>(mesh_index)), "primitives"), p), "material"));
    const std::uint32_t material = material_index(primitive.material);
    models.push_back({read_primitive(mesh_index, static_cast<int>(p), materials_[material]), material});
  }
  return mesh_models_[mesh_index] = std::move(models);
}

std::uint32_t GltfReader::material_index(int material) {
  if (auto it = material_of_.find(material); it != material_of_.end()) return it->second;
  materials_.push_back(read_material(material));
  return material_of_[material] = static_cast<std::uint32_t>(materials_.size() - 1);
}

// A TextureInfo for the index, texCoord and extensions of a normal or occlusion texture info.
tinygltf::TextureInfo texture_info(int index, int texcoord, const tinygltf::ExtensionMap& extensions) {
  tinygltf::TextureInfo info;
  info.index = index;
  info.texCoord = texcoord;
  info.extensions = extensions;
  return info;
}

Texture GltfReader::read_texture(const tinygltf::TextureInfo& info, const std::string& where) {
  int texcoord = info.texCoord;
  TextureTransform transform;
  if (auto it = info.extensions.find("KHR_texture_transform"); it != info.extensions.end()) {
    const tinygltf::Value& extension = it->second;
    const std::string at = child(where, "extensions/KHR_texture_transform");
    const auto pair = [&](const char* key, Vec2f fallback) {
      if (!extension.Has(key)) return fallback;
      const tinygltf::Value& value = extension.Get(key);
      if (!value.IsArray() || value.ArrayLen() != 2 || !value.Get(0).IsNumber() || !value.Get(1).IsNumber())
        fail(child(at, key), "expected 2 numbers");
      const Vec2f result(float(value.Get(0).GetNumberAsDouble()), float(value.Get(1).GetNumberAsDouble()));
      if (!std::isfinite(result.x) || !std::isfinite(result.y)) fail(child(at, key), "expected finite numbers");
      return result;
    };
    transform.offset = pair("offset", Vec2f(0.0f));
    transform.scale = pair("scale", Vec2f(1.0f));
    if (extension.Has("rotation")) {
      if (!extension.Get("rotation").IsNumber()) fail(child(at, "rotation"), "expected a number");
      transform.rotation = float(extension.Get("rotation").GetNumberAsDouble());
      if (!std::isfinite(transform.rotation)) fail(child(at, "rotation"), "expected a finite number");
    }
    if (extension.Has("texCoord")) {  // overrides the textureInfo's
      if (!extension.Get("texCoord").IsInt()) fail(child(at, "texCoord"), "expected an integer");
      texcoord = extension.Get("texCoord").GetNumberAsInt();
    }
  }
  if (texcoord < 0) fail(child(where, "texCoord"), fmt::format("{} is negative", texcoord));
  if (texcoord > 1) {
    count("textures on TEXCOORD_2 or higher not applied (TEXCOORD_0 and TEXCOORD_1 are read)");
    return {};
  }
  const tinygltf::Texture& texture = element(gltf_.textures, info.index, "texture", child(where, "index"));
  const std::string texture_at = child("/textures", static_cast<std::size_t>(info.index));
  if (texture.source < 0) {
    count("textures without an image source not applied");
    return {};
  }
  const tinygltf::Image& image = element(gltf_.images, texture.source, "image", child(texture_at, "source"));
  Texture result;
  if (!image.uri.empty()) {  // tinygltf keeps the uri of external files only, not of data: URIs
    result.path = (directory_ / decode_gltf_uri(image.uri)).string();
  } else if (image.bufferView >= 0) {
    auto [it, inserted] = embedded_.try_emplace(texture.source);
    if (inserted) {
      const std::string view_at = child(child("/images", static_cast<std::size_t>(texture.source)), "bufferView");
      const std::size_t length = element(gltf_.bufferViews, image.bufferView, "bufferView", view_at).byteLength;
      const unsigned char* bytes = view_bytes(image.bufferView, 0, length, 1, 1, view_at);
      it->second = std::make_shared<const std::string>(reinterpret_cast<const char*>(bytes), length);
    }
    result.encoded = it->second;
    result.path = fmt::format("{}#/images/{}", path_, texture.source);
  } else if (auto it = embedded_.find(texture.source); it != embedded_.end()) {
    result.encoded = it->second;
    result.path = fmt::format("{}#/images/{}", path_, texture.source);
  } else {
    count("textures whose image could not be loaded not applied (base colour used)");
    return {};
  }
  if (texture.sampler >= 0) {
    const tinygltf::Sampler& sampler = element(gltf_.samplers, texture.sampler, "sampler", child(texture_at, "sampler"));
    const auto wrap = [](int mode) {
      if (mode == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return TextureWrap::clamp_to_edge;
      if (mode == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return TextureWrap::mirrored_repeat;
      return TextureWrap::repeat;
    };
    result.wrap_s = wrap(sampler.wrapS);
    result.wrap_t = wrap(sampler.wrapT);
  }
  result.texcoord = texcoord;
  result.transform = transform;
  auto [readable, inserted] = image_readable_.try_emplace(texture.source, true);
  if (inserted) {
    std::string reason;
    readable->second = texture_is_readable(result, reason);
    if (!readable->second)
      notices_.push_back(fmt::format("{}: {}: texture image cannot be read ({}); using the factor alone",
                                     path_, child("/images", static_cast<std::size_t>(texture.source)),
                                     image.uri.empty() ? reason : image.uri + ": " + reason));
  }
  return readable->second ? result : Texture{};
}

// alphaMode MASK and BLEND (docs/alpha.md): alpha = baseColorFactor's alpha x the base colour
// texture's alpha channel; OPAQUE ignores it, as the spec says.
void GltfReader::read_alpha(const tinygltf::Material& source, const std::string& at, Material& material) {
  if (source.alphaMode == "OPAQUE") return;
  if (source.alphaMode != "MASK" && source.alphaMode != "BLEND")
    fail(child(at, "alphaMode"), fmt::format("'{}' is not OPAQUE, MASK or BLEND", source.alphaMode));
  material.alpha_mode = source.alphaMode == "MASK" ? AlphaMode::mask : AlphaMode::blend;
  const double alpha = source.pbrMetallicRoughness.baseColorFactor[3];
  if (!(alpha >= 0.0 && alpha <= 1.0))
    fail(child(at, "pbrMetallicRoughness/baseColorFactor"), fmt::format("alpha {} is outside [0, 1]", alpha));
  material.alpha = static_cast<float>(alpha);
  if (!(source.alphaCutoff >= 0.0)) fail(child(at, "alphaCutoff"), "must be >= 0");
  material.alpha_cutoff = static_cast<float>(source.alphaCutoff);
  material.alpha_texture = material.diffuse_texture;  // the base colour texture's alpha channel
}

// KHR_materials_transmission (+ KHR_materials_volume): the glass share of a material whose
// opaque part read_material has set up (docs/glass.md). Metals transmit nothing (the spec weights
// transmission by 1 - metallic). A volume of thickness 0, or none, is the spec's thin wall.
void GltfReader::read_transmission(const tinygltf::Material& source, const std::string& at, const Vec3d& base,
                                   double metallic, double ior, Material& material) {
  const std::string transmission_at = child(at, "extensions/KHR_materials_transmission");
  double factor = 0.0;
  if (const tinygltf::Value* value = extension_value(source, at, "KHR_materials_transmission", "transmissionFactor")) {
    factor = value->GetNumberAsDouble();
    if (!(factor >= 0.0 && factor <= 1.0))
      fail(child(transmission_at, "transmissionFactor"), fmt::format("{} is outside [0, 1]", factor));
  }
  factor *= 1.0 - metallic;
  if (!(factor > 0.0) || base == Vec3d(0.0)) return;
  material.transmission = Color(base);
  material.transmission_factor = static_cast<float>(factor);
  material.transmission_mix = true;
  material.ior = static_cast<float>(ior);
  const tinygltf::Value& extension = source.extensions.at("KHR_materials_transmission");
  if (extension.Has("transmissionTexture")) {
    tinygltf::TextureInfo info;
    const tinygltf::Value& texture = extension.Get("transmissionTexture");
    if (!texture.Get("index").IsInt()) fail(child(transmission_at, "transmissionTexture/index"), "expected an integer");
    info.index = texture.Get("index").GetNumberAsInt();
    if (texture.Has("texCoord")) info.texCoord = texture.Get("texCoord").GetNumberAsInt();
    material.transmission_texture = read_texture(info, child(transmission_at, "transmissionTexture"));
  }

  material.thin_walled = true;
  const std::string volume_at = child(at, "extensions/KHR_materials_volume");
  if (const tinygltf::Value* value = extension_value(source, at, "KHR_materials_volume", "thicknessFactor")) {
    if (!(value->GetNumberAsDouble() >= 0.0)) fail(child(volume_at, "thicknessFactor"), "must be >= 0");
    material.thin_walled = !(value->GetNumberAsDouble() > 0.0);
  }
  if (material.thin_walled) return;
  if (const tinygltf::Value* value = extension_value(source, at, "KHR_materials_volume", "attenuationDistance")) {
    const double distance = value->GetNumberAsDouble();
    if (!(distance > 0.0)) fail(child(volume_at, "attenuationDistance"), "must be > 0");
    material.attenuation_distance = static_cast<float>(distance);
  }
  if (const tinygltf::Value* value = extension_value(source, at, "KHR_materials_volume", "attenuationColor", false)) {
    Vec3d color(1.0);
    if (!value->IsArray() || value->ArrayLen() != 3) fail(child(volume_at, "attenuationColor"), "expected 3 numbers");
    for (int c = 0; c < 3; ++c) {
      if (!value->Get(c).IsNumber()) fail(child(volume_at, "attenuationColor"), "expected 3 numbers");
      color[c] = value->Get(c).GetNumberAsDouble();
      if (!(color[c] >= 0.0 && color[c] <= 1.0))
        fail(child(volume_at, "attenuationColor"), "components must be in [0, 1]");
    }
    material.attenuation_color = Color(color);
  }
}

// pbrMetallicRoughness -> Blinn-Phong; the mapping and its reasons are in docs/scene-formats.md.
Material GltfReader::read_material(int index) {
  Material material;
  if (index < 0) {
    // The spec's default: white base colour, metallic 1, roughness 1, single-sided.
    material.name = "<default>";
    const PhongTerms terms = phong_from_metallic_roughness(Vec3d(1.0), 1.0, 1.0, 0.04);
    material.diffuse = Color(terms.diffuse);
    material.specular = Color(terms.specular);
    material.shininess = static_cast<float>(terms.shininess);
    material.reflective = Color(terms.reflective);
    material.back_face = BackFace::culled;
    return material;
  }
  const tinygltf::Material& source = gltf_.materials[static_cast<std::size_t>(index)];
  const std::string at = child("/materials", static_cast<std::size_t>(index));
  const tinygltf::PbrMetallicRoughness& pbr = source.pbrMetallicRoughness;
  material.name = source.name.empty() ? fmt::format("material {}", index) : source.name;
  if (pbr.baseColorFactor.size() != 4) fail(child(at, "pbrMetallicRoughness/baseColorFactor"), "expected 4 numbers");
  Vec3d base(pbr.baseColorFactor[0], pbr.baseColorFactor[1], pbr.baseColorFactor[2]);
  const double metallic = std::clamp(pbr.metallicFactor, 0.0, 1.0), roughness = std::clamp(pbr.roughnessFactor, 0.0, 1.0);
  if (pbr.baseColorTexture.index >= 0)
    material.diffuse_texture = read_texture(pbr.baseColorTexture, child(at, "pbrMetallicRoughness/baseColorTexture"));
  Texture metallic_roughness_texture;
  if (pbr.metallicRoughnessTexture.index >= 0)
    metallic_roughness_texture =
        read_texture(pbr.metallicRoughnessTexture, child(at, "pbrMetallicRoughness/metallicRoughnessTexture"));
  if (source.normalTexture.index >= 0) {
    material.normal_texture =
        read_texture(texture_info(source.normalTexture.index, source.normalTexture.texCoord, source.normalTexture.extensions),
                     child(at, "normalTexture"));
    material.normal_scale = static_cast<float>(source.normalTexture.scale);
    if (!std::isfinite(material.normal_scale)) fail(child(at, "normalTexture/scale"), "expected a finite number");
  }
  if (source.occlusionTexture.index >= 0) {
    material.occlusion_texture = read_texture(
        texture_info(source.occlusionTexture.index, source.occlusionTexture.texCoord, source.occlusionTexture.extensions),
        child(at, "occlusionTexture"));
    material.occlusion_strength = static_cast<float>(source.occlusionTexture.strength);
    if (!(material.occlusion_strength >= 0.0f && material.occlusion_strength <= 1.0f))
      fail(child(at, "occlusionTexture/strength"), fmt::format("{} is outside [0, 1]", material.occlusion_strength));
  }
  read_alpha(source, at, material);
  // The spec: a single-sided material's back faces are culled; a double-sided one's are lit with
  // the normal reversed.
  material.back_face = source.doubleSided ? BackFace::flipped : BackFace::culled;

  // KHR_materials_ior: the dielectric's index, which also sets its normal-incidence reflectance
  // ((n - 1) / (n + 1))^2 (0.04 at the default 1.5).
  double ior = 1.5;
  if (const tinygltf::Value* value = extension_value(source, at, "KHR_materials_ior", "ior")) {
    ior = value->GetNumberAsDouble();
    if (!(ior >= 1.0 && ior <= 10.0))
      fail(child(at, "extensions/KHR_materials_ior/ior"), fmt::format("ior {} is outside [1, 10]", ior));
  }
  const double dielectric_f0 = ((ior - 1.0) / (ior + 1.0)) * ((ior - 1.0) / (ior + 1.0));
  const PhongTerms terms = phong_from_metallic_roughness(base, metallic, roughness, dielectric_f0);
  material.diffuse = Color(terms.diffuse);
  material.specular = Color(terms.specular);
  material.shininess = static_cast<float>(terms.shininess);
  material.reflective = Color(terms.reflective);
  // Per hit where the terms vary: with a metallic-roughness texture, or a metal whose base colour
  // varies (its highlight and mirror take that colour). A dielectric's vary only in the diffuse
  // term, which the diffuse texture and vertex colours multiply on the constant path.
  if (!metallic_roughness_texture.empty() || (metallic > 0.0 && !material.diffuse_texture.empty())) {
    MetallicRoughness inputs;
    inputs.base_color = Color(base);
    inputs.metallic = static_cast<float>(metallic);
    inputs.roughness = static_cast<float>(roughness);
    inputs.dielectric_f0 = static_cast<float>(dielectric_f0);
    inputs.texture = metallic_roughness_texture;
    material.metallic_roughness = inputs;
  }

  // Per hit, the shader weights the glass share by 1 - metallic itself.
  read_transmission(source, at, base, material.metallic_roughness ? 0.0 : metallic, ior, material);

  if (source.emissiveFactor.size() != 3) fail(child(at, "emissiveFactor"), "expected 3 numbers");
  Vec3d emission(source.emissiveFactor[0], source.emissiveFactor[1], source.emissiveFactor[2]);
  if (auto it = source.extensions.find("KHR_materials_emissive_strength"); it != source.extensions.end()) {
    const tinygltf::Value& strength = it->second.Get("emissiveStrength");
    if (strength.IsNumber()) {
      if (!(strength.GetNumberAsDouble() >= 0.0))
        fail(child(at, "extensions/KHR_materials_emissive_strength/emissiveStrength"), "must be >= 0");
      emission *= strength.GetNumberAsDouble();
    }
  }
  if (glm::any(glm::lessThan(emission, Vec3d(0.0))) || glm::any(glm::lessThan(base, Vec3d(0.0))))
    fail(at, "colour factors must be >= 0");
  // Emission is radiance leaving the front side (docs/area-lights.md): the material is an area light,
  // its texture (sRGB, sampled per hit and per light sample) modulating the factor.
  material.emission = Color(emission);
  material.emits_light = material.emission != Color(0.0f);
  if (material.emits_light && source.emissiveTexture.index >= 0)
    material.emission_texture = read_texture(source.emissiveTexture, child(at, "emissiveTexture"));
  return material;
}

Mat4d GltfReader::read_transform(const tinygltf::Node& node, const std::string& where) const {
  if (!node.matrix.empty()) {
    if (node.matrix.size() != 16) fail(child(where, "matrix"), "expected 16 numbers");
    return glm::make_mat4(node.matrix.data());  // column-major, as glm stores it
  }
  Mat4d transform(1.0);
  if (!node.translation.empty()) {
    if (node.translation.size() != 3) fail(child(where, "translation"), "expected 3 numbers");
    transform = glm::translate(transform, Vec3d(node.translation[0], node.translation[1], node.translation[2]));
  }
  if (!node.rotation.empty()) {
    if (node.rotation.size() != 4) fail(child(where, "rotation"), "expected 4 numbers (x, y, z, w)");
    const glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    const double length = glm::length(q);
    if (!(length > 0.0) || !std::isfinite(length)) fail(child(where, "rotation"), "quaternion is zero or not finite");
    transform *= glm::mat4_cast(q / length);
  }
  if (!node.scale.empty()) {
    if (node.scale.size() != 3) fail(child(where, "scale"), "expected 3 numbers");
    transform = glm::scale(transform, Vec3d(node.scale[0], node.scale[1], node.scale[2]));
  }
  return transform;
}

std::vector<int> GltfReader::scene_roots() {
  const std::size_t scene_count = gltf_.scenes.size();
  int chosen = -1;
  if (options_.scene) {
    if (*options_.scene < 0 || static_cast<std::size_t>(*options_.scene) >= scene_count)
      fail_flag(fmt::format("--gltf-scene {} is out of range (the file has {} scene(s))", *options_.scene, scene_count));
    chosen = *options_.scene;
  } else if (gltf_.defaultScene >= 0) {
    element(gltf_.scenes, gltf_.defaultScene, "scene", "/scene");
    chosen = gltf_.defaultScene;
  } else if (scene_count > 0) {
    chosen = 0;
  }
  std::vector<int> roots;
  if (chosen >= 0) {
    const std::string at = child("/scenes", static_cast<std::size_t>(chosen));
    const std::vector<int>& nodes = gltf_.scenes[static_cast<std::size_t>(chosen)].nodes;
    for (std::size_t i = 0; i < nodes.size(); ++i) element(gltf_.nodes, nodes[i], "node", child(child(at, "nodes"), i));
    return nodes;
  }
  // No scenes at all: every node that is nobody's child is a root.
  std::vector<bool> is_child(gltf_.nodes.size(), false);
  for (const tinygltf::Node& node : gltf_.nodes)
    for (int c : node.children)
      if (c >= 0 && static_cast<std::size_t>(c) < is_child.size()) is_child[static_cast<std::size_t>(c)] = true;
  for (std::size_t i = 0; i < is_child.size(); ++i)
    if (!is_child[i]) roots.push_back(static_cast<int>(i));
  if (!gltf_.nodes.empty()) notices_.push_back(fmt::format("{}: the file has no scenes: showing every root node", path_));
  return roots;
}

void GltfReader::read_camera(const std::vector<Placed>& placed, Scene& scene) {
  const auto is_placed = [&](int camera) {
    for (const Placed& p : placed)
      if (gltf_.nodes[static_cast<std::size_t>(p.node)].camera == camera) return &p;
    return static_cast<const Placed*>(nullptr);
  };
  const Placed* chosen = nullptr;
  int camera = -1;
  if (!options_.camera.empty()) {
    const std::string& wanted = options_.camera;
    if (std::all_of(wanted.begin(), wanted.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
      camera = wanted.size() < 9 ? std::stoi(wanted) : -1;
      if (camera < 0 || static_cast<std::size_t>(camera) >= gltf_.cameras.size())
        fail_flag(fmt::format("--camera {} is out of range (the file has {} camera(s))", wanted, gltf_.cameras.size()));
    } else {
      for (std::size_t i = 0; i < gltf_.cameras.size() && camera < 0; ++i)
        if (gltf_.cameras[i].name == wanted) camera = static_cast<int>(i);
      for (const Placed& p : placed)
        if (camera < 0 && gltf_.nodes[static_cast<std::size_t>(p.node)].name == wanted)
          camera = gltf_.nodes[static_cast<std::size_t>(p.node)].camera;
      if (camera < 0) fail_flag(fmt::format("--camera '{}': no camera or camera node has this name{}", wanted, camera_names()));
    }
    chosen = is_placed(camera);
    if (!chosen)
      fail_flag(fmt::format("--camera {}: no node of the selected scene uses camera {}", wanted, camera));
    if (gltf_.cameras[static_cast<std::size_t>(camera)].type != "perspective")
      fail_flag(fmt::format("--camera {}: camera {} is '{}'; such cameras are not supported (only perspective)", wanted,
                            camera, gltf_.cameras[static_cast<std::size_t>(camera)].type));
  } else {
    bool skipped = false;
    for (const Placed& p : placed) {
      const int c = gltf_.nodes[static_cast<std::size_t>(p.node)].camera;
      if (c < 0) continue;
      element(gltf_.cameras, c, "camera", child(child("/nodes", static_cast<std::size_t>(p.node)), "camera"));
      if (gltf_.cameras[static_cast<std::size_t>(c)].type == "perspective") {
        chosen = &p;
        camera = c;
        break;
      }
      skipped = true;
    }
    if (skipped) notices_.push_back(fmt::format("{}: orthographic camera(s) skipped (not supported)", path_));
  }

  if (!chosen) {
    // Frame the bounding sphere of the geometry from the front (+z in glTF), a little from the
    // right and above, as glTF sample screenshots do; fovy 45 degrees.
    const bool empty = !(lo_.x <= hi_.x);
    const Vec3d center = empty ? Vec3d(0.0) : 0.5 * (lo_ + hi_);
    double radius = empty ? 1.0 : 0.5 * glm::length(hi_ - lo_);
    if (!(radius > 0.0)) radius = 1.0;
    scene.camera.fovy_degrees = 45.0;
    scene.camera.target = center;
    scene.camera.eye = center + glm::normalize(Vec3d(0.5, 0.4, 1.0)) * (1.1 * radius / std::sin(22.5 * kPi / 180.0));
    scene.camera.up = Vec3d(0.0, 1.0, 0.0);
    if (report_) {
      report_->camera_framed = true;
      report_->bounds = empty ? Bounds3d{} : Bounds3d{lo_, hi_};
      report_->view = scene.camera.target - scene.camera.eye;
    } else {
      notices_.push_back(
          fmt::format("{}: no camera: framing the scene's bounding box from the front (+z), right and above", path_));
    }
    return;
  }
  const tinygltf::Camera& source = gltf_.cameras[static_cast<std::size_t>(camera)];
  const std::string at = child(child("/cameras", static_cast<std::size_t>(camera)), "perspective");
  const double fovy = source.perspective.yfov * 180.0 / kPi;
  if (!(fovy > 0.0 && fovy < 180.0)) fail(child(at, "yfov"), fmt::format("yfov {} is outside (0, pi) radians", source.perspective.yfov));
  const Mat4d& m = chosen->world_from_node;
  scene.camera.eye = Vec3d(m * Vec4d(0.0, 0.0, 0.0, 1.0));
  scene.camera.target = scene.camera.eye + glm::normalize(Vec3d(m * Vec4d(0.0, 0.0, -1.0, 0.0)));
  scene.camera.up = Vec3d(m * Vec4d(0.0, 1.0, 0.0, 0.0));
  scene.camera.fovy_degrees = fovy;
  if (source.perspective.aspectRatio > 0.0) {
    scene.settings.height = kCameraImageHeight;
    scene.settings.width = static_cast<int>(std::clamp(std::round(kCameraImageHeight * source.perspective.aspectRatio),
                                                       1.0, double(kMaxImageSide)));
  }
}

void GltfReader::read_lights(const std::vector<Placed>& placed, Scene& scene) {
  for (const Placed& p : placed) {
    const tinygltf::Node& node = gltf_.nodes[static_cast<std::size_t>(p.node)];
    const auto it = node.extensions.find("KHR_lights_punctual");
    if (it == node.extensions.end()) continue;
    const std::string at = child(child(child("/nodes", static_cast<std::size_t>(p.node)), "extensions"), "KHR_lights_punctual");
    const tinygltf::Value& index = it->second.Get("light");
    if (!index.IsNumber()) fail(child(at, "light"), "expected a light index");
    const tinygltf::Light& source = element(gltf_.lights, index.GetNumberAsInt(), "light", child(at, "light"));
    const std::string light_at = fmt::format("/extensions/KHR_lights_punctual/lights/{}", index.GetNumberAsInt());
    Vec3d color(1.0);
    if (!source.color.empty()) {
      if (source.color.size() != 3) fail(child(light_at, "color"), "expected 3 numbers");
      color = Vec3d(source.color[0], source.color[1], source.color[2]);
    }
    if (!(source.intensity >= 0.0) || glm::any(glm::lessThan(color, Vec3d(0.0))))
      fail(light_at, "colour and intensity must be >= 0");
    if (source.range > 0.0) count("light ranges ignored (lights reach everywhere)");
    Light light;
    // candela (point, spot) or lux (directional) -> our radiometric colour: / pi, see docs/scene-formats.md.
    light.color = Color(color * source.intensity / kPi);
    const Vec3d origin(p.world_from_node * Vec4d(0.0, 0.0, 0.0, 1.0));
    const Vec3d forward(p.world_from_node * Vec4d(0.0, 0.0, -1.0, 0.0));
    if (source.type == "directional") {
      if (!(glm::length(forward) > 0.0)) fail(light_at, "the light's node transform has no -z direction");
      light.position = Vec4d(-glm::normalize(forward), 0.0);
    } else if (source.type == "point" || source.type == "spot") {
      light.position = Vec4d(origin, 1.0);
      light.attenuation = Vec3d(0.0, 0.0, 1.0);
      if (source.type == "spot") {
        const double outer = std::clamp(source.spot.outerConeAngle, 1e-6, kPi / 2);
        const double inner = std::clamp(source.spot.innerConeAngle, 0.0, outer);
        if (!(glm::length(forward) > 0.0)) fail(light_at, "the light's node transform has no -z direction");
        light.spot_direction = glm::normalize(forward);
        light.spot_cos_inner = std::cos(inner);
        light.spot_cos_outer = std::cos(outer);
      }
    } else {
      fail(child(light_at, "type"), fmt::format("unknown light type '{}'", source.type));
    }
    scene.lights.push_back(light);
  }
  if (scene.lights.empty() && !lit_by_own_emitters(scene)) {
    scene.lights = make_default_lights(scene.camera);
    if (report_)
      report_->default_lights_added = true;
    else
      notices_.push_back(fmt::format("{}: no lights: using the default key light and headlight", path_));
  }
}

Scene GltfReader::read() {
  Scene scene;
  scene.source = path_;
  // glTF colours are linear and its viewers show them sRGB-encoded (docs/display.md).
  scene.settings.display.encoding = DisplayEncoding::srgb;
  for (std::size_t i = 0; i < gltf_.extensionsRequired.size(); ++i) {
    const std::string& name = gltf_.extensionsRequired[i];
    if (name != "KHR_lights_punctual" && name != "KHR_materials_emissive_strength" && name != "KHR_texture_transform" &&
        name != "KHR_mesh_quantization" && name != "KHR_materials_transmission" && name != "KHR_materials_ior" &&
        name != "KHR_materials_volume")
      fail(child("/extensionsRequired", i), fmt::format("required extension {} is not supported", name));
  }

  // Our node i + 1 is glTF node i; node 0 is the identity root holding the scene's root nodes.
  scene.nodes.push_back(Node{"<root>", Mat4d(1.0), {}, {}});
  for (std::size_t i = 0; i < gltf_.nodes.size(); ++i) {
    const tinygltf::Node& source = gltf_.nodes[i];
    const std::string at = child("/nodes", i);
    Node node;
    node.name = source.name.empty() ? fmt::format("/nodes/{}", i) : source.name;
    node.parent_from_node = read_transform(source, at);
    for (std::size_t c = 0; c < source.children.size(); ++c) {
      element(gltf_.nodes, source.children[c], "node", child(child(at, "children"), c));
      node.children.push_back(static_cast<std::uint32_t>(source.children[c]) + 1);
    }
    scene.nodes.push_back(std::move(node));
  }
  const std::vector<int> roots = scene_roots();
  for (int root : roots) scene.nodes[0].children.push_back(static_cast<std::uint32_t>(root) + 1);

  // Walk the selected scene depth-first (explicit stack), attaching meshes and collecting camera
  // and light placements and world bounds. A node shared by several parents is visited once per
  // path, so the walk is sized first: a few hundred bytes of glTF can instance a node 2^40 times.
  const std::uint64_t instances = sum_over_instances(scene, [](const Node&) { return std::uint64_t(1); });
  if (const auto shortfall = memory_shortfall(instances * 2 * sizeof(Placed)))
    fail("/nodes", fmt::format("the node hierarchy expands to {} node instances (nodes shared by several parents); "
                               "placing them {}", instances, *shortfall));
  std::vector<Placed> placed;
  std::vector<Placed> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it)
    stack.push_back({*it, scene.nodes[static_cast<std::size_t>(*it) + 1].parent_from_node});
  while (!stack.empty()) {
    const Placed entry = stack.back();
    stack.pop_back();
    placed.push_back(entry);
    const tinygltf::Node& source = gltf_.nodes[static_cast<std::size_t>(entry.node)];
    Node& node = scene.nodes[static_cast<std::size_t>(entry.node) + 1];
    if (source.mesh >= 0) {
      element(gltf_.meshes, source.mesh, "mesh", child(child("/nodes", static_cast<std::size_t>(entry.node)), "mesh"));
      if (node.models.empty()) node.models = models_of_mesh(source.mesh);
      for (const Model& model : node.models)
        for (const Vec3f& p : model.mesh->positions) {
          const Vec3d world(entry.world_from_node * Vec4d(Vec3d(p), 1.0));
          lo_ = glm::min(lo_, world);
          hi_ = glm::max(hi_, world);
        }
    }
    if (source.skin >= 0 || !source.weights.empty()) count("skins and morph targets ignored (bind pose shown)");
    for (auto c = source.children.rbegin(); c != source.children.rend(); ++c)
      stack.push_back({*c, entry.world_from_node * scene.nodes[static_cast<std::size_t>(*c) + 1].parent_from_node});
  }

  // Checked before a camera is framed on it: an eye placed from such bounds could not start a ray.
  if (lo_.x <= hi_.x && std::max(max_abs_coordinate(lo_), max_abs_coordinate(hi_)) > kMaxWorldCoordinate)
    fail("/nodes", fmt::format("the geometry extends from ({:g}, {:g}, {:g}) to ({:g}, {:g}, {:g}), beyond +-{:g} in "
                               "world space", lo_.x, lo_.y, lo_.z, hi_.x, hi_.y, hi_.z, kMaxWorldCoordinate));
  scene.materials = std::move(materials_);
  if (scene.materials.empty()) scene.materials.push_back(read_material(-1));
  read_camera(placed, scene);
  read_lights(placed, scene);  // after the materials: emissive ones replace the headlight
  for (const auto& [what, n] : skipped_) notices_.push_back(fmt::format("{}: {} ({}x)", path_, what, n));
  scene.notices = std::move(notices_);
  return scene;
}

// tinygltf's first error line, with "buffer[N]" / "image[N]" turned into a JSON path. Its "File not
// found : URI" names no index: the (text) document is searched for the buffer with that uri.
InputError tinygltf_error(const std::string& path, const std::string& message) {
  std::string line = message.substr(0, message.find('\n'));
  if (line.empty()) line = "cannot parse glTF";
  // tinygltf passes on nlohmann's exception text; say it the way the native JSON loader does.
  const std::string syntax = "parse error at line ", column_label = ", column ";
  if (const std::size_t at = line.find(syntax); at != std::string::npos) {
    std::size_t pos = at + syntax.size();
    const std::string row = read_digits(line, pos);
    if (!row.empty() && line.compare(pos, column_label.size(), column_label) == 0) {
      pos += column_label.size();
      const std::string column = read_digits(line, pos);
      if (!column.empty() && line.compare(pos, 2, ": ") == 0)
        return InputError(path, row + ":" + column, "JSON syntax error: " + line.substr(pos + 2));
    }
  }
  for (std::size_t at = 0; at < line.size(); ++at)
    for (const std::string name : {"buffer", "bufferView", "image", "accessor"})
      if (line.compare(at, name.size() + 1, name + "[") == 0) {
        std::size_t pos = at + name.size() + 1;
        const std::string index = read_digits(line, pos);
        if (!index.empty() && pos < line.size() && line[pos] == ']')
          return InputError(path, fmt::format("/{}s/{}", name, index), line);
      }
  const std::string not_found = "File not found : ";
  if (line.rfind(not_found, 0) == 0) {
    std::ifstream in(path, std::ios::binary);
    const nlohmann::json document = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    const std::string uri = line.substr(not_found.size());
    if (document.is_object() && document.contains("buffers") && document["buffers"].is_array())
      for (std::size_t i = 0; i < document["buffers"].size(); ++i) {
        const nlohmann::json& buffer = document["buffers"][i];
        if (buffer.is_object() && buffer.contains("uri") && buffer["uri"].is_string() &&
            decode_gltf_uri(buffer["uri"].get<std::string>()) == uri)
          return InputError(path, child(child("/buffers", i), "uri"), fmt::format("buffer file '{}' not found", uri));
      }
  }
  return InputError(path, "", line);
}

// tinygltf answers every malformed GLB container with "Invalid glTF binary."; the container
// (12-byte header, then 8-byte-headed chunks: JSON first, optionally BIN) is checked here first so
// the message says what is wrong. Layout: glTF 2.0 specification, section 4.4 "Binary glTF Layout".
// Reads only the 12-byte header and the 8-byte chunk headers, not the chunks: `size` is the
// file's size in bytes, `first_bytes` its first four.
void check_glb_container(const std::string& path, std::uint64_t size, std::string_view first_bytes) {
  if (first_bytes != "glTF")
    throw InputError(path, "", fmt::format("not a binary glTF: it starts with {}, not the magic 'glTF'",
                                           printable_line(first_bytes)));
  std::ifstream in(path, std::ios::binary);
  const auto u32_at = [&](std::uint64_t offset) {  // little-endian
    unsigned char b[4] = {};
    in.seekg(std::streamoff(offset));
    in.read(reinterpret_cast<char*>(b), 4);
    return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
  };
  if (size < 20) throw InputError(path, "", fmt::format("truncated: {} bytes, shorter than the GLB header", size));
  if (const std::uint32_t version = u32_at(4); version != 2)
    throw InputError(path, "", fmt::format("GLB version {}; only version 2 is supported", version));
  if (const std::uint32_t length = u32_at(8); length != size)
    throw InputError(path, "", fmt::format("the GLB header gives a length of {} bytes; the file has {}{}", length, size,
                                           length > size ? " (truncated?)" : ""));
  std::uint64_t offset = 12;
  for (int chunk = 0; offset < size; ++chunk) {
    if (size - offset < 8) throw InputError(path, "", fmt::format("chunk {} header at byte {} is truncated", chunk, offset));
    const std::uint64_t length = u32_at(offset), type = u32_at(offset + 4);
    if (chunk == 0 && type != 0x4E4F534Au) throw InputError(path, "", "the first GLB chunk is not JSON");
    if (length > size - offset - 8)
      throw InputError(path, "", fmt::format("chunk {} ({} bytes from byte {}) runs past the end of the file ({} bytes)",
                                             chunk, length, offset + 8, size));
    offset += 8 + length;
  }
}

}  // namespace

std::string decode_gltf_uri(const std::string& uri) {
  std::string out;
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
      out += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

Scene load_gltf_scene(const std::string& path, const GltfOptions& options, LoadReport* report) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError(path, "", fs::exists(path, error) ? "not a regular file" : "no such file");
  const std::uint64_t size = fs::file_size(path, error);
  if (size == 0) throw InputError(path, "", "empty file");
  char magic[4] = {};
  std::ifstream(path, std::ios::binary).read(magic, 4);
  const std::string_view first_bytes(magic, std::min<std::uint64_t>(size, 4));
  std::string extension = fs::path(path).extension().string();
  for (char& c : extension) c = char(std::tolower(static_cast<unsigned char>(c)));
  const bool binary = first_bytes == "glTF" || extension == ".glb";
  if (binary) check_glb_container(path, size, first_bytes);

  tinygltf::TinyGLTF loader;
  EmbeddedImages embedded;
  loader.SetImageLoader(keep_encoded_image, &embedded);
  tinygltf::Model model;
  std::string errors, warnings;
  const bool ok = binary ? loader.LoadBinaryFromFile(&model, &errors, &warnings, path)
                         : loader.LoadASCIIFromFile(&model, &errors, &warnings, path);
  if (!ok || !errors.empty()) throw tinygltf_error(path, errors);

  Scene scene = GltfReader(path, model, std::move(embedded), options, report).read();
  validate_scene(scene);
  return scene;
}

}  // namespace rt
