#include "rt/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <fmt/format.h>

#include "rt/core/error.h"

namespace rt {

namespace {

bool finite(const Color& c) { return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b); }
bool finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

void check_color(const Scene& scene, const std::string& where, const Color& c) {
  if (!finite(c)) throw InputError(scene.source, where, "colour is not finite");
  if (c.r < 0.0f || c.g < 0.0f || c.b < 0.0f) throw InputError(scene.source, where, "colour is negative");
}

}  // namespace

std::optional<CameraProblem> find_camera_problem(const Camera& camera) {
  if (!finite(camera.eye)) return CameraProblem{"eye", "eye is not finite"};
  if (max_abs_coordinate(camera.eye) > kMaxEyeCoordinate)
    return CameraProblem{"eye", fmt::format("eye ({:g}, {:g}, {:g}) lies beyond +-{:g}, where float32 rays are no "
                                            "longer valid", camera.eye.x, camera.eye.y, camera.eye.z, kMaxEyeCoordinate)};
  if (!finite(camera.target)) return CameraProblem{"target", "target is not finite"};
  if (!finite(camera.up)) return CameraProblem{"up", "up is not finite"};
  if (!(camera.fovy_degrees > 0.0 && camera.fovy_degrees < 180.0))
    return CameraProblem{"fovy", fmt::format("fovy {} is outside (0, 180) degrees", camera.fovy_degrees)};
  const Vec3d view = camera.target - camera.eye;
  if (!(glm::length(view) > 0.0)) return CameraProblem{"target", "target is the same point as eye"};
  // Relative test: |up x view| tiny compared with |up| |view| leaves the frame's u undefined.
  const double sine = glm::length(glm::cross(camera.up, view)) / (glm::length(camera.up) * glm::length(view));
  if (!(sine > 1e-9)) return CameraProblem{"up", "up vector is zero or parallel to the view direction"};
  return std::nullopt;
}

void validate_camera(const Camera& camera, const std::string& source) {
  if (auto problem = find_camera_problem(camera)) throw InputError(source, "camera." + problem->field, problem->reason);
}

