#include "rt/io/load_obj.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include "rt/core/error.h"
#include "rt/render/texture.h"
#include "rt/scene/framing.h"
#include "rt/scene/shapes.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

// tinyobjloader reads a number it cannot parse ("nan", "1e999", "abc") as 0 and carries on, and
// skips lines it does not know, binary garbage included. So before tinyobj sees a file, every
// statement below has its numbers checked here, and a control character (other than tab, CR and
// form feed) anywhere marks the file as binary. Errors name the 1-based line.
const std::set<std::string> kObjNumericKeywords{"v", "vn", "vt"};
const std::set<std::string> kMtlNumericKeywords{"Ka", "Kd", "Ks", "Ke", "Tf", "Ns", "Ni", "d", "Tr", "illum"};

void check_numbers(const std::string& path, std::istream& in, const std::set<std::string>& keywords) {
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);  // UTF-8 byte order mark
    for (unsigned char c : line)
      if (c < 0x20 && c != '\t' && c != '\r' && c != '\f')
        throw InputError(path, std::to_string(number),
                         fmt::format("binary data (byte 0x{:02x}): not a text file", static_cast<unsigned>(c)));
    std::istringstream tokens(line);
    std::string keyword, token;
    if (!(tokens >> keyword) || !keywords.contains(keyword)) continue;
    while (tokens >> token) {
      if (token.starts_with('#') || token == "spectral") break;  // a comment; a spectral curve file
      if (token == "xyz" || token == "-halo") continue;          // MTL colour space and dissolve options
      char* end = nullptr;
      const double value = std::strtod(token.c_str(), &end);
      if (end != token.c_str() + token.size())
        throw InputError(path, std::to_string(number), fmt::format("'{}': '{}' is not a number", keyword, token));
      if (!std::isfinite(value))
        throw InputError(path, std::to_string(number), fmt::format("'{}': '{}' is not finite", keyword, token));
    }
  }
}

// Reads MTL libraries named by `mtllib` from the OBJ's directory and remembers those it cannot open.
class MtlLibraryReader : public tinyobj::MaterialReader {
 public:
  explicit MtlLibraryReader(fs::path directory) : directory_(std::move(directory)) {}

  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn, std::string* err) override {
    const fs::path path = directory_ / name;
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      missing.push_back(name);
      return false;
    }
    check_numbers(path.string(), in, kMtlNumericKeywords);
    in.clear();
    in.seekg(0);
    tinyobj::LoadMtl(material_map, materials, &in, warn, err);
    return true;
  }

  std::vector<std::string> missing;

 private:
  fs::path directory_;
};

// A triangle of OBJ index triples, and the face it came from (0-based, in file order).
struct ObjTriangle {
  tinyobj::index_t corners[3];
  std::size_t face;
};

struct ObjFile {
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::vector<std::string> missing_libraries;
  std::vector<std::string> unknown_materials;  // usemtl names no library defines
  std::size_t position_count = 0, normal_count = 0;
};

// 1-based line of the first `f` line with at least `min_vertices` vertices that comes after
// `skip` such lines (tinyobj keeps the faces of three or more vertices, in file order). 0 if none.
std::size_t find_face_line(const std::string& path, std::size_t skip, std::size_t min_vertices) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::size_t number = 0, seen = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line[start] != 'f' || start + 1 >= line.size() ||
        (line[start + 1] != ' ' && line[start + 1] != '\t'))
      continue;
    std::istringstream tokens(line.substr(start + 1));
    std::string token;
    std::size_t vertices = 0;
    while (tokens >> token) ++vertices;
    if (vertices >= min_vertices && seen++ == skip) return number;
  }
  return 0;
}

[[noreturn]] void fail_at_line(const std::string& path, std::size_t line, const std::string& reason) {
  throw InputError(path, line > 0 ? std::to_string(line) : "", reason);
}

// `face` counts from 0 over the faces tinyobj keeps.
[[noreturn]] void fail_at_face(const std::string& path, std::size_t face, const std::string& reason) {
  fail_at_line(path, find_face_line(path, face, 3), reason);
}

// tinyobj stores the vertex count of a face in a byte: more than 255 vertices wrap around.
[[noreturn]] void fail_long_face(const std::string& path) {
  fail_at_line(path, find_face_line(path, 0, 256), "a face has more than 255 vertices (not supported)");
}

