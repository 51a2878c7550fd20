#pragma once
// Primary rays, exactly as the seed's RayThruPixel.

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

// Where sample `index` of `count` (count >= 1) falls inside pixel (i, j), as an offset in
// [0, 1)^2 from the pixel's top-left corner (pixel units). count == 1: the centre (0.5, 0.5).
// Otherwise stratified: a columns x rows grid, columns the largest divisor of count not above
// sqrt(count), one sample jittered uniformly inside each cell. The jitter is a hash of (i, j,
// index) (splitmix64), so the image is the same whatever the thread count or tile order.
Vec2d pixel_sample_offset(int i, int j, int index, int count);

// The float32 ray from the eye through sample `index` of `count` of pixel (i, j).
Ray ray_through_pixel_sample(const CameraFrame& frame, int i, int j, int index, int count);

}  // namespace rt
