#pragma once
// Wavefront OBJ geometry through tinyobjloader.

#include <string>

#include "rt/scene/scene.h"

namespace rt {

// Loads every face of the OBJ at `path` into one object-space mesh; polygons are triangulated,
// `vn` normals are used when every face has them, smooth angle-weighted normals otherwise.
// Materials are ignored here. Throws InputError for a missing or malformed file.
TriangleMesh load_obj_mesh(const std::string& path);

}  // namespace rt
