#include "rt/render/camera.h"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "rt/core/error.h"

namespace rt {

CameraFrame make_camera_frame(const Camera& camera, int width, int height, const std::string& source) {
  validate_camera(camera, source);
  if (width <= 0 || height <= 0)
    throw InputError(source, "", fmt::format("image size {}x{} is not positive", width, height));
  CameraFrame frame;
  frame.eye = camera.eye;
  frame.w = glm::normalize(camera.eye - camera.target);
  frame.u = glm::normalize(glm::cross(camera.up, frame.w));
  frame.v = glm::cross(frame.w, frame.u);
  frame.tan_half_fovy = std::tan(camera.fovy_degrees * std::numbers::pi / 360.0);
  frame.aspect = static_cast<double>(width) / static_cast<double>(height);
  frame.width = width;
  frame.height = height;
  return frame;
}

Vec3d camera_direction(const CameraFrame& frame, double x, double y) {
  const double alpha = 2.0 * x / frame.width - 1.0;
  const double beta = 1.0 - 2.0 * y / frame.height;
  return glm::normalize(alpha * frame.aspect * frame.tan_half_fovy * frame.u + beta * frame.tan_half_fovy * frame.v -
                        frame.w);
}

Ray ray_through_pixel(const CameraFrame& frame, int i, int j) {
  Ray ray;
  ray.origin = Vec3f(frame.eye);
  ray.direction = Vec3f(camera_direction(frame, i + 0.5, j + 0.5));
  return ray;
}

}  // namespace rt
