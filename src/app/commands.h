#pragma once
// What `rt render` (one scene, a batch, or a region of an image), `rt view`, `rt merge` and `rt info` do.
// Internal to the app module: cli.cpp parses the flags and calls these.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "rt/app/scene_options.h"
#include "rt/io/load_gltf.h"
#include "rt/render/region.h"
#include "rt/render/shade.h"

namespace rt {

// A part of the image: --crop X0 Y0 X1 Y1 (region) or --tile K/N (k, n).
struct RegionRequest {
  std::optional<PixelRegion> crop;
  int k = 0, n = 0;  // n > 0: tile k of n (tile_region)

  bool given() const { return crop.has_value() || n > 0; }
};

struct RenderArgs {
  std::vector<std::string> scene_paths;  // none: the built-in default scene
  std::string output;                    // -o: one scene only
  std::string outdir;                    // --outdir: DIR/<scene stem>.png (or the region's name)
  bool skip_existing = false;
  RegionRequest region;
  std::optional<int> width, height, max_depth;
  std::optional<DisplayEncoding> display;  // --display, --exposure, --tonemap (docs/display.md)
  std::optional<double> exposure_ev;
  std::optional<ToneMap> tonemap;
  std::string accel = "embree";
  std::string embree_robust = "on";
  std::string embree_quality = "medium";
  std::string embree_kernel = "watertight";
  int sphere_tessellation = 0;
  std::string ray_offset = "robust";
  int threads = 0;
  std::uint64_t memory_limit = 0;  // bytes; 0: what the machine has available
  std::uint64_t texture_cache = 0;  // bytes; 0: half the available memory
  int spp = 1;
  std::string stats_path;
  bool explain = false;
  bool partial_output = false;      // on SIGINT/SIGTERM, write the finished tiles to <stem>.partial<ext>
  std::vector<int> debug_pixel;     // x y: trace that pixel's ray tree instead of rendering
  EffectsOptions effects;
  bool quiet = false;
  GltfOptions gltf;
  SceneOptions scene;
};

// rt view: one scene in a window (rt/view/viewer.h), with rt render's image settings.
struct ViewArgs {
  std::string scene_path;  // empty: the built-in default scene
  RenderArgs render;       // image settings; output: where S saves
  std::string screenshot;
  bool exit_when_done = false;
};

// Renders each scene in turn (a failing scene is reported and the batch goes on), returning the
// exit status: 0 all rendered or skipped, 1 some failed, 128 + signal when interrupted. A single
// scene's error propagates as an exception (InputError, UsageError, ...), as before batches.
int run_render(const RenderArgs& args);

// rt view: checks for a display first (RuntimeError pointing to rt render when there is none), then
// loads, flattens and builds the scene as rt render does and shows it. Returns the viewer's status.
int run_view(const ViewArgs& args);

// rt merge: stitches region files into `output` (merge_regions, then write_image). Returns 0;
// throws on error.
int run_merge(const std::vector<std::string>& paths, const std::string& output, bool quiet);

// rt info: what a scene contains, its framing and its effects plan on stdout; the loaders' notes and
// warnings on stderr unless `quiet`. Returns 0; throws on error.
int run_info(const std::string& scene_path, const GltfOptions& gltf, const SceneOptions& scene_options,
             const EffectsOptions& effects, bool quiet);

}  // namespace rt
