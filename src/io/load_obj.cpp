#include "rt/io/load_obj.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <unordered_map>

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include "obj_parser.h"
#include "rt/core/error.h"
#include "rt/render/texture.h"
#include "rt/scene/framing.h"
#include "rt/scene/shapes.h"
#include "rt/scene/tangents.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

// Runs of consecutive faces, [first, end) each: the faces of one model, in file order.
using FaceRuns = std::vector<std::pair<std::size_t, std::size_t>>;

// Calls triangle(a, b, c) with the corners (offsets in `corners`) of each triangle of a face of n
// corners: a triangle passes through; a quad is split along the shorter diagonal (as tinyobj
// does), a larger polygon as a fan from its first vertex (exact for convex polygons).
template <class Triangle>
void triangulate_face(const ObjFile& obj, const ObjCorner* corners, std::size_t n, Triangle&& triangle) {
  if (n == 4) {
    auto position = [&](std::size_t k) {
      const auto i = static_cast<std::size_t>(corners[k].position);
      return Vec3d(obj.positions[3 * i], obj.positions[3 * i + 1], obj.positions[3 * i + 2]);
    };
    const Vec3d d02 = position(2) - position(0), d13 = position(3) - position(1);
    if (glm::dot(d02, d02) < glm::dot(d13, d13)) {
      triangle(0, 1, 2);
      triangle(0, 2, 3);
    } else {
      triangle(0, 1, 3);
      triangle(1, 2, 3);
    }
  } else {
    for (std::size_t k = 1; k + 1 < n; ++k) triangle(0, k, k + 1);
  }
}

constexpr std::uint32_t kUnassigned = UINT32_MAX;

// One mesh from faces of the file: vertices are renumbered densely, in order of first use by the
// triangles. With `vn` on every corner each distinct (position, normal) pair is a vertex;
// otherwise each position is, and smooth angle-weighted normals are computed. With a valid `vt`
// on every corner the texture coordinate joins the key, stored as (u, 1 - v): OBJ puts v = 0 at
// the image's bottom row, OIIO at its top. `position_vertex`: scratch, kUnassigned per position
// of the file (or empty, then sized here), and left so.
TriangleMesh build_mesh(const ObjFile& obj, const FaceRuns& runs, std::vector<std::uint32_t>& position_vertex) {
  const std::size_t texcoord_count = obj.texcoord_count(), normal_count = obj.normal_count();
  bool use_texcoords = texcoord_count > 0, use_normals = normal_count > 0;
  std::size_t triangle_count = 0;
  for (const auto& [first, end] : runs)
    for_each_face(obj, first, end, [&](const ObjCorner* corners, std::size_t n) {
      for (std::size_t k = 0; k < n && (use_texcoords || use_normals); ++k) {
        const ObjCorner& corner = corners[k];
        if (corner.texcoord < 0 || static_cast<std::size_t>(corner.texcoord) >= texcoord_count) use_texcoords = false;
        if (corner.normal < 0 || !obj.normal_usable[static_cast<std::size_t>(corner.normal)]) use_normals = false;
      }
      triangle_count += n - 2;
    });

  TriangleMesh mesh;
  mesh.triangles.reserve(triangle_count);
  mesh.positions.reserve(std::min(obj.position_count(), 3 * triangle_count));
  auto add_vertex = [&](const ObjCorner& corner) {
    const auto v = static_cast<std::size_t>(corner.position);
    mesh.positions.push_back(Vec3f(obj.positions[3 * v], obj.positions[3 * v + 1], obj.positions[3 * v + 2]));
    if (use_normals) {
      const auto n = static_cast<std::size_t>(corner.normal);
      const auto& q = obj.normals;
      mesh.normals.push_back(Vec3f(glm::normalize(Vec3d(q[3 * n], q[3 * n + 1], q[3 * n + 2]))));
    }
    if (use_texcoords) {
      const auto c = static_cast<std::size_t>(corner.texcoord);
      mesh.texcoords.push_back(Vec2f(obj.texcoords[2 * c], 1.0f - obj.texcoords[2 * c + 1]));
    }
    return static_cast<std::uint32_t>(mesh.positions.size() - 1);
  };
  auto add_triangles = [&](auto&& vertex_for) {
    for (const auto& [first, end] : runs)
      for_each_face(obj, first, end, [&](const ObjCorner* corners, std::size_t n) {
        triangulate_face(obj, corners, n, [&](std::size_t a, std::size_t b, std::size_t c) {
          mesh.triangles.push_back({vertex_for(corners[a]), vertex_for(corners[b]), vertex_for(corners[c])});
        });
      });
  };
  if (!use_normals && !use_texcoords) {
    // The key is the position index: a table of the file's positions instead of a hash map.
    if (position_vertex.empty()) position_vertex.assign(obj.position_count(), kUnassigned);
    std::vector<std::int32_t> used;  // the positions given a vertex, to reset their entries after
    used.reserve(mesh.positions.capacity());
    add_triangles([&](const ObjCorner& corner) {
      std::uint32_t& vertex = position_vertex[static_cast<std::size_t>(corner.position)];
      if (vertex == kUnassigned) {
        vertex = add_vertex(corner);
        used.push_back(corner.position);
      }
      return vertex;
    });
    for (std::int32_t position : used) position_vertex[static_cast<std::size_t>(position)] = kUnassigned;
  } else {
    std::unordered_map<std::uint64_t, std::uint32_t> vertex_of_key;
    vertex_of_key.reserve(triangle_count);
    add_triangles([&](const ObjCorner& corner) {
      const auto v = static_cast<std::uint64_t>(corner.position);
      std::uint64_t key = use_normals ? v * normal_count + static_cast<std::uint64_t>(corner.normal) : v;
      if (use_texcoords) key = key * texcoord_count + static_cast<std::uint64_t>(corner.texcoord);
      const auto [it, inserted] = vertex_of_key.try_emplace(key, 0);
      if (inserted) it->second = add_vertex(corner);
      return it->second;
    });
  }
  if (!use_normals) compute_vertex_normals(mesh);
  return mesh;
}