void validate_scene(const Scene& scene) {
  validate_camera(scene.camera, scene.source);
  const RenderSettings& s = scene.settings;
  if (s.width <= 0 || s.height <= 0 || s.width > kMaxImageSide || s.height > kMaxImageSide)
    throw InputError(scene.source, "image",
                     fmt::format("image size {}x{} is outside 1..{} per side", s.width, s.height, kMaxImageSide));
  if (s.max_depth < 0 || s.max_depth > kMaxReflectionDepth)
    throw InputError(scene.source, "max_depth",
                     fmt::format("max depth {} is outside 0..{}", s.max_depth, kMaxReflectionDepth));
  check_color(scene, "background", s.background);

  for (std::size_t i = 0; i < scene.materials.size(); ++i) {
    const Material& m = scene.materials[i];
    const std::string where = fmt::format("material '{}'", m.name);
    check_color(scene, where, m.ambient);
    check_color(scene, where, m.diffuse);
    check_color(scene, where, m.specular);
    check_color(scene, where, m.emission);
    if (m.reflective) check_color(scene, where, *m.reflective);
    if (!std::isfinite(m.shininess) || m.shininess < 0.0f)
      throw InputError(scene.source, where, "shininess must be finite and >= 0");
  }
  for (std::size_t i = 0; i < scene.lights.size(); ++i) {
    const Light& l = scene.lights[i];
    const std::string where = fmt::format("light {}", i);
    check_color(scene, where, l.color);
    if (!finite(Vec3d(l.position)) || !(l.position.w == 0.0 || l.position.w == 1.0))
      throw InputError(scene.source, where, "position must be finite with w = 0 (directional) or 1 (point)");
    if (l.is_directional() && Vec3d(l.position) == Vec3d(0.0))
      throw InputError(scene.source, where, "directional light has a zero direction");
    if (!finite(l.attenuation) || l.attenuation.x < 0 || l.attenuation.y < 0 || l.attenuation.z < 0 ||
        l.attenuation == Vec3d(0.0))
      throw InputError(scene.source, where, "attenuation must be finite, >= 0 and not all zero");
    if (l.is_spot() && (!finite(l.spot_direction) || !(l.spot_cos_inner >= l.spot_cos_outer) || l.spot_cos_inner > 1.0))
      throw InputError(scene.source, where, "spot light needs a finite direction and -1 < cos outer <= cos inner <= 1");
  }
  if (scene.nodes.empty()) throw InputError(scene.source, "", "scene has no root node");
  if (scene.root >= scene.nodes.size()) throw InputError(scene.source, "", "root node index out of range");
  for (std::size_t i = 0; i < scene.nodes.size(); ++i) {
    const Node& node = scene.nodes[i];
    const std::string where = fmt::format("node '{}'", node.name.empty() ? std::to_string(i) : node.name);
    for (std::uint32_t child : node.children)
      if (child >= scene.nodes.size()) throw InputError(scene.source, where, "child index out of range");
    for (const Model& model : node.models) {
      if (!model.mesh == !model.sphere)
        throw InputError(scene.source, where, "model must have exactly one of a mesh and a sphere");
      if (model.material >= scene.materials.size())
        throw InputError(scene.source, where, "model material index out of range");
      if (model.sphere) {
        const Sphere& sphere = *model.sphere;
        if (!std::isfinite(sphere.center.x) || !std::isfinite(sphere.center.y) || !std::isfinite(sphere.center.z) ||
            !(sphere.radius > 0.0) || !std::isfinite(sphere.radius))
          throw InputError(scene.source, where, "sphere needs a finite centre and a finite radius > 0");
        if (scene.materials[model.material].culls_back_faces())
          throw InputError(scene.source, where,
                           fmt::format("sphere has material '{}' with culled back faces: culling applies to meshes only",
                                       scene.materials[model.material].name));
        continue;
      }
      const TriangleMesh& mesh = *model.mesh;
      if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
        throw InputError(scene.source, where, "mesh has a different number of normals and positions");
      if (!mesh.texcoords.empty() && mesh.texcoords.size() != mesh.positions.size())
        throw InputError(scene.source, where, "mesh has a different number of texcoords and positions");
      if (!mesh.texcoords1.empty() && mesh.texcoords1.size() != mesh.positions.size())
        throw InputError(scene.source, where, "mesh has a different number of second texcoords and positions");
      if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size())
        throw InputError(scene.source, where, "mesh has a different number of vertex colours and positions");
      if (!mesh.tangents.empty() && mesh.tangents.size() != mesh.positions.size())
        throw InputError(scene.source, where, "mesh has a different number of tangents and positions");
      for (const Vec3u& t : mesh.triangles)
        if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() || t.z >= mesh.positions.size())
          throw InputError(scene.source, where, "triangle index out of range");
    }
  }
}

std::uint64_t sum_over_instances(const Scene& scene, const std::function<std::uint64_t(const Node&)>& weight) {
  if (scene.nodes.empty()) return 0;
  constexpr std::uint64_t kSaturated = std::numeric_limits<std::uint64_t>::max();
  const auto add = [](std::uint64_t a, std::uint64_t b) { return a > kSaturated - b ? kSaturated : a + b; };
  enum class State : std::uint8_t { unvisited, open, done };
  std::vector<State> state(scene.nodes.size(), State::unvisited);
  std::vector<std::uint64_t> subtree(scene.nodes.size(), 0);  // memo: sum over one instance of the node
  std::vector<std::pair<std::uint32_t, std::size_t>> stack{{scene.root, 0}};  // node, next child
  state[scene.root] = State::open;
  while (!stack.empty()) {
    auto& [node, next] = stack.back();
    const std::vector<std::uint32_t>& children = scene.nodes[node].children;
    if (next < children.size()) {
      const std::uint32_t child = children[next++];
      if (state[child] == State::open) {
        const std::string& name = scene.nodes[child].name;
        throw InputError(scene.source, fmt::format("node '{}'", name.empty() ? std::to_string(child) : name),
                         "node hierarchy contains a cycle");
      }
      if (state[child] == State::unvisited) {
        state[child] = State::open;
        stack.push_back({child, 0});
      }
      continue;
    }
    std::uint64_t sum = weight(scene.nodes[node]);
    for (std::uint32_t child : children) sum = add(sum, subtree[child]);
    subtree[node] = sum;
    state[node] = State::done;
    stack.pop_back();
  }
  return subtree[scene.root];
}

bool lit_by_own_emitters(const Scene& scene) {
  for (const Node& node : scene.nodes)
    for (const Model& model : node.models) {
      if (!model.mesh || model.mesh->triangles.empty() || model.material >= scene.materials.size()) continue;
      const Material& material = scene.materials[model.material];
      if (material.is_emitter() && material.emission_texture.empty()) return true;
    }
  return false;
}

}  // namespace rt
