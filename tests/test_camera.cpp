// Primary rays against the seed's RayThruPixel formulas, evaluated independently here.

#include "catch.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <algorithm>
#include <utility>
#include <vector>

#include "rt/core/error.h"
#include "rt/render/camera.h"

namespace {

rt::Camera make_camera(rt::Vec3d eye, rt::Vec3d target, rt::Vec3d up, double fovy) {
  rt::Camera camera;
  camera.eye = eye;
  camera.target = target;
  camera.up = up;
  camera.fovy_degrees = fovy;
  return camera;
}

// The seed's formula, written out from the issue text: frame, then the direction through the
// centre of pixel (i, j) of a width x height image.
rt::Vec3d expected_direction(const rt::Camera& c, int width, int height, int i, int j) {
  const rt::Vec3d w = glm::normalize(c.eye - c.target);
  const rt::Vec3d u = glm::normalize(glm::cross(c.up, w));
  const rt::Vec3d v = glm::cross(w, u);
  const double t = std::tan(c.fovy_degrees * std::numbers::pi / 180.0 / 2.0);
  const double aspect = double(width) / double(height);
  const double alpha = 2.0 * (i + 0.5) / width - 1.0;
  const double beta = 1.0 - 2.0 * (j + 0.5) / height;
  return glm::normalize(alpha * aspect * t * u + beta * t * v - w);
}

void check_close(const rt::Vec3d& actual, const rt::Vec3d& expected, double tolerance) {
  INFO("actual (" << actual.x << ", " << actual.y << ", " << actual.z << "), expected (" << expected.x << ", "
                  << expected.y << ", " << expected.z << ")");
  CHECK(std::abs(actual.x - expected.x) <= tolerance);
  CHECK(std::abs(actual.y - expected.y) <= tolerance);
  CHECK(std::abs(actual.z - expected.z) <= tolerance);
}

// The float ray through pixel (i, j) must be the double direction rounded to float32.
void check_ray(const rt::CameraFrame& frame, const rt::Camera& camera, int i, int j) {
  INFO("pixel (" << i << ", " << j << ")");
  const rt::Vec3d expected = expected_direction(camera, frame.width, frame.height, i, j);
  check_close(rt::camera_direction(frame, i + 0.5, j + 0.5), expected, 1e-14);
  const rt::Ray ray = rt::ray_through_pixel(frame, i, j);
  CHECK(ray.origin == rt::Vec3f(camera.eye));
  check_close(rt::Vec3d(ray.direction), expected, 1e-7);
  CHECK(ray.tnear == 0.0f);
  CHECK(ray.tfar == rt::kInfinity);
}

}  // namespace

