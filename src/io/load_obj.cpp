#include "rt/io/load_obj.h"

#include <cmath>
#include <filesystem>
#include <unordered_map>

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include "rt/core/error.h"
#include "rt/scene/shapes.h"

namespace rt {

namespace {

std::string first_line(const std::string& text) { return text.substr(0, text.find('\n')); }

}  // namespace

TriangleMesh load_obj_mesh(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw InputError(path, "", "no such file");
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config))
    throw InputError(path, "", first_line(reader.Error().empty() ? "cannot parse OBJ" : reader.Error()));

  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  const std::size_t position_count = attrib.vertices.size() / 3, normal_count = attrib.normals.size() / 3;
  bool all_have_normals = normal_count > 0;
  for (const tinyobj::shape_t& shape : reader.GetShapes())
    for (const tinyobj::index_t& index : shape.mesh.indices) {
      if (index.vertex_index < 0 || static_cast<std::size_t>(index.vertex_index) >= position_count)
        throw InputError(path, fmt::format("shape '{}'", shape.name),
                         fmt::format("vertex index {} out of range (file has {} vertices)", index.vertex_index + 1,
                                     position_count));
      if (index.normal_index < 0 || static_cast<std::size_t>(index.normal_index) >= normal_count)
        all_have_normals = false;
    }

  TriangleMesh mesh;
  auto position = [&](std::size_t i) {
    return Vec3f(Vec3d(attrib.vertices[3 * i], attrib.vertices[3 * i + 1], attrib.vertices[3 * i + 2]));
  };
  // Without normals the OBJ vertex list maps one to one; with them, each distinct
  // (position, normal) pair becomes one mesh vertex.
  std::unordered_map<std::uint64_t, std::uint32_t> vertex_of_pair;
  auto vertex_for = [&](const tinyobj::index_t& index) -> std::uint32_t {
    if (!all_have_normals) return static_cast<std::uint32_t>(index.vertex_index);
    const std::uint64_t key = static_cast<std::uint64_t>(index.vertex_index) * normal_count + index.normal_index;
    auto [it, inserted] = vertex_of_pair.try_emplace(key, static_cast<std::uint32_t>(mesh.positions.size()));
    if (inserted) {
      const std::size_t n = static_cast<std::size_t>(index.normal_index);
      const Vec3d normal(attrib.normals[3 * n], attrib.normals[3 * n + 1], attrib.normals[3 * n + 2]);
      const double length = glm::length(normal);
      mesh.positions.push_back(position(static_cast<std::size_t>(index.vertex_index)));
      mesh.normals.push_back(length > 0.0 && std::isfinite(length) ? Vec3f(normal / length) : Vec3f(0, 0, 1));
    }
    return it->second;
  };
  if (!all_have_normals)
    for (std::size_t i = 0; i < position_count; ++i) mesh.positions.push_back(position(i));

  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    const auto& indices = shape.mesh.indices;
    std::size_t offset = 0;
    for (unsigned char face_vertices : shape.mesh.num_face_vertices) {
      if (face_vertices == 3)
        mesh.triangles.push_back(
            {vertex_for(indices[offset]), vertex_for(indices[offset + 1]), vertex_for(indices[offset + 2])});
      offset += face_vertices;  // points and lines (fewer than 3 vertices) are not surfaces
    }
  }
  for (const Vec3f& p : mesh.positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw InputError(path, "", "a vertex position is not finite");
  if (!all_have_normals) compute_vertex_normals(mesh);
  return mesh;
}

}  // namespace rt
