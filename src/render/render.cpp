#include "rt/render/render.h"

#include <x86intrin.h>

#include <atomic>
#include <chrono>
#include <mutex>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "rt/render/camera.h"

namespace rt {

namespace {

// Embree asks for flush-to-zero and denormals-are-zero on rendering threads (speed). The mode is
// set per tile and restored afterwards, so every pixel is computed under the same mode whichever
// thread runs it, and the caller's thread is left as it was.
class ScopedFlushDenormals {
 public:
  ScopedFlushDenormals() : saved_(_mm_getcsr()) {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
  }
  ~ScopedFlushDenormals() { _mm_setcsr(saved_); }
  ScopedFlushDenormals(const ScopedFlushDenormals&) = delete;
  ScopedFlushDenormals& operator=(const ScopedFlushDenormals&) = delete;

 private:
  unsigned saved_;
};

// Timing every query costs two timestamp reads each (5-12% of the render); timing one pixel in
// kTimingStride, on diagonals so that every column and row is sampled, estimates the shares of
// render time per ray kind for about a eighth of that.
constexpr int kTimingStride = 8;
bool is_timing_sample(int x, int y) { return (x + 3 * y) % kTimingStride == 0; }

}  // namespace

RenderResult render_image(const Scene& scene, const FlatScene& flat, const Accel& accel,
                          const RenderOptions& options) {
  const int width = scene.settings.width, height = scene.settings.height;
  const CameraFrame frame = make_camera_frame(scene.camera, width, height, scene.source);
  const TextureSampler textures(scene);
  RenderResult result;
  result.plan = plan_effects(scene, flat, options.ray_offset, options.effects);
  const ShadingContext context{scene, flat, accel, result.plan, options.ray_offset, &textures, false};
  const ShadingContext timed_context{scene, flat, accel, result.plan, options.ray_offset, &textures, true};
  const int tile = std::max(1, options.tile_size);
  const int spp = std::max(1, options.samples_per_pixel);
  const int tiles_x = (width + tile - 1) / tile, tiles_y = (height + tile - 1) / tile;
  const int tile_count = tiles_x * tiles_y;

  result.image = Image(width, height);
  tbb::enumerable_thread_specific<RayCounts> thread_counts;
  std::atomic<int> tiles_done{0};
  std::mutex progress_mutex;

  auto render_tiles = [&](const tbb::blocked_range<int>& range) {
    ScopedFlushDenormals flush;
    RayCounts& counts = thread_counts.local();
    for (int t = range.begin(); t != range.end(); ++t) {
      const int x0 = (t % tiles_x) * tile, y0 = (t / tiles_x) * tile;
      const int x1 = std::min(x0 + tile, width), y1 = std::min(y0 + tile, height);
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const bool timed = options.time_queries && is_timing_sample(x, y);
          const std::uint64_t start = timed ? __rdtsc() : 0;
          if (spp == 1) {
            result.image.at(x, y) = find_color(timed ? timed_context : context, ray_through_pixel(frame, x, y), 0, counts);
          } else {
            Vec3d sum(0.0);  // linear RGB, double: the box filter's average
            for (int s = 0; s < spp; ++s)
              sum += Vec3d(find_color(timed ? timed_context : context, ray_through_pixel_sample(frame, x, y, s, spp), 0, counts));
            result.image.at(x, y) = Color(sum / double(spp));
          }
          counts.camera += std::uint64_t(spp);
          if (timed) counts.loop_ticks += __rdtsc() - start;
        }
      const int done = ++tiles_done;
      if (options.on_progress) {
        std::lock_guard lock(progress_mutex);
        options.on_progress(static_cast<double>(done) / tile_count);
      }
    }
  };

  const auto start = std::chrono::steady_clock::now();
  const tbb::blocked_range<int> all_tiles(0, tile_count, 1);
  if (options.threads > 0) {
    tbb::task_arena arena(options.threads);
    arena.execute([&] { tbb::parallel_for(all_tiles, render_tiles, tbb::simple_partitioner()); });
  } else {
    tbb::parallel_for(all_tiles, render_tiles, tbb::simple_partitioner());
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const RayCounts& counts : thread_counts) result.rays += counts;
  return result;
}

}  // namespace rt
