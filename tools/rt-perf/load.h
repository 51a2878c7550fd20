#pragma once
// rt-perf load: how long the scene loaders take per file (parse + the in-memory Scene, as `rt
// render` loads it, before flattening and the BVH), against a raw read of the same bytes.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "intersect.h"

namespace rt::perf {

// Registers the `load` subcommand on `app`; the returned function runs it once parsed and returns
// the exit status.
std::function<int()> add_load_command(CLI::App& app);

// The files a load of `path` reads whole: the scene file and, for a .gltf, the buffers and images
// its "buffers" and "images" arrays name by a relative URI that exists (data: URIs are inside the
// file). For every other format only the scene file (not an OBJ's MTL libraries, not the meshes a
// JSON scene names, not a .glb's external images). `counted` says which in words.
struct SceneBytes {
  std::vector<std::string> files;
  std::uint64_t bytes = 0;
  std::string counted;
};
// Throws InputError when `path` is not a regular file.
SceneBytes scene_input_files(const std::string& path);

// Wall-clock seconds of `runs` loads of one file with load_scene, and of `runs` raw reads of its
// input files into memory (the page cache is warm for both: the files are read before timing).
struct LoadMeasurement {
  std::string path;
  SceneBytes input;
  Timing load;
  Timing read;
  // input.bytes / median seconds, in MB/s with 1 MB = 10^6 bytes; 0 when the median is 0.
  double load_mb_per_second() const;
  double read_mb_per_second() const;
};
// Throws InputError for a missing or malformed scene (what load_scene throws).
LoadMeasurement measure_load(const std::string& path, int runs);

// One measurement as a JSON object: file, bytes, bytes_counted, files, runs, load_median_s,
// load_min_s, load_mb_per_s, read_median_s, read_min_s, read_mb_per_s.
nlohmann::json to_json(const LoadMeasurement& measurement);

}  // namespace rt::perf
