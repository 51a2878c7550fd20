#include "rt/flatten/flatten.h"

#include <cmath>
#include <vector>

#include <fmt/format.h>

#include "rt/core/error.h"
#include "rt/scene/shapes.h"

namespace rt {

namespace {

struct StackEntry {
  std::uint32_t node;
  Mat4d world_from_node;
  std::size_t depth;  // number of ancestors; a path longer than the node count proves a cycle
};

bool finite(const Vec3f& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string node_label(const Scene& scene, std::uint32_t index) {
  const std::string& name = scene.nodes[index].name;
  return fmt::format("node '{}'", name.empty() ? std::to_string(index) : name);
}

void append_model(const Scene& scene, std::uint32_t node_index, const Model& model, const Mat4d& world_from_object,
                  FlatScene& flat) {
  const TriangleMesh* mesh = model.mesh.get();
  TriangleMesh with_normals;
  if (mesh->normals.empty()) {
    with_normals = *mesh;
    compute_vertex_normals(with_normals);
    mesh = &with_normals;
  }
  const double det = glm::determinant(Mat3d(world_from_object));
  if (!(std::abs(det) > 0.0) || !std::isfinite(det))
    throw InputError(scene.source, node_label(scene, node_index), "transform is singular or not finite");
  // Normals transform by the inverse transpose of the linear part (they are covectors).
  const Mat3d normal_from_object = glm::transpose(glm::inverse(Mat3d(world_from_object)));

  const auto base = static_cast<std::uint32_t>(flat.positions.size());
  for (std::size_t i = 0; i < mesh->positions.size(); ++i) {
    const Vec3f p(world_from_object * Vec4d(Vec3d(mesh->positions[i]), 1.0));
    const Vec3d n = normal_from_object * Vec3d(mesh->normals[i]);
    const double length = glm::length(n);
    const Vec3f unit_n = length > 0.0 ? Vec3f(n / length) : Vec3f(0.0f, 0.0f, 1.0f);
    if (!finite(p) || !finite(unit_n))
      throw InputError(scene.source, node_label(scene, node_index),
                       fmt::format("vertex {} is not finite in world space", i));
    flat.positions.push_back(p);
    flat.normals.push_back(unit_n);
  }
  if (!mesh->texcoords.empty()) {
    flat.texcoords.resize(base, Vec2f(0.0f));
    flat.texcoords.insert(flat.texcoords.end(), mesh->texcoords.begin(), mesh->texcoords.end());
  }
  // A mirroring transform reverses the orientation of (p1 - p0) x (p2 - p0) but not of the
  // inverse-transposed normals; swapping two indices restores their agreement.
  const bool flip = det < 0.0;
  for (const Vec3u& t : mesh->triangles) {
    // Zero area exactly: the cross product of the float32 world positions' edges, in double.
    const Vec3d p0(flat.positions[base + t.x]), p1(flat.positions[base + t.y]), p2(flat.positions[base + t.z]);
    if (glm::cross(p1 - p0, p2 - p0) == Vec3d(0.0)) {
      ++flat.degenerate_triangles_dropped;
      continue;
    }
    flat.triangles.push_back(flip ? Vec3u(base + t.x, base + t.z, base + t.y) : base + t);
    flat.material_ids.push_back(model.material);
  }
}

}  // namespace

FlatScene flatten_scene(const Scene& scene) {
  FlatScene flat;
  if (scene.nodes.empty()) return flat;

  std::size_t vertex_total = 0, triangle_total = 0;  // reserve() hint; a node reached twice adds more
  for (const Node& node : scene.nodes)
    for (const Model& model : node.models) {
      vertex_total += model.mesh->positions.size();
      triangle_total += model.mesh->triangles.size();
    }
  flat.positions.reserve(vertex_total + 1);
  flat.normals.reserve(vertex_total);
  flat.triangles.reserve(triangle_total);
  flat.material_ids.reserve(triangle_total);

  std::vector<StackEntry> stack{{scene.root, scene.nodes[scene.root].parent_from_node, 0}};
  while (!stack.empty()) {
    const StackEntry entry = stack.back();
    stack.pop_back();
    const Node& node = scene.nodes[entry.node];
    for (const Model& model : node.models) append_model(scene, entry.node, model, entry.world_from_node, flat);
    // Push in reverse so children are visited in file order (keeps triangle ids predictable).
    for (auto child = node.children.rbegin(); child != node.children.rend(); ++child) {
      if (entry.depth + 2 > scene.nodes.size())  // path of depth + 2 nodes must repeat one
        throw InputError(scene.source, node_label(scene, *child), "node hierarchy contains a cycle");
      stack.push_back({*child, entry.world_from_node * scene.nodes[*child].parent_from_node, entry.depth + 1});
    }
  }
  if (!flat.texcoords.empty()) flat.texcoords.resize(flat.positions.size(), Vec2f(0.0f));
  if (flat.positions.size() >= 0xFFFFFFFFu)
    throw InputError(scene.source, "", "scene has more than 2^32 - 1 vertices");
  // Keep one spare slot so Embree's 16-byte load of the last vertex stays inside the allocation.
  if (flat.positions.capacity() < flat.positions.size() + 1) flat.positions.reserve(flat.positions.size() + 1);
  return flat;
}

}  // namespace rt
