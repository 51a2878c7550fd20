#include <catch2/catch.hpp>

#include "rt/render/camera.h"

TEST_CASE("placeholder camera", "[camera]") {
  rt::Camera camera;
  const rt::CameraFrame frame = rt::make_camera_frame(camera, 640, 480, "test");
  CHECK(frame.aspect == Approx(640.0 / 480.0));
}
