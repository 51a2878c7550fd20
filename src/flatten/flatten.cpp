#include "rt/flatten/flatten.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/scene/shapes.h"

namespace rt {

namespace {

struct StackEntry {
  std::uint32_t node;
  Mat4d world_from_node;
};

bool finite(const Vec3f& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string node_label(const Scene& scene, std::uint32_t index) {
  const std::string& name = scene.nodes[index].name;
  return fmt::format("node '{}'", name.empty() ? std::to_string(index) : name);
}

// world_from_object of the unit sphere standing for `sphere` in its node's space.
Mat4d unit_sphere_to_node(const Sphere& sphere) {
  Mat4d m(sphere.radius);
  m[3] = Vec4d(sphere.center, 1.0);
  return m;
}

void append_sphere(const Scene& scene, std::uint32_t node_index, const Model& model, const Mat4d& world_from_node,
                   FlatScene& flat) {
  FlatSphere sphere;
  sphere.world_from_object = world_from_node * unit_sphere_to_node(*model.sphere);
  const Mat3d linear(sphere.world_from_object);
  const double det = glm::determinant(linear);
  if (!(std::abs(det) > 0.0) || !std::isfinite(det))
    throw InputError(scene.source, node_label(scene, node_index), "transform is singular or not finite");
  Vec3d lower, upper;
  sphere_bounds(sphere, lower, upper);
  if (std::max(max_abs_coordinate(lower), max_abs_coordinate(upper)) > kMaxWorldCoordinate)
    throw InputError(scene.source, node_label(scene, node_index),
                     fmt::format("a sphere reaches beyond +-{:g} in world space", kMaxWorldCoordinate));
  sphere.object_from_world = glm::inverse(sphere.world_from_object);
  sphere.normal_from_object = glm::transpose(glm::inverse(linear));
  sphere.material = model.material;
  flat.spheres.push_back(sphere);
}

// Appends `from` (one value per vertex of the model whose first vertex is `base`) to the
// scene-wide attribute `to`, which is empty until some model has the attribute; the vertices of
// earlier models without it get `fallback`.
template <class T>
void append_attribute(std::vector<T>& to, std::size_t base, const std::vector<T>& from, const T& fallback) {
  if (from.empty()) return;
  to.resize(base, fallback);
  to.insert(to.end(), from.begin(), from.end());
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
    if (max_abs_coordinate(Vec3d(p)) > kMaxWorldCoordinate)
      throw InputError(scene.source, node_label(scene, node_index),
                       fmt::format("vertex {} lies at ({:g}, {:g}, {:g}) in world space, beyond +-{:g}", i, p.x, p.y,
                                   p.z, kMaxWorldCoordinate));
    flat.positions.push_back(p);
    flat.normals.push_back(unit_n);
  }
  append_attribute(flat.texcoords, base, mesh->texcoords, Vec2f(0.0f));
  append_attribute(flat.texcoords1, base, mesh->texcoords1, Vec2f(0.0f));
  append_attribute(flat.colors, base, mesh->colors, Vec4f(1.0f));
  // A mirroring transform reverses the orientation of (p1 - p0) x (p2 - p0) but not of the
  // inverse-transposed normals; swapping two indices restores their agreement.
  const bool flip = det < 0.0;
  if (!mesh->tangents.empty()) {
    // Tangents lie in the surface: they transform by the linear part itself. A mirror reverses
    // cross(normal, tangent), so the handedness turns too.
    const Mat3d linear(world_from_object);
    flat.tangents.resize(base, Vec4f(0.0f));
    for (const Vec4f& t : mesh->tangents) {
      const Vec3d world = linear * Vec3d(t);
      const double length = glm::length(world);
      flat.tangents.emplace_back(length > 0.0 && std::isfinite(length) ? Vec3f(world / length) : Vec3f(0.0f),
                                 flip ? -t.w : t.w);
    }
  }
  for (const Vec3u& t : mesh->triangles) {
    // Zero area exactly: the cross product of the float32 world positions' edges, in double.
    const Vec3d p0(flat.positions[base + t.x]), p1(flat.positions[base + t.y]), p2(flat.positions[base + t.z]);
    if (glm::cross(p1 - p0, p2 - p0) == Vec3d(0.0)) {
      ++flat.degenerate_triangles_dropped;
      if (scene.materials[model.material].emits_light) ++flat.degenerate_emitter_triangles_dropped;
      continue;
    }
    flat.triangles.push_back(flip ? Vec3u(base + t.x, base + t.z, base + t.y) : base + t);
    flat.material_ids.push_back(model.material);
  }
}

}  // namespace

void sphere_bounds(const FlatSphere& sphere, Vec3d& lower, Vec3d& upper) {
  const Mat4d& m = sphere.world_from_object;
  const Vec3d centre(m[3]);
  const Vec3d half(glm::length(Vec3d(m[0][0], m[1][0], m[2][0])), glm::length(Vec3d(m[0][1], m[1][1], m[2][1])),
                   glm::length(Vec3d(m[0][2], m[1][2], m[2][2])));
  lower = centre - half;
  upper = centre + half;
}

Bounds3d flat_bounds(const FlatScene& flat) {
  Bounds3d bounds;
  for (const Vec3u& tri : flat.triangles)
    for (std::uint32_t index : {tri.x, tri.y, tri.z}) bounds.extend(Vec3d(flat.positions[index]));
  for (const FlatSphere& sphere : flat.spheres) {
    Vec3d lower, upper;
    sphere_bounds(sphere, lower, upper);
    bounds.extend(lower);
    bounds.extend(upper);
  }
  return bounds;
}

FlatScene flatten_scene(const Scene& scene, const FlattenOptions& options) {
  FlatScene flat;
  if (scene.nodes.empty()) return flat;
  if (options.sphere_tessellation != 0 && options.sphere_tessellation < 3)
    throw InputError(fmt::format("sphere tessellation must be 0 (analytic) or >= 3 slices, not {}",
                                 options.sphere_tessellation));
  // One unit-sphere mesh shared by every tessellated sphere; each model's sphere transform is
  // folded into its world_from_object.
  std::shared_ptr<const TriangleMesh> unit_sphere_mesh;
  if (options.sphere_tessellation > 0)
    unit_sphere_mesh = std::make_shared<const TriangleMesh>(
        make_sphere_mesh(1.0, options.sphere_tessellation, std::max(2, options.sphere_tessellation / 2)));

  // Exact sizes of the flattened buffers (every instance of every node), checked against the
  // memory available before anything is allocated.
  const auto instanced_total = [&](auto count_of_mesh) {
    return sum_over_instances(scene, [&](const Node& node) {
      std::uint64_t n = 0;
      for (const Model& model : node.models)
        if (const TriangleMesh* mesh = model.mesh ? model.mesh.get() : unit_sphere_mesh.get()) n += count_of_mesh(*mesh);
      return n;
    });
  };
  const std::uint64_t vertex_total = instanced_total([](const TriangleMesh& mesh) { return mesh.positions.size(); });
  const std::uint64_t triangle_total = instanced_total([](const TriangleMesh& mesh) { return mesh.triangles.size(); });
  // Per vertex: position, normal, texcoords, and the optional attributes when some mesh has them
  // (every vertex gets them then).
  std::uint64_t vertex_bytes = 2 * sizeof(Vec3f) + sizeof(Vec2f);
  bool has_texcoords1 = false, has_colors = false, has_tangents = false;
  for (const Node& node : scene.nodes)
    for (const Model& model : node.models)
      if (model.mesh) {
        has_texcoords1 = has_texcoords1 || !model.mesh->texcoords1.empty();
        has_colors = has_colors || !model.mesh->colors.empty();
        has_tangents = has_tangents || !model.mesh->tangents.empty();
      }
  vertex_bytes += (has_texcoords1 ? sizeof(Vec2f) : 0) + (has_colors ? sizeof(Vec4f) : 0) + (has_tangents ? sizeof(Vec4f) : 0);
  const std::uint64_t bytes = vertex_total * vertex_bytes + triangle_total * (sizeof(Vec3u) + sizeof(std::uint32_t));
  if (const auto shortfall = memory_shortfall(bytes))
    throw InputError(scene.source, "", fmt::format("flattening {} triangles and {} vertices (every instance) {}",
                                                   triangle_total, vertex_total, *shortfall));
  if (vertex_total >= 0xFFFFFFFFu)
    throw InputError(scene.source, "", fmt::format("the scene expands to {} vertices; at most 2^32 - 2 are supported",
                                                   vertex_total));
  flat.positions.reserve(vertex_total + 1);
  flat.normals.reserve(vertex_total);
  flat.triangles.reserve(triangle_total);
  flat.material_ids.reserve(triangle_total);

  std::vector<StackEntry> stack{{scene.root, scene.nodes[scene.root].parent_from_node}};
  while (!stack.empty()) {
    const StackEntry entry = stack.back();
    stack.pop_back();
    const Node& node = scene.nodes[entry.node];
    for (const Model& model : node.models) {
      if (!model.sphere) {
        append_model(scene, entry.node, model, entry.world_from_node, flat);
      } else if (unit_sphere_mesh) {
        const Model tessellated{unit_sphere_mesh, model.material};
        append_model(scene, entry.node, tessellated, entry.world_from_node * unit_sphere_to_node(*model.sphere), flat);
      } else {
        append_sphere(scene, entry.node, model, entry.world_from_node, flat);
      }
    }
    // Push in reverse so children are visited in file order (keeps triangle ids predictable).
    // (No cycle is possible here: sum_over_instances above has already refused one.)
    for (auto child = node.children.rbegin(); child != node.children.rend(); ++child)
      stack.push_back({*child, entry.world_from_node * scene.nodes[*child].parent_from_node});
  }
  // Vertices of the models after the last one with an attribute get its fallback too.
  if (!flat.texcoords.empty()) flat.texcoords.resize(flat.positions.size(), Vec2f(0.0f));
  if (!flat.texcoords1.empty()) flat.texcoords1.resize(flat.positions.size(), Vec2f(0.0f));
  if (!flat.colors.empty()) flat.colors.resize(flat.positions.size(), Vec4f(1.0f));
  if (!flat.tangents.empty()) flat.tangents.resize(flat.positions.size(), Vec4f(0.0f));
  // Keep one spare slot so Embree's 16-byte load of the last vertex stays inside the allocation.
  if (flat.positions.capacity() < flat.positions.size() + 1) flat.positions.reserve(flat.positions.size() + 1);
  return flat;
}

void release_object_meshes(Scene& scene) {
  for (Node& node : scene.nodes)
    for (Model& model : node.models) model.mesh.reset();
}

}  // namespace rt
