#pragma once
// Scene loading, one entry point for every format.

#include <string>
#include <vector>

#include "rt/io/load_gltf.h"
#include "rt/scene/framing.h"
#include "rt/scene/scene.h"

namespace rt {

// What a loader made up or left out, for the CLI to tell the user and to adjust to its flags.
struct LoadReport {
  std::vector<std::string> warnings;  // one line each, "FILE: what"
  // The file has no camera: Scene::camera is frame_bounds(bounds, width / height, view).
  bool camera_framed = false;
  Bounds3d bounds;
  Vec3d view{0.0, 0.0, -1.0};
  // The file has no lights: Scene::lights is {make_headlight(Scene::camera)}.
  bool headlight_added = false;
};

// Loads a scene file, choosing the loader by extension (.json, .test, .gltf, .glb, .obj); `gltf`
// applies to glTF files only. The result is validated. Fills `report`, if given, for formats that
// lack a camera or lights (OBJ).
// Throws InputError naming the file, the line or JSON path, and the reason.
Scene load_scene(const std::string& path, const GltfOptions& gltf = {}, LoadReport* report = nullptr);

// Whether load_scene reads `path` as glTF (by extension).
bool is_gltf_path(const std::string& path);

// Parses the native JSON scene format (see docs/scene-format.md) from `text`; `path` names the
// source in messages and anchors relative mesh paths. Comments (// and /* */) are allowed.
Scene parse_scene_json(const std::string& text, const std::string& path);

// The built-in default scene (scenes/default.json, compiled into the binary).
Scene make_default_scene();

}  // namespace rt
