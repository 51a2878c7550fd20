#pragma once
// Scene loading, one entry point for every format.

#include <optional>
#include <string>
#include <vector>

#include "rt/io/load_gltf.h"
#include "rt/io/load_report.h"
#include "rt/scene/scene.h"

namespace rt {

// Loads a scene file, choosing the loader by extension (.json, .test, .gltf, .glb, .obj); `gltf`
// applies to glTF files only. The result is validated. Fills `report`, if given, for formats that
// lack a camera or lights (OBJ, glTF).
// Throws InputError naming the file, the line or JSON path, and the reason.
Scene load_scene(const std::string& path, const GltfOptions& gltf = {}, LoadReport* report = nullptr);

// The output file a scene file names for itself (.json "output", .test "output"), read without
// loading the scene, so that a batch can check its outputs before rendering. nullopt when the file
// names none, its format has no such field, or it cannot be read or parsed (load_scene says why).
std::optional<std::string> declared_output(const std::string& path);

// Whether load_scene reads `path` as glTF (by extension).
bool is_gltf_path(const std::string& path);

// Parses the native JSON scene format (see docs/json-scene-format.md) from `text`; `path` names the
// source in messages and anchors relative mesh paths. Comments (// and /* */) are allowed.
Scene parse_scene_json(const std::string& text, const std::string& path);

// The built-in default scene (scenes/default.json, compiled into the binary).
Scene make_default_scene();

}  // namespace rt
