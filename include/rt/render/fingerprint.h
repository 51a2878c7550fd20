#pragma once
// A digest of everything in a scene that decides its pixels, so that parts of one image rendered
// by different processes (rt render --tile, rt merge) can be checked to come from the same scene.

#include <string>

#include "rt/flatten/flatten.h"
#include "rt/scene/scene.h"

namespace rt {

// 16 hex digits (XXH64, chained over the buffers) of the world-space geometry, the materials with
// their texture images' bytes, the lights, the camera, the image size, depth and background.
// Scene files that load and flatten to the same values get the same fingerprint, whatever their
// name, path or format; a change to any of those values changes it (with probability 1 - 2^-64).
// Names, notices and the default output name do not count.
std::string scene_fingerprint(const Scene& scene, const FlatScene& flat);

}  // namespace rt
