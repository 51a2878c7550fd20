#pragma once
// The batch render loop: tiles in parallel with TBB, one FindColor per pixel.

#include <functional>

#include "rt/accel/accel.h"
#include "rt/core/image.h"
#include "rt/render/shade.h"

namespace rt {

struct RenderOptions {
  int threads = 0;     // worker threads; 0 = all hardware threads
  int tile_size = 16;  // square tiles, in pixels
  // Camera rays per pixel, averaged with equal weights (a box filter over the pixel); 1 traces the
  // pixel centre exactly as the seed does, N > 1 stratified jittered samples (pixel_sample_offset).
  int samples_per_pixel = 1;
  RayOffset ray_offset{};
  EffectsOptions effects{};  // what may be skipped (exact pruning by default)
  // Estimate the share of render time per ray kind (RayCounts' tick counters) from one pixel in
  // eight; costs about 1% of render time.
  bool time_queries = false;
  // Called from worker threads (serialised) with the fraction of tiles done, in [0, 1].
  std::function<void(double)> on_progress;
};

struct RenderResult {
  Image image;
  EffectsPlan plan;  // what the render skipped, decided by plan_effects before the first ray
  RayCounts rays;
  double seconds = 0.0;  // wall-clock time of the render loop
};

// Renders scene.settings.width x height pixels. The image is bit-identical whatever the thread
// count or tile order: each pixel depends only on its own ray. Throws InputError on a bad camera.
RenderResult render_image(const Scene& scene, const FlatScene& flat, const Accel& accel,
                          const RenderOptions& options);

}  // namespace rt
