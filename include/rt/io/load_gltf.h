#pragma once
// glTF 2.0 scenes (.gltf with external or embedded buffers, binary .glb) through tinygltf.
// What is read, how PBR materials and light units map to ours, and what is skipped:
// docs/scene-formats.md.

#include <optional>
#include <string>

#include "rt/io/load_report.h"
#include "rt/scene/scene.h"

namespace rt {

// Choices a glTF file leaves to the viewer.
struct GltfOptions {
  std::optional<int> scene;  // index into /scenes; default: the file's "scene", else 0
  std::string camera;        // a camera's name, its node's name or an index into /cameras; empty:
                             // the first perspective camera met walking the scene's nodes
};

// A glTF buffer or image URI (an RFC 3986 relative reference) as a file path relative to the
// .gltf's directory: %XX escapes decoded, nothing else changed.
std::string decode_gltf_uri(const std::string& uri);

// Loads the glTF file at `path` (.glb when it starts with the binary magic "glTF") into a scene
// graph: one node per glTF node under an identity root, one model per triangle primitive.
// Anything skipped or substituted (primitive modes, unsampled textures, a missing camera or
// lights, an unreadable texture) is explained in Scene::notices, except a made-up camera or
// headlight, which is recorded in `report` if given (as the OBJ loader does, so that the CLI's
// camera and light flags replace them). The result is validated.
// Throws InputError naming the file, the JSON path (e.g. /meshes/0/primitives/1/indices) and the reason.
Scene load_gltf_scene(const std::string& path, const GltfOptions& options = {}, LoadReport* report = nullptr);

}  // namespace rt
