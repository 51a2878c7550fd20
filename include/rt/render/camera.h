#pragma once
// Primary rays, exactly as the seed's RayThruPixel.

#include <vector>

#include "rt/accel/accel.h"
#include "rt/scene/scene.h"

namespace rt {

// The camera's orthonormal frame in world space (double precision):
// w = normalize(eye - target), u = normalize(up x w), v = w x u; the camera looks along -w.
struct CameraFrame {
  Vec3d eye, u, v, w;
  double tan_half_fovy = 0.0;  // tan(fovy / 2)
  double aspect = 1.0;         // image width / height
  int width = 0, height = 0;   // image size in pixels
};

// Builds the frame for an image of width x height pixels. Throws InputError (naming `source`)
// if eye == target, up is parallel to the view direction, fovy is outside (0, 180) or a size
// is not positive.
CameraFrame make_camera_frame(const Camera& camera, int width, int height, const std::string& source);

// World-space direction (double, unit length) through image position (x, y) in pixels, where
// x grows to the right, y grows downwards, and (i + 0.5, j + 0.5) is the centre of pixel (i, j):
//   alpha = 2x / width - 1,  beta = 1 - 2y / height,
//   d = normalize(alpha * aspect * tan(fovy/2) u + beta * tan(fovy/2) v - w).
Vec3d camera_direction(const CameraFrame& frame, double x, double y);

// The float32 ray from the eye through the centre of pixel (i, j), row j = 0 at the top.
Ray ray_through_pixel(const CameraFrame& frame, int i, int j);

// ray_through_pixel for every pixel of one frame, with camera_direction's per-column and per-row
// terms computed once (alpha aspect tan(fovy/2) u and beta tan(fovy/2) v): the same rays bit
// for bit, for an addition, a normalisation and a rounding per pixel.
class PixelCentreRays {
 public:
  explicit PixelCentreRays(const CameraFrame& frame);
  // Writes the ray through pixel (i, j) into `ray` field by field (building a Ray and copying it
  // stalled store forwarding on every pixel).
  void set_ray(Ray& ray, int i, int j) const {
    const Vec3d d = glm::normalize(Vec3d(across_x_[std::size_t(i)], across_y_[std::size_t(i)],
                                         across_z_[std::size_t(i)]) + down_[std::size_t(j)] - w_);
    ray.origin.x = eye_.x, ray.origin.y = eye_.y, ray.origin.z = eye_.z;
    ray.direction.x = float(d.x), ray.direction.y = float(d.y), ray.direction.z = float(d.z);
    ray.tnear = 0.0f;
    ray.tfar = kInfinity;
  }
  // set_ray for the four pixels (i .. i + 3, j) into rays[0 .. 3] (i + 3 < width), in SIMD lanes
  // with the same operations in the same order: the same rays bit for bit.
  void set_rays4(Ray* rays, int i, int j) const;

 private:
  Vec3f eye_;
  Vec3d w_;
  std::vector<double> across_x_, across_y_, across_z_;  // per column i (world space, double)
  std::vector<Vec3d> down_;  // per row j (world space, double)
};

// Where sample `index` of `count` (count >= 1) falls inside pixel (i, j), as an offset in
// [0, 1)^2 from the pixel's top-left corner (pixel units). count == 1: the centre (0.5, 0.5).
// Otherwise stratified: a columns x rows grid, columns the largest divisor of count not above
// sqrt(count), one sample jittered uniformly inside each cell. The jitter is a hash of (i, j,
// index) (splitmix64), so the image is the same whatever the thread count or tile order.
Vec2d pixel_sample_offset(int i, int j, int index, int count);

// The float32 ray from the eye through sample `index` of `count` of pixel (i, j).
Ray ray_through_pixel_sample(const CameraFrame& frame, int i, int j, int index, int count);

}  // namespace rt