Color color_of(const tinyobj::real_t rgb[3]) { return Color(rgb[0], rgb[1], rgb[2]); }

// `directory`: where the OBJ lives; MTL texture paths are relative to it.
Material to_material(const tinyobj::material_t& m, const fs::path& directory) {
  Material material;
  material.back_face = BackFace::flipped;  // OBJ has no sides: lit from either, as renderers treat it
  const auto texture_at = [&](const std::string& name) {
    Texture texture;
    if (!name.empty()) texture.path = (directory / name).lexically_normal().string();
    return texture;
  };
  material.diffuse_texture = texture_at(m.diffuse_texname);
  material.specular_texture = texture_at(m.specular_texname);             // map_Ks: multiplies Ks
  material.shininess_texture = texture_at(m.specular_highlight_texname);  // map_Ns: multiplies Ns
  // norm (an extension of the format) is a tangent-space normal map; bump and map_bump are height
  // maps, as the MTL spec has them, scaled by -bm. A material with both uses the normal map.
  material.normal_texture = texture_at(m.normal_texname);
  if (material.normal_texture.empty()) {
    material.bump_texture = texture_at(m.bump_texname);
    material.bump_scale = static_cast<float>(m.bump_texopt.bump_multiplier);
  }
  material.name = m.name;
  material.ambient = color_of(m.ambient);
  material.diffuse = color_of(m.diffuse);
  material.specular = color_of(m.specular);
  material.emission = color_of(m.emission);
  // Ke is emitted radiance: a material with a non-black Ke is an area light (docs/area-lights.md).
  material.emits_light = material.emission != Color(0.0f);
  if (material.emits_light && !m.emissive_texname.empty())
    material.emission_texture.path = (directory / m.emissive_texname).lexically_normal().string();
  material.shininess = static_cast<float>(m.shininess);
  // illum 3 and 5 trace a mirror reflection weighted by Ks. illum 4, 6 and 7 are glass
  // (docs/scene-formats.md): a dielectric of index Ni whose transmitted light is filtered by Tf
  // (clear when the file gives no Tf), its reflection weighted by the exact Fresnel reflectance
  // in place of Ks; the Phong terms stay.
  material.reflective = (m.illum == 3 || m.illum == 5) ? material.specular : Color(0.0f);
  if (m.illum == 4 || m.illum == 6 || m.illum == 7) {
    const Color filter = color_of(m.transmittance);
    material.transmission = filter == Color(0.0f) ? Color(1.0f) : filter;
    // Some exporters write Ni 0 for "unset": that reads as the usual glass, 1.5.
    material.ior = m.ior > 0 ? static_cast<float>(m.ior) : 1.5f;
  } else if (m.dissolve < 1.0 || !m.alpha_texname.empty()) {
    // Dissolve (d, or 1 - Tr) and map_d: see-through with weight alpha (docs/alpha.md). Glass
    // above is see-through by refraction instead, so its d is not applied on top.
    material.alpha_mode = AlphaMode::blend;
    material.alpha = std::clamp(static_cast<float>(m.dissolve), 0.0f, 1.0f);
    if (!m.alpha_texname.empty()) {
      material.alpha_texture.path = (directory / m.alpha_texname).lexically_normal().string();
      material.alpha_from_grey = true;  // a scalar map; an image with an alpha channel uses that
    }
  }
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

TriangleMesh load_obj_mesh(const std::string& path, const ObjLoadOptions& options) {
  const ObjFile obj = read_obj(path, options);
  std::vector<std::uint32_t> position_vertex;
  return build_mesh(obj, FaceRuns{{0, obj.face_count()}}, position_vertex);
}

Material default_obj_material() {
  Material material;
  material.name = "(default)";
  material.back_face = BackFace::flipped;
  material.ambient = Color(0.1f);
  material.diffuse = Color(0.7f);
  material.specular = Color(0.2f);
  material.shininess = 32.0f;
  material.reflective = Color(0.0f);
  return material;
}

Scene load_obj_scene(const std::string& path, LoadReport* report, const ObjLoadOptions& options) {
  const ObjFile obj = read_obj(path, options);
  Scene scene;
  scene.source = path;
  // OBJ/MTL colours are linear as renderers read them, and 8-bit files are viewed as sRGB (docs/display.md).
  scene.settings.display.encoding = DisplayEncoding::srgb;
  for (const tinyobj::material_t& m : obj.materials)
    scene.materials.push_back(to_material(m, fs::path(path).parent_path()));
  std::optional<std::uint32_t> default_material;
  Node root;
  root.name = fs::path(path).filename().string();

  std::vector<std::uint32_t> position_vertex;
  for (std::size_t s = 0; s + 1 < obj.shape_starts.size(); ++s) {
    // One model per material of the shape, in order of first use within it.
    std::vector<int> order;
    std::map<int, FaceRuns> groups;
    // The material runs that overlap the shape, clipped to it.
    const std::size_t shape_begin = obj.shape_starts[s], shape_end = obj.shape_starts[s + 1];
    auto run = std::upper_bound(obj.material_runs.begin(), obj.material_runs.end(), shape_begin,
                                [](std::size_t face, const auto& r) { return face < r.first; }) - 1;
    for (; run != obj.material_runs.end() && run->first < shape_end; ++run) {
      const std::size_t first = std::max(run->first, shape_begin);
      const std::size_t end = std::min(run + 1 == obj.material_runs.end() ? shape_end : (run + 1)->first, shape_end);
      if (first >= end) continue;
      const int material = run->second;
      const int id = material >= 0 && static_cast<std::size_t>(material) < obj.materials.size() ? material : -1;
      auto [it, inserted] = groups.try_emplace(id);
      if (inserted) order.push_back(id);
      it->second.emplace_back(first, end);
    }
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
      TriangleMesh mesh = build_mesh(obj, groups[id], position_vertex);
      if (!scene.materials[material].normal_texture.empty() && !mesh.texcoords.empty()) {
        if (mesh.normals.empty()) compute_vertex_normals(mesh);
        generate_tangents(mesh);
      }
      root.models.push_back({std::make_shared<const TriangleMesh>(std::move(mesh)), material});
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
  // A texture that cannot be read is left out (map_Kd falls back to Kd alone, as glTF textures do).
  for (Material& material : scene.materials) {
    const std::pair<Texture*, const char*> maps[] = {
        {&material.diffuse_texture, "map_Kd '{}' cannot be read ({}); using Kd alone"},
        {&material.emission_texture, "map_Ke '{}' cannot be read ({}); using Ke alone"},
        {&material.specular_texture, "map_Ks '{}' cannot be read ({}); using Ks alone"},
        {&material.shininess_texture, "map_Ns '{}' cannot be read ({}); using Ns alone"},
        {&material.normal_texture, "norm '{}' cannot be read ({}); left flat"},
        {&material.bump_texture, "bump map '{}' cannot be read ({}); left flat"}};
    for (const auto& [texture, message] : maps) {
      std::string reason;
      if (texture->empty() || texture_is_readable(*texture, reason)) continue;
      r.warnings.push_back(fmt::format("{}: material '{}': {}", path, material.name,
                                       fmt::format(fmt::runtime(message), texture->path, reason)));
      *texture = {};
    }
  }
  r.bounds = world_bounds(scene);
  r.view = choose_view(scene);
  r.camera_framed = true;
  scene.camera = frame_bounds(r.bounds, double(scene.settings.width) / scene.settings.height, r.view);
  // A file whose own surfaces emit is lit by them; otherwise a headlight shows the model.
  if (!lit_by_own_emitters(scene)) {
    scene.lights = make_default_lights(scene.camera);
    r.default_lights_added = true;
  }
  validate_scene(scene);
  return scene;
}

}  // namespace rt
