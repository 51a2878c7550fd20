#include "rt/scene/framing.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

namespace rt {

Bounds3d mesh_bounds(const TriangleMesh& mesh) {
  Bounds3d bounds;
  for (const Vec3f& p : mesh.positions) bounds.extend(Vec3d(p));
  return bounds;
}

Bounds3d world_bounds(const Scene& scene) {
  Bounds3d bounds;
  if (scene.root >= scene.nodes.size()) return bounds;
  std::vector<std::pair<std::uint32_t, Mat4d>> stack{{scene.root, scene.nodes[scene.root].parent_from_node}};
  while (!stack.empty()) {
    const auto [index, world_from_node] = stack.back();
    stack.pop_back();
    const Node& node = scene.nodes[index];
    for (const Model& model : node.models)
      if (model.mesh)
        for (const Vec3f& p : model.mesh->positions) bounds.extend(Vec3d(world_from_node * Vec4d(Vec3d(p), 1.0)));
    for (std::uint32_t child : node.children)
      stack.emplace_back(child, world_from_node * scene.nodes[child].parent_from_node);
  }
  return bounds;
}

Camera frame_bounds(const Bounds3d& bounds, double aspect, const Vec3d& view, const Vec3d& up, double fovy_degrees) {
  const Vec3d center = bounds.empty() ? Vec3d(0.0) : bounds.center();
  double radius = bounds.empty() ? std::sqrt(3.0) / 2.0 : bounds.radius();
  if (!(radius > 0.0)) radius = 1.0;
  const Vec3d direction = glm::normalize(view);
  const double half_fovy = fovy_degrees * std::numbers::pi / 360.0;
  const double half_fovx = std::atan(std::tan(half_fovy) * aspect);
  const double distance = radius / std::sin(std::min(half_fovy, half_fovx));

  Camera camera;
  camera.eye = center - distance * direction;
  camera.target = center;
  camera.fovy_degrees = fovy_degrees;
  camera.up = up;
  for (const Vec3d& fallback : {Vec3d(0.0, 0.0, 1.0), Vec3d(1.0, 0.0, 0.0)})
    if (find_camera_problem(camera)) camera.up = fallback;
  return camera;
}

std::vector<Light> make_default_lights(const Camera& camera) {
  // The camera's frame, world space: back points from the target towards the eye.
  const Vec3d back = glm::normalize(camera.eye - camera.target);
  const Vec3d right = glm::normalize(glm::cross(camera.up, back));
  const Vec3d up = glm::cross(back, right);
  Light key;
  key.position = Vec4d(glm::normalize(0.5 * right + 1.0 * up + 0.7 * back), 0.0);
  key.color = Color(0.8f);
  Light head;
  head.position = Vec4d(camera.eye, 1.0);
  head.color = Color(0.4f);
  head.attenuation = Vec3d(1.0, 0.0, 0.0);
  return {key, head};
}

}  // namespace rt