// tinyobj reports a parse failure as text such as "Failed parse `f' line(e.g. zero value for face
// index. line 12.)"; keep the line number apart and say what is wrong in plain words.
[[noreturn]] void fail_parse(const std::string& path, const std::string& message) {
  const std::string text = message.substr(0, message.find('\n'));
  std::string line;  // the digits after the first "line N" or "line: N"
  for (std::size_t at = text.find("line"); at != std::string::npos && line.empty(); at = text.find("line", at + 1)) {
    std::size_t pos = at + 4;
    if (pos < text.size() && text[pos] == ':') ++pos;
    if (pos < text.size() && text[pos] == ' ') line = read_digits(text, ++pos);
  }
  std::string reason = text.empty() ? "cannot parse OBJ" : text;
  if (text.find("`f' line") != std::string::npos)
    reason = "bad face: a vertex index is 0 or not a number (OBJ indices start at 1)";
  throw InputError(path, line, reason);
}

ObjFile read_obj(const std::string& path) {
  if (!fs::is_regular_file(path)) throw InputError(path, "", "no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open file");
  check_numbers(path, in, kObjNumericKeywords);
  in.clear();
  in.seekg(0);
  ObjFile obj;
  MtlLibraryReader mtl_reader(fs::path(path).parent_path());
  std::string warn, err;
  // Triangulated here, not by tinyobj, which reads vertex positions before indices are checked.
  if (!tinyobj::LoadObj(&obj.attrib, &obj.shapes, &obj.materials, &warn, &err, &in, &mtl_reader,
                        /*triangulate=*/false, /*default_vcols_fallback=*/false))
    fail_parse(path, err);
  obj.missing_libraries = mtl_reader.missing;
  std::set<std::string> unknown;
  std::istringstream warnings(warn);
  const std::string before = "material [ '", after = "' ] not found in .mtl";
  for (std::string w; std::getline(warnings, w);) {
    const std::size_t start = w.find(before), end = w.rfind(after);
    if (start == std::string::npos || end == std::string::npos || end < start + before.size()) continue;
    std::string name = w.substr(start + before.size(), end - start - before.size());
    if (unknown.insert(name).second) obj.unknown_materials.push_back(std::move(name));
  }
  obj.position_count = obj.attrib.vertices.size() / 3;
  obj.normal_count = obj.attrib.normals.size() / 3;
  // OBJ positions are world space; checked before a camera is framed on them (rt/scene/scene.h).
  for (std::size_t i = 0; i < obj.attrib.vertices.size(); ++i)
    if (std::abs(obj.attrib.vertices[i]) > kMaxWorldCoordinate)
      throw InputError(path, "", fmt::format("vertex {} has a coordinate {:g}, beyond +-{:g}", i / 3 + 1,
                                             obj.attrib.vertices[i], kMaxWorldCoordinate));
  if (obj.shapes.empty() || std::all_of(obj.shapes.begin(), obj.shapes.end(), [](const tinyobj::shape_t& shape) {
        return shape.mesh.num_face_vertices.empty();
      }))
    throw InputError(path, "", "no faces ('f' lines): nothing to render");
  return obj;
}

// The triangles of every face of `shape`, indices checked; faces are numbered from `first_face`.
// Triangles pass through; quads are split along the shorter diagonal (as tinyobj does), larger
// polygons as a fan from their first vertex (exact for convex polygons).
std::vector<std::pair<ObjTriangle, int>> triangulate_shape(const std::string& path, const ObjFile& obj,
                                                           const tinyobj::shape_t& shape, std::size_t first_face) {
  std::vector<std::pair<ObjTriangle, int>> triangles;
  const auto& indices = shape.mesh.indices;
  std::size_t total = 0;
  for (unsigned char n : shape.mesh.num_face_vertices) total += n;
  if (total != indices.size()) fail_long_face(path);
  std::size_t offset = 0;
  for (std::size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
    const std::size_t face = first_face + f, n = shape.mesh.num_face_vertices[f];
    if (n < 3 || offset + n > indices.size()) fail_long_face(path);
    for (std::size_t k = offset; k < offset + n; ++k) {
      const tinyobj::index_t& index = indices[k];
      if (index.vertex_index < 0 || static_cast<std::size_t>(index.vertex_index) >= obj.position_count)
        fail_at_face(path, face,
                     index.vertex_index < 0
                         ? "vertex index out of range: a relative index points before the first vertex"
                         : fmt::format("vertex index {} out of range ({} vertices defined)", index.vertex_index + 1,
                                       obj.position_count));
      if (index.normal_index >= 0 && static_cast<std::size_t>(index.normal_index) >= obj.normal_count)
        fail_at_face(path, face, fmt::format("normal index {} out of range ({} normals defined)",
                                             index.normal_index + 1, obj.normal_count));
      if (index.normal_index < -1)
        fail_at_face(path, face, "normal index out of range: a relative index points before the first normal");
    }
    const int material = f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
    auto add = [&](std::size_t a, std::size_t b, std::size_t c) {
      triangles.push_back({ObjTriangle{{indices[offset + a], indices[offset + b], indices[offset + c]}, face}, material});
    };
    if (n == 4) {
      auto position = [&](std::size_t k) {
        const auto i = static_cast<std::size_t>(indices[offset + k].vertex_index);
        return Vec3d(obj.attrib.vertices[3 * i], obj.attrib.vertices[3 * i + 1], obj.attrib.vertices[3 * i + 2]);
      };
      const Vec3d d02 = position(2) - position(0), d13 = position(3) - position(1);
      if (glm::dot(d02, d02) < glm::dot(d13, d13)) {
        add(0, 1, 2);
        add(0, 2, 3);
      } else {
        add(0, 1, 3);
        add(1, 2, 3);
      }
    } else {
      for (std::size_t k = 1; k + 1 < n; ++k) add(0, k, k + 1);
    }
    offset += n;
  }
  if (offset != indices.size()) fail_long_face(path);
  return triangles;
}

