#include "rt/render/camera.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>

#include <fmt/format.h>

#include "rt/core/error.h"
#include "rt/render/sampling.h"
#include "lane_math.h"

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
  return ray_through_pixel_sample(frame, i, j, 0, 1);
}

PixelCentreRays::PixelCentreRays(const CameraFrame& frame) : eye_(frame.eye), w_(frame.w) {
  // As camera_direction at x = i + 0.5, y = j + 0.5, term by term.
  for (int i = 0; i < frame.width; ++i) {
    const double alpha = 2.0 * (i + 0.5) / frame.width - 1.0;
    const Vec3d across = alpha * frame.aspect * frame.tan_half_fovy * frame.u;
    across_x_.push_back(across.x);
    across_y_.push_back(across.y);
    across_z_.push_back(across.z);
  }
  for (int j = 0; j < frame.height; ++j) {
    const double beta = 1.0 - 2.0 * (j + 0.5) / frame.height;
    down_.push_back(beta * frame.tan_half_fovy * frame.v);
  }
}

void PixelCentreRays::set_rays4(Ray* rays, int i, int j) const {
  namespace lm = lane_math;
  // glm's operations: (across + down) - w, dot(v, v) = (x x + y y) + z z, normalize(v) =
  // v * (1 / sqrt(dot(v, v))).
  const Vec3d& down = down_[std::size_t(j)];
  lm::D4 x, y, z;
  lm::load(x, across_x_.data() + i);
  lm::load(y, across_y_.data() + i);
  lm::load(z, across_z_.data() + i);
  x = (x + lm::broadcast(down.x)) - lm::broadcast(w_.x);
  y = (y + lm::broadcast(down.y)) - lm::broadcast(w_.y);
  z = (z + lm::broadcast(down.z)) - lm::broadcast(w_.z);
  const lm::D4 scale = lm::broadcast(1.0) / lm::sqrt((x * x + y * y) + z * z);
  const __m128 dx = lm::to_float(x * scale), dy = lm::to_float(y * scale), dz = lm::to_float(z * scale);
  // Each Ray as two 16-byte halves, (origin, direction.x) and (direction.y, direction.z, tnear,
  // tfar), put together by shuffles rather than field by field.
  static_assert(sizeof(Ray) == 32 && offsetof(Ray, direction) == 12 && offsetof(Ray, tnear) == 24 &&
                offsetof(Ray, tfar) == 28);
  const __m128 eye = _mm_setr_ps(eye_.x, eye_.y, eye_.z, 0.0f), eye_z = _mm_set1_ps(eye_.z);
  const __m128 tail = _mm_setr_ps(0.0f, kInfinity, 0.0f, kInfinity);  // (tnear, tfar) twice
  const __m128 zx01 = _mm_unpacklo_ps(eye_z, dx), zx23 = _mm_unpackhi_ps(eye_z, dx);  // (z, dx_k, z, dx_k+1)
  const __m128 yz01 = _mm_unpacklo_ps(dy, dz), yz23 = _mm_unpackhi_ps(dy, dz);      // (dy_k, dz_k, dy_k+1, dz_k+1)
  const auto put = [&](int k, __m128 front, __m128 back) {
    float* const ray = reinterpret_cast<float*>(rays + k);
    _mm_storeu_ps(ray, front);
    _mm_storeu_ps(ray + 4, back);
  };
  put(0, _mm_shuffle_ps(eye, zx01, _MM_SHUFFLE(1, 0, 1, 0)), _mm_movelh_ps(yz01, tail));
  put(1, _mm_shuffle_ps(eye, zx01, _MM_SHUFFLE(3, 2, 1, 0)), _mm_movehl_ps(tail, yz01));
  put(2, _mm_shuffle_ps(eye, zx23, _MM_SHUFFLE(1, 0, 1, 0)), _mm_movelh_ps(yz23, tail));
  put(3, _mm_shuffle_ps(eye, zx23, _MM_SHUFFLE(3, 2, 1, 0)), _mm_movehl_ps(tail, yz23));
}

Vec2d pixel_sample_offset(int i, int j, int index, int count) {
  if (count <= 1) return Vec2d(0.5);
  int columns = 1;
  for (int c = 1; c * c <= count; ++c)
    if (count % c == 0) columns = c;
  const int rows = count / columns;
  const std::uint64_t key = (std::uint64_t(std::uint32_t(j)) << 32 | std::uint32_t(i)) * 0x9e3779b97f4a7c15ULL +
                            std::uint64_t(index);
  const std::uint64_t a = mix64(key), b = mix64(a ^ 0xd1b54a32d192ed03ULL);
  return Vec2d((index % columns + unit_double(a)) / columns, (index / columns + unit_double(b)) / rows);
}

Ray ray_through_pixel_sample(const CameraFrame& frame, int i, int j, int index, int count) {
  const Vec2d offset = pixel_sample_offset(i, j, index, count);
  Ray ray;
  ray.origin = Vec3f(frame.eye);
  ray.direction = Vec3f(camera_direction(frame, i + offset.x, j + offset.y));
  return ray;
}

}  // namespace rt
