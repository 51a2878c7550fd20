#pragma once
// rt-perf export-mitsuba: a scene as `rt render` would render it (same loader, image size and
// scene flags, headlight included), flattened and written out for an outside renderer
// (tools/check-mitsuba builds a Mitsuba 3 scene from it): DIR/scene.json with the camera, lights,
// materials and spheres, and one binary PLY mesh per material, in world space.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>

#include "rt/flatten/flatten.h"
#include "rt/scene/scene.h"

namespace rt::perf {

// Registers the `export-mitsuba` subcommand on `app`; the returned function runs it once parsed
// and returns the exit status.
std::function<int()> add_export_command(CLI::App& app);

// Writes the triangles of `flat` whose material is `material` to `path` as a binary
// little-endian PLY: float x y z nx ny nz per vertex (world space, unit normals), faces as
// `vertex_indices` (uchar count, int indices) in the flattened order and winding. Vertices are
// renumbered in order of first use; `comment` (line breaks become spaces) goes into the header.
// Returns the number of triangles written; throws RuntimeError when the file cannot be written.
std::size_t write_material_ply(const FlatScene& flat, std::uint32_t material, const std::string& path,
                               std::string comment);

}  // namespace rt::perf