// One mesh from triangles of the file: vertices are renumbered densely. With `vn` on every corner
// each distinct (position, normal) pair is a vertex; otherwise each position is, and smooth
// angle-weighted normals are computed. With a valid `vt` on every corner the texture coordinate
// joins the key, stored as (u, 1 - v): OBJ puts v = 0 at the image's bottom row, OIIO at its top.
TriangleMesh build_mesh(const ObjFile& obj, const std::vector<ObjTriangle>& triangles) {
  const std::size_t texcoord_count = obj.attrib.texcoords.size() / 2;
  bool use_texcoords = texcoord_count > 0;
  for (const ObjTriangle& t : triangles)
    for (const tinyobj::index_t& index : t.corners)
      if (index.texcoord_index < 0 || static_cast<std::size_t>(index.texcoord_index) >= texcoord_count)
        use_texcoords = false;
  bool use_normals = obj.normal_count > 0;
  for (const ObjTriangle& t : triangles)
    for (const tinyobj::index_t& index : t.corners) {
      if (index.normal_index < 0) {
        use_normals = false;
        continue;
      }
      const auto n = static_cast<std::size_t>(index.normal_index);
      const double length = glm::length(Vec3d(obj.attrib.normals[3 * n], obj.attrib.normals[3 * n + 1],
                                              obj.attrib.normals[3 * n + 2]));
      if (!(length > 0.0 && std::isfinite(length))) use_normals = false;
    }

  TriangleMesh mesh;
  std::unordered_map<std::uint64_t, std::uint32_t> vertex_of_key;
  auto vertex_for = [&](const tinyobj::index_t& index) -> std::uint32_t {
    const auto v = static_cast<std::uint64_t>(index.vertex_index);
    std::uint64_t key = use_normals ? v * obj.normal_count + static_cast<std::uint64_t>(index.normal_index) : v;
    if (use_texcoords) key = key * texcoord_count + static_cast<std::uint64_t>(index.texcoord_index);
    auto [it, inserted] = vertex_of_key.try_emplace(key, static_cast<std::uint32_t>(mesh.positions.size()));
    if (inserted) {
      const auto& p = obj.attrib.vertices;
      mesh.positions.push_back(Vec3f(Vec3d(p[3 * v], p[3 * v + 1], p[3 * v + 2])));
      if (use_normals) {
        const auto n = static_cast<std::size_t>(index.normal_index);
        const auto& q = obj.attrib.normals;
        mesh.normals.push_back(Vec3f(glm::normalize(Vec3d(q[3 * n], q[3 * n + 1], q[3 * n + 2]))));
      }
      if (use_texcoords) {
        const auto c = static_cast<std::size_t>(index.texcoord_index);
        mesh.texcoords.push_back(Vec2f(obj.attrib.texcoords[2 * c], 1.0f - obj.attrib.texcoords[2 * c + 1]));
      }
    }
    return it->second;
  };
  for (const ObjTriangle& t : triangles)
    mesh.triangles.push_back({vertex_for(t.corners[0]), vertex_for(t.corners[1]), vertex_for(t.corners[2])});
  if (!use_normals) compute_vertex_normals(mesh);
  return mesh;
}

Color color_of(const tinyobj::real_t rgb[3]) { return Color(rgb[0], rgb[1], rgb[2]); }

// `directory`: where the OBJ lives; MTL texture paths are relative to it.
Material to_material(const tinyobj::material_t& m, const fs::path& directory) {
  Material material;
  if (!m.diffuse_texname.empty()) material.diffuse_texture.path = (directory / m.diffuse_texname).lexically_normal().string();
  material.name = m.name;
  material.ambient = color_of(m.ambient);
  material.diffuse = color_of(m.diffuse);
  material.specular = color_of(m.specular);
  material.emission = color_of(m.emission);
  material.shininess = static_cast<float>(m.shininess);
  // illum 3-7 all trace a mirror reflection weighted by Ks; the transparency and refraction of
  // 4, 6 and 7 are not supported, so glass renders as an opaque mirror.
  material.reflective = (m.illum >= 3 && m.illum <= 7) ? material.specular : Color(0.0f);
  return material;
}

