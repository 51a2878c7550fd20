#pragma once
// What a loader reports besides the scene: warnings, and the camera and lights it made up.

#include <string>
#include <vector>

#include "rt/scene/framing.h"

namespace rt {

// What a loader made up or left out, for the CLI to tell the user and to adjust to its flags.
struct LoadReport {
  std::vector<std::string> warnings;  // one line each, "FILE: what"
  // The file has no camera: the loader framed `bounds` looking along `view`, and the CLI reframes
  // with frame_bounds(bounds, width / height, view) once the image size and flags are known.
  bool camera_framed = false;
  Bounds3d bounds;
  Vec3d view{0.0, 0.0, -1.0};
  // The file has no lights: Scene::lights is make_default_lights(Scene::camera).
  bool default_lights_added = false;
};

}  // namespace rt
