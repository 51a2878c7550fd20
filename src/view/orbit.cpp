#include "rt/view/orbit.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>

namespace rt {

namespace {

// `v` turned by `angle` radians about the unit `axis`, counter-clockwise seen from the axis' tip.
Vec3d rotate(const Vec3d& v, double angle, const Vec3d& axis) {
  return Vec3d(glm::rotate(glm::dmat4(1.0), angle, axis) * glm::dvec4(v, 0.0));
}

}  // namespace

Camera orbit_camera(const Camera& camera, double yaw, double pitch) {
  const Vec3d up = glm::normalize(camera.up);
  Vec3d offset = rotate(camera.eye - camera.target, yaw, up);  // target -> eye, world space
  // Clamp the elevation (angle between offset and up) to [1, 179] degrees after the pitch.
  const double distance = glm::length(offset);
  const double elevation = std::acos(std::clamp(glm::dot(offset, up) / distance, -1.0, 1.0));
  const double margin = glm::pi<double>() / 180.0;
  const double new_elevation = std::clamp(elevation - pitch, margin, glm::pi<double>() - margin);
  const Vec3d right = glm::normalize(glm::cross(up, offset));  // the camera's u axis
  offset = rotate(offset, new_elevation - elevation, right);
  Camera moved = camera;
  moved.eye = camera.target + offset;
  return moved;
}

Camera zoom_camera(const Camera& camera, double factor) {
  Camera moved = camera;
  moved.eye = camera.target + (camera.eye - camera.target) * std::max(factor, 1e-6);
  return moved;
}

}  // namespace rt