// The view direction of the default camera: -z (the usual front view), unless the surface facing
// along z clearly faces -z, i.e. the model opens towards -z (the original Cornell box data).
Vec3d choose_view(const Scene& scene) {
  double net = 0.0, total = 0.0;
  for (const Model& model : scene.nodes[scene.root].models)
    for (const Vec3u& t : model.mesh->triangles) {
      const Vec3d p0(model.mesh->positions[t.x]), p1(model.mesh->positions[t.y]), p2(model.mesh->positions[t.z]);
      const double z = glm::cross(p1 - p0, p2 - p0).z;
      net += z;
      total += std::abs(z);
    }
  return net < -0.25 * total ? Vec3d(0.0, 0.0, 1.0) : Vec3d(0.0, 0.0, -1.0);
}

std::string join(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& name : names) text += (text.empty() ? "'" : ", '") + name + "'";
  return text;
}

}  // namespace

TriangleMesh load_obj_mesh(const std::string& path) {
  const ObjFile obj = read_obj(path);
  std::vector<ObjTriangle> triangles;
  std::size_t face = 0;
  for (const tinyobj::shape_t& shape : obj.shapes) {
    for (const auto& [triangle, material] : triangulate_shape(path, obj, shape, face)) triangles.push_back(triangle);
    face += shape.mesh.num_face_vertices.size();
  }
  return build_mesh(obj, triangles);
}

Material default_obj_material() {
  Material material;
  material.name = "(default)";
  material.ambient = Color(0.1f);
  material.diffuse = Color(0.7f);
  material.specular = Color(0.2f);
  material.shininess = 32.0f;
  material.reflective = Color(0.0f);
  return material;
}

Scene load_obj_scene(const std::string& path, LoadReport* report) {
  const ObjFile obj = read_obj(path);
  Scene scene;
  scene.source = path;
  for (const tinyobj::material_t& m : obj.materials)
    scene.materials.push_back(to_material(m, fs::path(path).parent_path()));
  std::optional<std::uint32_t> default_material;
  Node root;
  root.name = fs::path(path).filename().string();

  std::size_t face = 0;
  for (const tinyobj::shape_t& shape : obj.shapes) {
    // Groups in order of first use within the shape.
    std::vector<int> order;
    std::map<int, std::vector<ObjTriangle>> groups;
    for (const auto& [triangle, material] : triangulate_shape(path, obj, shape, face)) {
      const int id = material >= 0 && static_cast<std::size_t>(material) < obj.materials.size() ? material : -1;
      auto [it, inserted] = groups.try_emplace(id);
      if (inserted) order.push_back(id);
      it->second.push_back(triangle);
    }
    face += shape.mesh.num_face_vertices.size();
    for (int id : order) {
      std::uint32_t material;
      if (id >= 0) {
        material = static_cast<std::uint32_t>(id);
      } else {
        if (!default_material) {
          default_material = static_cast<std::uint32_t>(scene.materials.size());
          scene.materials.push_back(default_obj_material());
        }
        material = *default_material;
      }
      root.models.push_back({std::make_shared<const TriangleMesh>(build_mesh(obj, groups[id])), material});
    }
  }
  if (scene.materials.empty()) scene.materials.push_back(default_obj_material());
  scene.nodes.push_back(std::move(root));

  LoadReport local;
  LoadReport& r = report ? *report : local;
  for (const std::string& library : obj.missing_libraries)
    r.warnings.push_back(fmt::format("{}: material library '{}' not found: its materials fall back to the default", path,
                                     library));
  if (!obj.unknown_materials.empty() && obj.missing_libraries.empty())
    r.warnings.push_back(fmt::format("{}: {} material(s) not defined in any library, using the default: {}", path,
                                     obj.unknown_materials.size(), join(obj.unknown_materials)));
  // A map_Kd that cannot be read falls back to Kd alone, as glTF textures do.
  for (Material& material : scene.materials) {
    std::string reason;
    if (!material.diffuse_texture.empty() && !texture_is_readable(material.diffuse_texture, reason)) {
      r.warnings.push_back(fmt::format("{}: material '{}': map_Kd '{}' cannot be read ({}); using Kd alone", path,
                                       material.name, material.diffuse_texture.path, reason));
      material.diffuse_texture = {};
    }
  }
  r.bounds = world_bounds(scene);
  r.view = choose_view(scene);
  r.camera_framed = true;
  scene.camera = frame_bounds(r.bounds, double(scene.settings.width) / scene.settings.height, r.view);
  scene.lights = {make_headlight(scene.camera)};
  r.headlight_added = true;
  validate_scene(scene);
  return scene;
}

}  // namespace rt