TEST_CASE("camera frame of a camera looking down -z", "[camera]") {
  // eye at the origin looking at -z, up +y, fovy 90: w = +z, u = +x, v = +y, tan(45 deg) = 1.
  const rt::Camera camera = make_camera({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 90.0);
  const rt::CameraFrame frame = rt::make_camera_frame(camera, 4, 2, "test");
  check_close(frame.w, {0, 0, 1}, 1e-15);
  check_close(frame.u, {1, 0, 0}, 1e-15);
  check_close(frame.v, {0, 1, 0}, 1e-15);
  CHECK(frame.tan_half_fovy == Approx(1.0).epsilon(1e-15));
  CHECK(frame.aspect == 2.0);
  CHECK(frame.width == 4);
  CHECK(frame.height == 2);

  // Pixel (0, 0): alpha = 2 * 0.5 / 4 - 1 = -0.75, beta = 1 - 2 * 0.5 / 2 = 0.5,
  // d ~ (-0.75 * 2, 0.5, -1) = (-1.5, 0.5, -1), length sqrt(3.5).
  const double n = std::sqrt(3.5);
  check_close(rt::camera_direction(frame, 0.5, 0.5), {-1.5 / n, 0.5 / n, -1.0 / n}, 1e-15);
  // Pixel (3, 1) mirrors it: alpha = 0.75, beta = -0.5.
  check_close(rt::camera_direction(frame, 3.5, 1.5), {1.5 / n, -0.5 / n, -1.0 / n}, 1e-15);
  // The image centre (x = 2, y = 1) lies between pixels and looks straight ahead.
  check_close(rt::camera_direction(frame, 2.0, 1.0), {0, 0, -1}, 1e-15);
  const rt::Ray ray = rt::ray_through_pixel(frame, 0, 0);
  check_close(rt::Vec3d(ray.direction), {-1.5 / n, 0.5 / n, -1.0 / n}, 1e-7);
}

TEST_CASE("camera looking along +x with z up, odd-sized portrait image", "[camera]") {
  // w = -x, u = up x w = z x (-x) = -y, v = w x u = (-x) x (-y) = +z. fovy 60: tan = 1/sqrt(3).
  // 3x5 image, aspect 0.6.
  const rt::Camera camera = make_camera({0, 0, 0}, {1, 0, 0}, {0, 0, 1}, 60.0);
  const rt::CameraFrame frame = rt::make_camera_frame(camera, 3, 5, "test");
  check_close(frame.w, {-1, 0, 0}, 1e-15);
  check_close(frame.u, {0, -1, 0}, 1e-15);
  check_close(frame.v, {0, 0, 1}, 1e-15);
  CHECK(frame.aspect == Approx(0.6).epsilon(1e-15));

  const double s = std::sqrt(3.0);
  // Pixel (0, 0): alpha = -2/3, beta = 0.8: d ~ (1, 0.4 / sqrt3, 0.8 / sqrt3).
  const rt::Vec3d top_left = glm::normalize(rt::Vec3d(1.0, 0.4 / s, 0.8 / s));
  check_close(rt::camera_direction(frame, 0.5, 0.5), top_left, 1e-15);
  check_close(rt::Vec3d(rt::ray_through_pixel(frame, 0, 0).direction), top_left, 1e-7);
  // Pixel (2, 4): alpha = 2/3, beta = -0.8.
  const rt::Vec3d bottom_right = glm::normalize(rt::Vec3d(1.0, -0.4 / s, -0.8 / s));
  check_close(rt::Vec3d(rt::ray_through_pixel(frame, 2, 4).direction), bottom_right, 1e-7);
  // Centre pixel (1, 2) has alpha = beta = 0 exactly: the ray is -w = +x.
  const rt::Ray centre = rt::ray_through_pixel(frame, 1, 2);
  CHECK(centre.direction == rt::Vec3f(1.0f, 0.0f, 0.0f));
}

TEST_CASE("camera rays of an oblique camera match the seed's formula", "[camera]") {
  const rt::Camera camera = make_camera({1.0, 2.0, 3.0}, {-0.5, 0.25, -1.0}, {0.3, 1.0, -0.2}, 50.0);

  SECTION("frame is orthonormal, right-handed and follows the definitions") {
    const rt::CameraFrame frame = rt::make_camera_frame(camera, 7, 4, "test");
    CHECK(frame.eye == camera.eye);
    check_close(frame.w, glm::normalize(camera.eye - camera.target), 1e-15);
    CHECK(glm::length(frame.u) == Approx(1.0).epsilon(1e-14));
    CHECK(glm::length(frame.v) == Approx(1.0).epsilon(1e-14));
    CHECK(std::abs(glm::dot(frame.u, frame.v)) < 1e-14);
    CHECK(std::abs(glm::dot(frame.u, frame.w)) < 1e-14);
    CHECK(std::abs(glm::dot(frame.v, frame.w)) < 1e-14);
    check_close(glm::cross(frame.u, frame.v), frame.w, 1e-14);
    CHECK(glm::dot(frame.v, camera.up) > 0.0);  // v is "up" on screen
    CHECK(frame.tan_half_fovy == Approx(std::tan(25.0 * std::numbers::pi / 180.0)).epsilon(1e-14));
    CHECK(frame.aspect == Approx(7.0 / 4.0).epsilon(1e-15));
  }

  for (const auto& [width, height] : {std::pair{4, 2}, std::pair{3, 5}, std::pair{640, 480}}) {
    DYNAMIC_SECTION("corners and centre of a " << width << "x" << height << " image") {
      const rt::CameraFrame frame = rt::make_camera_frame(camera, width, height, "test");
      check_ray(frame, camera, 0, 0);
      check_ray(frame, camera, width - 1, height - 1);
      check_ray(frame, camera, width - 1, 0);
      check_ray(frame, camera, width / 2, height / 2);
      // Top-left looks left of and above the view axis, bottom-right right of and below.
      const rt::Vec3d top_left = rt::camera_direction(frame, 0.5, 0.5);
      CHECK(glm::dot(top_left, frame.u) < 0.0);
      CHECK(glm::dot(top_left, frame.v) > 0.0);
      const rt::Vec3d bottom_right = rt::camera_direction(frame, width - 0.5, height - 0.5);
      CHECK(glm::dot(bottom_right, frame.u) > 0.0);
      CHECK(glm::dot(bottom_right, frame.v) < 0.0);
      // The image centre looks exactly at the target.
      check_close(rt::camera_direction(frame, width / 2.0, height / 2.0), glm::normalize(camera.target - camera.eye),
                  1e-15);
    }
  }

  SECTION("the centre pixel of an odd-sized image looks at the target") {
    const rt::CameraFrame frame = rt::make_camera_frame(camera, 3, 5, "test");
    const rt::Vec3d forward = glm::normalize(camera.target - camera.eye);
    check_close(rt::Vec3d(rt::ray_through_pixel(frame, 1, 2).direction), forward, 1e-7);
  }
}

TEST_CASE("PixelCentreRays gives ray_through_pixel's rays bit for bit", "[camera]") {
  const rt::Camera camera = make_camera({1.0, 2.0, 3.0}, {-0.5, 0.25, -1.0}, {0.3, 1.0, -0.2}, 50.0);
  for (const auto& [width, height] : {std::pair{7, 4}, std::pair{3, 5}, std::pair{640, 480}}) {
    INFO(width << "x" << height);
    const rt::CameraFrame frame = rt::make_camera_frame(camera, width, height, "test");
    const rt::PixelCentreRays centre_rays(frame);
    int different = 0;
    rt::Ray ray;
    ray.tnear = 1.0f;  // set_ray must reset it
    for (int j = 0; j < height; ++j)
      for (int i = 0; i < width; ++i) {
        centre_rays.set_ray(ray, i, j);
        const rt::Ray expected = rt::ray_through_pixel(frame, i, j);
        different += std::memcmp(&ray, &expected, sizeof ray) != 0;
      }
    CHECK(different == 0);
    // set_rays4: four neighbours along a row at once, at every start column that fits.
    int different4 = 0;
    for (int j = 0; j < height; ++j)
      for (int i = 0; i + 4 <= width; ++i) {
        rt::Ray rays[4];
        for (rt::Ray& r : rays) r.tnear = 1.0f;
        centre_rays.set_rays4(rays, i, j);
        for (int k = 0; k < 4; ++k) {
          const rt::Ray expected = rt::ray_through_pixel(frame, i + k, j);
          different4 += std::memcmp(&rays[k], &expected, sizeof expected) != 0;
        }
      }
    CHECK(different4 == 0);
  }
}

TEST_CASE("make_camera_frame rejects unusable cameras and sizes", "[camera]") {
  const rt::Camera good = make_camera({1.0, 2.0, 3.0}, {-0.5, 0.25, -1.0}, {0.3, 1.0, -0.2}, 50.0);
  REQUIRE_NOTHROW(rt::make_camera_frame(good, 64, 48, "cam.json"));

  auto require_input_error = [](const rt::Camera& camera, int width, int height) {
    try {
      rt::make_camera_frame(camera, width, height, "cam.json");
      FAIL("no exception thrown");
    } catch (const rt::InputError& error) {
      CHECK_THAT(error.what(), Catch::Matchers::ContainsSubstring("cam.json"));
    }
  };

  rt::Camera camera = good;
  SECTION("up parallel to the view direction") {
    camera.up = camera.target - camera.eye;
    require_input_error(camera, 64, 48);
  }
  SECTION("up anti-parallel to the view direction") {
    camera.up = 3.0 * (camera.eye - camera.target);
    require_input_error(camera, 64, 48);
  }
  SECTION("up is zero") {
    camera.up = rt::Vec3d(0.0);
    require_input_error(camera, 64, 48);
  }
  SECTION("eye equals target") {
    camera.target = camera.eye;
    require_input_error(camera, 64, 48);
  }
  SECTION("fovy 0") {
    camera.fovy_degrees = 0.0;
    require_input_error(camera, 64, 48);
  }
  SECTION("fovy 180") {
    camera.fovy_degrees = 180.0;
    require_input_error(camera, 64, 48);
  }
  SECTION("fovy 200") {
    camera.fovy_degrees = 200.0;
    require_input_error(camera, 64, 48);
  }
  SECTION("negative fovy") {
    camera.fovy_degrees = -45.0;
    require_input_error(camera, 64, 48);
  }
  SECTION("non-finite eye") {
    camera.eye.x = std::numeric_limits<double>::infinity();
    require_input_error(camera, 64, 48);
  }
  SECTION("zero width") { require_input_error(camera, 0, 48); }
  SECTION("zero height") { require_input_error(camera, 64, 0); }
  SECTION("negative width") { require_input_error(camera, -64, 48); }
}

TEST_CASE("pixel samples are stratified, jittered and deterministic", "[camera]") {
  CHECK(rt::pixel_sample_offset(3, 4, 0, 1) == rt::Vec2d(0.5));
  for (const auto& [count, columns] : {std::pair{4, 2}, std::pair{16, 4}, std::pair{64, 8}, std::pair{6, 2},
                                       std::pair{7, 1}, std::pair{12, 3}}) {
    INFO("count " << count);
    const int rows = count / columns;
    double sum_x = 0.0, sum_y = 0.0;
    int samples = 0;
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 7; ++i) {
        std::vector<int> cells(static_cast<std::size_t>(count), 0);
        for (int index = 0; index < count; ++index) {
          const rt::Vec2d p = rt::pixel_sample_offset(i, j, index, count);
          REQUIRE(p == rt::pixel_sample_offset(i, j, index, count));  // deterministic
          REQUIRE((p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0));
          const int cx = static_cast<int>(p.x * columns), cy = static_cast<int>(p.y * rows);
          CHECK(cx == index % columns);  // sample `index` lies in its own cell
          CHECK(cy == index / columns);
          ++cells[static_cast<std::size_t>(cy * columns + cx)];
          sum_x += p.x * columns - cx;  // jitter within the cell
          sum_y += p.y * rows - cy;
          ++samples;
        }
        CHECK(std::count(cells.begin(), cells.end(), 1) == count);  // every cell exactly once
      }
    // Jitter is uniform in the cell: its mean over the samples is 1/2 within a few standard
    // errors (1 / sqrt(12 n)).
    const double tolerance = 4.0 / std::sqrt(12.0 * samples);
    CHECK(sum_x / samples == Approx(0.5).margin(tolerance));
    CHECK(sum_y / samples == Approx(0.5).margin(tolerance));
  }
  CHECK(rt::pixel_sample_offset(0, 0, 0, 4) != rt::pixel_sample_offset(1, 0, 0, 4));  // pixels differ
}
