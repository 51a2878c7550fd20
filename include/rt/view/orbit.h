#pragma once
// Camera moves of rt view: orbiting around the target and zooming towards it (world space, double).

#include "rt/scene/scene.h"

namespace rt {

// Turns the eye around the target, keeping its distance: `yaw` radians about camera.up, then
// `pitch` radians about the camera's right axis (positive: the eye rises). The pitch stops one
// degree short of the up direction (and of its opposite), where the camera frame is undefined.
// Target, up and fovy are unchanged.
Camera orbit_camera(const Camera& camera, double yaw, double pitch);

// Moves the eye along the view line so that its distance to the target is multiplied by
// `factor` (> 0; below 1 moves closer). The distance never drops below 1e-6 of what it was at
// the start of the move, so the eye never reaches the target.
Camera zoom_camera(const Camera& camera, double factor);

}  // namespace rt
