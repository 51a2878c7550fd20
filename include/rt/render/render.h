#pragma once
// The batch render loop: tiles in parallel with TBB, one FindColor per pixel.

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rt/accel/accel.h"
#include "rt/core/image.h"
#include "rt/render/region.h"
#include "rt/render/texture.h"
#include "rt/render/shade.h"

namespace rt {

struct RenderOptions {
  int threads = 0;     // worker threads; 0 = all hardware threads
  int tile_size = 16;  // square tiles, in pixels
  // Camera rays per pixel, averaged with equal weights (a box filter over the pixel); 1 traces the
  // pixel centre exactly as the seed does, N > 1 stratified jittered samples (pixel_sample_offset).
  int samples_per_pixel = 1;
  // When >= 0: trace only sample `sample_index` of the samples_per_pixel stratified samples, and
  // the image holds that sample's colour instead of the average. Summing the images of samples
  // 0, 1, ... in order (double) and dividing by samples_per_pixel gives the full render bit for bit
  // (rt view's progressive accumulation).
  int sample_index = -1;
  RayOffset ray_offset{};
  EffectsOptions effects{};  // what may be skipped (exact pruning by default)
  // Estimate the share of render time per ray kind (RayCounts' tick counters) from one pixel in
  // eight; costs about 1% of render time. The timed pixels are shaded one by one (shade_camera_hit,
  // not the batch shader), so the shares are those of that path.
  bool time_queries = false;
  // Shade the camera and reflection hits of plain materials a block at a time (the batch shader,
  // src/render/batch_shade.h). The image and the counts are the same bit for bit either way; false
  // runs shade_camera_hit and find_color for every pixel.
  bool batch_shading = true;
  // Called from worker threads (serialised) with the fraction of tiles done, in [0, 1].
  std::function<void(double)> on_progress;
  // Called from worker threads (serialised, before on_progress) when a tile is finished, with its
  // pixels in full-image coordinates and the image being filled (image.at(x - region.x0, y -
  // region.y0) is pixel (x, y); the tile's pixels are final, other tiles may be in progress).
  std::function<void(const PixelRegion& tile, const Image& image)> on_tile;
  // When set and it becomes true (e.g. from a signal handler), the render stops within a row of
  // pixels: no tile is started after that and the tile in progress is abandoned.
  const std::atomic<bool>* cancel = nullptr;
  // The pixels to render, in full-image coordinates; unset: the whole image. Each pixel is the
  // same as in a render of the whole image, bit for bit (--crop, --tile, rt merge).
  std::optional<PixelRegion> region;
  // The texture cache's size in bytes (TextureSampler; --texture-cache); 0: half the available memory.
  std::uint64_t texture_cache_bytes = 0;
};

struct RenderResult {
  Image image;          // the region's pixels: image.at(x - region.x0, y - region.y0) is pixel (x, y)
  PixelRegion region;   // what was rendered, in full-image coordinates
  EffectsPlan plan;  // what the render skipped, decided by plan_effects before the first ray
  RayCounts rays;
  TextureUse textures;  // how the textures were sampled
  double seconds = 0.0;  // wall-clock time of the render loop
  // Wall-clock time from entering render_image (texture set-up and the effects plan included) to
  // the first finished tile: when the first pixels could be shown. 0 when no tile finished.
  double first_tile_seconds = 0.0;
  // One flag per tile (RenderOptions::tile_size squares over the region, row-major): 1 when
  // finished, which all are unless the render was cancelled. Unfinished tiles are black in `image`.
  std::vector<std::uint8_t> tile_done;
  // Samples whose colour was NaN or infinite, replaced by black (a guard: shading should never
  // produce one), and the first such pixel in row-major order (full-image coordinates).
  std::uint64_t non_finite_samples = 0;
  std::optional<std::pair<int, int>> first_non_finite_pixel;  // (x, y)

  int tile_count() const { return int(tile_done.size()); }
  int tiles_finished() const;
  bool cancelled() const { return tiles_finished() < tile_count(); }
};

// Throws InputError naming scene.source when the image a render of `region` (default: the whole
// image) allocates (float RGB, plus the 8-bit copy an output file needs) does not fit in available
// memory (rt/core/memory.h). render_image checks it; callers may check earlier, before loading and
// building the rest.
void check_render_memory(const Scene& scene, const std::optional<PixelRegion>& region = {});

// Renders options.region (default: all scene.settings.width x height pixels). The image is
// bit-identical whatever the thread count, tile order or region: each pixel depends only on its
// own rays. Throws InputError on a bad camera or a region outside the image.
RenderResult render_image(const Scene& scene, const FlatScene& flat, const Accel& accel,
                          const RenderOptions& options);

// The pixel (x, y) rendered alone with a trace of its ray tree: for every sample, each ray (camera,
// reflection, shadow) with origin, direction and what it hit, each light's term or the rule that
// skipped it, and the colours returned. One line per event, indented by depth. For --debug-pixel.
std::vector<std::string> trace_pixel(const Scene& scene, const FlatScene& flat, const Accel& accel,
                                     const RenderOptions& options, int x, int y);

}  // namespace rt
