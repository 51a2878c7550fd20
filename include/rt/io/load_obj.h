#pragma once
// Wavefront OBJ (+ MTL): single meshes for the JSON format's "obj" geometry, and whole OBJ scenes
// for `rt render FILE.obj` (docs/scene-formats.md). The OBJ is parsed here, in parallel chunks,
// with tinyobjloader's semantics; MTL libraries go through tinyobjloader.

#include <cstddef>
#include <string>

#include "rt/io/load_scene.h"
#include "rt/scene/scene.h"

namespace rt {

// How an OBJ file is split for parallel parsing. The result never depends on it; tests use it to
// put chunk boundaries at every line.
struct ObjLoadOptions {
  // Bytes per chunk: each chunk ends at the first line end at or after this many bytes. 0 chooses
  // about four chunks per TBB worker thread, of at least 256 KiB (smaller files are one chunk).
  std::size_t chunk_bytes = 0;
};

// Loads every face of the OBJ at `path` into one object-space mesh; polygons are triangulated,
// `vn` normals are used when every face has them, smooth angle-weighted normals otherwise.
// Materials are ignored here. Throws InputError "FILE:LINE: REASON" for a missing or malformed file.
TriangleMesh load_obj_mesh(const std::string& path, const ObjLoadOptions& options = {});

// The material of OBJ faces that have none (no usemtl, a name the MTL lacks, a missing MTL file):
// grey plastic, ambient 0.1, diffuse 0.7, specular 0.2, shininess 32, no mirror reflection.
Material default_obj_material();

// Loads the OBJ at `path` and its MTL libraries (relative to the OBJ's directory) as a scene: one
// model per (shape, material) group, all in the root node; polygons triangulated; `vn` used where
// every face of a group has them, else smooth angle-weighted normals per group; MTL Ka Kd Ks Ke
// Ns illum mapped to Material (illum 3 to 7 reflect Ks, others do not reflect). Adds a camera
// framing the geometry and a headlight and records both in `report`, with warnings for a missing
// MTL file, unknown material names and ignored map_Kd textures. Settings are the defaults.
// Throws InputError "FILE:LINE: REASON" for a missing or malformed file. The result is validated.
Scene load_obj_scene(const std::string& path, LoadReport* report = nullptr, const ObjLoadOptions& options = {});

}  // namespace rt
