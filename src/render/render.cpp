#include "rt/render/render.h"

#include "rt/render/surface_test.h"

#include <x86intrin.h>

#include <algorithm>
#include <array>
#include <span>
#include <atomic>
#include <cmath>
#include <chrono>
#include <cstring>
#include <mutex>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <fmt/format.h>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/render/camera.h"
#include "batch_shade.h"

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

// Timing every query costs two timestamp reads each (5-12% of the render), and a timed pixel takes
// the scalar shading path, so only one pixel in `stride` is timed, on diagonals ((x + 3 y) % stride
// == 0, stride a power of two) so that every row and column is sampled. The stride keeps about
// kTimedPixels pixels timed, enough for the shares of render time per ray kind: 8 below 256², 256
// from 1024². Timestamps are read only in blocks that hold a timed pixel. At 1 in 8, with
// timestamps around every packet, --stats made the 1024² diffuse torus's render 7% slower; now
// about 1.5% (docs/performance.md).
constexpr std::int64_t kTimedPixels = 4096;
int timing_stride(int width, int height) {
  const std::int64_t pixels = std::int64_t(width) * std::int64_t(height);
  int stride = 8;
  while (stride < 256 && pixels / (2 * stride) >= kTimedPixels) stride *= 2;
  return stride;
}
// A mask, not %: the stride is a power of two, and this runs for every pixel under --stats.
bool is_timing_sample(int x, int y, int stride) { return ((x + 3 * y) & (stride - 1)) == 0; }

// A block's recorded shadow rays (PendingShading::shadow_rays, world space) traced as packets,
// light slot by light slot so that a packet goes towards one light (a single light: in recorded
// order). The buffers are reused from block to block.
class BlockShadows {
 public:
  std::vector<std::uint8_t> blocked;  // per recorded shadow ray: 1 when occluded

  // Traces them all; returns the timestamp ticks the queries took when `timed`, else 0.
  std::uint64_t trace(const Accel& accel, const PendingShading& pending, std::size_t slot_count, bool timed) {
    const std::size_t count = pending.shadow_rays.size();
    blocked.assign(count, 0);
    if (count == 0) return 0;
    if (slot_count == 1) {
      const std::uint64_t start = timed ? __rdtsc() : 0;
      accel.occluded_coherent(pending.shadow_rays, blocked);
      return timed ? __rdtsc() - start : 0;
    }
    by_light_.clear();
    for (std::size_t light = 0; light < slot_count; ++light)
      for (std::size_t i = 0; i < count; ++i)
        if (pending.shadow_lights[i] == light) by_light_.push_back(static_cast<std::uint32_t>(i));
    grouped_rays_.resize(count);
    grouped_blocked_.resize(count);
    for (std::size_t i = 0; i < count; ++i) grouped_rays_[i] = pending.shadow_rays[by_light_[i]];
    const std::uint64_t start = timed ? __rdtsc() : 0;
    for (std::size_t first = 0; first < count;) {
      std::size_t last = first + 1;
      while (last < count && pending.shadow_lights[by_light_[last]] == pending.shadow_lights[by_light_[first]]) ++last;
      accel.occluded_coherent(std::span(grouped_rays_).subspan(first, last - first),
                              std::span(grouped_blocked_).subspan(first, last - first));
      first = last;
    }
    const std::uint64_t ticks = timed ? __rdtsc() - start : 0;
    for (std::size_t i = 0; i < count; ++i) blocked[by_light_[i]] = grouped_blocked_[i];
    return ticks;
  }

 private:
  std::vector<std::uint32_t> by_light_;  // shadow ray indices, grouped by light slot
  std::vector<Ray> grouped_rays_;
  std::vector<std::uint8_t> grouped_blocked_;
};

// Camera rays are traced in packets of kPacket x kPacket pixels and shaded in blocks of kBlock x
// kBlock (see render_image's render_block): a block's reflection rays are one wavefront, its
// shadow rays one batch. A block is a default tile: its wavefront of reflection rays (up to 256) is
// traced with the BVH warmer than 8 x 8 blocks left it (dragon Whitted render / re-trace 1.33 ->
// 1.31).
constexpr int kPacket = 4;
constexpr int kPacketPixels = kPacket * kPacket;
constexpr int kBlock = 16;
constexpr int kBlockPixels = kBlock * kBlock;
static_assert(kPacketPixels <= BatchShader::kLanes, "a packet's camera hits must fit the batch shader's lanes");
static_assert(kBlock % kPacket == 0);

// The order of a block's pixels: packet by packet, each packet's row by row. Pixel k is at (dx[k],
// dy[k]) from the block's corner and at cell[k] of its colour buffer (row-major, kBlock a row);
// row_of_four[k]: pixels k .. k + 3 are a packet's whole row; packet p is pixels
// [packet_start[p], packet_start[p + 1]).
struct BlockLayout {
  int pixels = 0, packets = 0;
  std::array<int, kBlockPixels> dx, dy, cell;
  std::array<bool, kBlockPixels> row_of_four;
  std::array<int, kBlockPixels / kPacketPixels + 1> packet_start;
};

// The layout of a w x h block (w, h <= kBlock).
BlockLayout layout_block(int w, int h) {
  BlockLayout layout;
  int n = 0;
  for (int py = 0; py < h; py += kPacket)
    for (int px = 0; px < w; px += kPacket) {
      layout.packet_start[std::size_t(layout.packets++)] = n;
      const int row_end = std::min(px + kPacket, w);
      for (int y = py; y < std::min(py + kPacket, h); ++y)
        for (int x = px; x < row_end; ++x, ++n) {
          layout.dx[std::size_t(n)] = x;
          layout.dy[std::size_t(n)] = y;
          layout.cell[std::size_t(n)] = y * kBlock + x;
          layout.row_of_four[std::size_t(n)] = x == px && row_end - px == 4;
        }
    }
  layout.packet_start[std::size_t(layout.packets)] = n;
  layout.pixels = n;
  return layout;
}

// Copies a w x h block of pixels (`colors`, `pitch` pixels a row) to image pixels from (x, y)
// with non-temporal stores: the image is not read again while rendering, so its 12 bytes a pixel
// need not pass through the caches (and evict the scene's data) on the way to memory. Fenced, so
// that another thread reading them after a later synchronisation sees them.
void stream_block(const Color* colors, int pitch, int x, int y, int w, int h, Image& image) {
  static_assert(sizeof(Color) == 3 * sizeof(float));
  for (int row = 0; row < h; ++row) {
    auto* to = reinterpret_cast<unsigned char*>(&image.at(x, y + row));
    const auto* from = reinterpret_cast<const unsigned char*>(&colors[std::size_t(row * pitch)]);
    std::size_t bytes = std::size_t(w) * sizeof(Color), done = 0;
    const auto stream_word = [&] {
      std::int32_t word;
      std::memcpy(&word, from + done, sizeof word);
      _mm_stream_si32(reinterpret_cast<int*>(to + done), word);
      done += sizeof word;
    };
    while (done < bytes && (reinterpret_cast<std::uintptr_t>(to + done) & 15) != 0) stream_word();
    for (; done + 16 <= bytes; done += 16)
      _mm_stream_si128(reinterpret_cast<__m128i*>(to + done), _mm_loadu_si128(reinterpret_cast<const __m128i*>(from + done)));
    while (done < bytes) stream_word();
  }
  _mm_sfence();
}

}  // namespace

namespace {

PixelRegion checked_region(const Scene& scene, const std::optional<PixelRegion>& region) {
  const int width = scene.settings.width, height = scene.settings.height;
  if (!region) return full_region(width, height);
  if (!region->inside(width, height))
    throw InputError(scene.source, "", fmt::format("the region {} (x0 y0 x1 y1) is empty or outside the {}x{} image",
                                                   to_string(*region), width, height));
  return *region;
}

}  // namespace

void check_render_memory(const Scene& scene, const std::optional<PixelRegion>& region) {
  // Per pixel: the float RGB image, its 8-bit copy and the encoded file, which write_image builds
  // in memory (at most the float size, for uncompressed EXR).
  constexpr std::uint64_t kBytesPerPixel = sizeof(Color) + 3 + sizeof(Color);
  const PixelRegion pixels = checked_region(scene, region);
  if (const auto shortfall = memory_shortfall(pixels.pixel_count() * kBytesPerPixel))
    throw InputError(scene.source, "", fmt::format("a {}x{} image {} ({} bytes per pixel)", pixels.width(),
                                                   pixels.height(), *shortfall, kBytesPerPixel));
}

RenderResult render_image(const Scene& scene, const FlatScene& flat, const Accel& accel,
                          const RenderOptions& options) {
  const auto entered = std::chrono::steady_clock::now();
  check_render_memory(scene, options.region);
  const int width = scene.settings.width;
  const PixelRegion region = checked_region(scene, options.region);
  const CameraFrame frame = make_camera_frame(scene.camera, width, scene.settings.height, scene.source);
  const PixelCentreRays centre_rays(frame);
  const int stride = timing_stride(width, scene.settings.height);  // of the timed pixels (options.time_queries)
  const TextureSampler textures(scene, options.texture_cache_bytes);
  RenderResult result;
  result.textures = textures.use();
  result.plan = plan_effects(scene, flat, options.ray_offset, options.effects, &textures);
  ShadingContext context{scene, flat, accel, result.plan, options.ray_offset, &textures, false};
  context.alpha = scene_alpha_of(accel);
  ShadingContext timed_context = context;
  timed_context.time_queries = true;
  const int tile = std::max(1, options.tile_size);
  const int spp = std::max(1, options.samples_per_pixel);
  if (options.sample_index >= spp)
    throw std::invalid_argument(fmt::format("sample_index {} of {} samples", options.sample_index, spp));
  const int tiles_x = (region.width() + tile - 1) / tile, tiles_y = (region.height() + tile - 1) / tile;
  const int tile_count = tiles_x * tiles_y;

  result.region = region;
  result.image = Image(region.width(), region.height());
  result.tile_done.assign(std::size_t(tile_count), 0);
  struct ThreadState {
    RayCounts counts;
    // Buffers of the camera blocks, reused from block to block.
    PendingShading pending;
    BlockShadows shadows;
    BatchShader::Workspace batch;
    // A block's rays, hits, per-pixel sums and timing ticks: kept here, not built (and zeroed)
    // per block.
    std::array<Ray, kBlockPixels> rays;
    std::array<Hit, kBlockPixels> hits;
    std::array<Vec3d, kBlockPixels> sums;
    std::array<std::uint64_t, kBlockPixels> ticks{};
    std::uint64_t non_finite = 0;
    std::uint64_t first_non_finite = ~std::uint64_t(0);  // row-major pixel index
    // The colours of the block being rendered (row-major, kBlock pixels a row), streamed into the
    // image once the block is done: a small buffer that stays in the cache from block to block.
    std::array<Color, kBlockPixels> block_colors;
  };
  tbb::enumerable_thread_specific<ThreadState> thread_states;
  std::atomic<int> tiles_done{0};
  std::mutex progress_mutex;
  const auto cancelled = [&] { return options.cancel && options.cancel->load(std::memory_order_relaxed); };

  // One sample's colour at pixel (x, y), with the NaN/Inf guard: a non-finite colour becomes black
  // and is counted. x - x is 0 for a finite x and NaN for an infinite or NaN one: one test for the
  // three channels.
  const auto guarded = [width](Color c, ThreadState& state, int x, int y) {
    if ((c.r - c.r) + (c.g - c.g) + (c.b - c.b) == 0.0f) [[likely]]
      return c;
    ++state.non_finite;
    state.first_non_finite = std::min(state.first_non_finite, std::uint64_t(y) * std::uint64_t(width) + std::uint64_t(x));
    return Color(0.0f);
  };

  // A block's camera rays are traced a kPacket x kPacket packet at a time, per sample index
  // (Embree: one 16-ray packet); their shadow rays are recorded, traced together light by light,
  // and each pixel's terms then summed as shade_hit sums them (PendingShading). When timed, a
  // timed pixel is charged an equal share of its packets' ticks, so the shares stay fractions of
  // the timed pixels' loop ticks.
  // Light slots: the scene's lights, then the emitters (RayCounts::add_shadow_query).
  const std::size_t light_count = scene.lights.size();
  const std::size_t slot_count = light_count + result.plan.emitters.size();
  const bool sampled_lights = result.plan.area_lights != nullptr;  // the only reader of the path seed
  const BatchShader batch(context);
  const bool batching = options.batch_shading && batch.enabled();
  const BlockLayout whole_layout = layout_block(kBlock, kBlock);
  const Color background = batch.background();
  const bool background_is_finite = std::isfinite(background.r) && std::isfinite(background.g) && std::isfinite(background.b);
  const auto render_block = [&](int bx0, int by0, int bx1, int by1, ThreadState& state) {
    RayCounts& counts = state.counts;
    PendingShading& pending = state.pending;
    // The block's pixels (a whole block's layout is made once); pixel k is (xs[k], ys[k]).
    BlockLayout edge_layout;
    const bool whole = bx1 - bx0 == kBlock && by1 - by0 == kBlock;
    if (!whole) edge_layout = layout_block(bx1 - bx0, by1 - by0);
    const BlockLayout& layout = whole ? whole_layout : edge_layout;
    const int n = layout.pixels, packets = layout.packets;
    const std::array<int, kBlockPixels / kPacketPixels + 1>& packet_start = layout.packet_start;
    const std::array<int, kBlockPixels>& cell = layout.cell;
    const std::array<bool, kBlockPixels>& row_of_four = layout.row_of_four;
    std::array<int, kBlockPixels> xs, ys;
    for (int k = 0; k < n; ++k) {
      xs[std::size_t(k)] = bx0 + layout.dx[std::size_t(k)];
      ys[std::size_t(k)] = by0 + layout.dy[std::size_t(k)];
    }
    std::array<bool, kBlockPixels> timed{};
    std::array<std::uint64_t, kBlockPixels>& ticks = state.ticks;  // per timed pixel: its loop ticks this sample
    bool block_timed = false;  // any pixel of the block timed: only then are its queries timed
    if (options.time_queries)
      for (int k = 0; k < n; ++k) block_timed |= timed[k] = is_timing_sample(xs[k], ys[k], stride);
    std::array<Vec3d, kBlockPixels>& sums = state.sums;  // linear RGB, double: the box filter's average (spp > 1)
    if (spp > 1) sums.fill(Vec3d(0.0));
    std::array<Ray, kBlockPixels>& rays = state.rays;
    std::array<Hit, kBlockPixels>& hits = state.hits;
    const bool one_sample = options.sample_index >= 0;  // the image holds sample sample_index alone
    const int first_sample = one_sample ? options.sample_index : 0;
    const int end_sample = one_sample ? options.sample_index + 1 : spp;
    for (int s = first_sample; s < end_sample; ++s) {
      if (spp == 1)
        for (int k = 0; k < n;) {
          if (row_of_four[k]) {  // its rays in SIMD lanes
            centre_rays.set_rays4(&rays[std::size_t(k)], xs[k], ys[k]);
            k += 4;
          } else {
            centre_rays.set_ray(rays[k], xs[k], ys[k]);
            ++k;
          }
        }
      else
        for (int k = 0; k < n; ++k) rays[k] = ray_through_pixel_sample(frame, xs[k], ys[k], s, spp);
      pending.clear();
      std::array<std::int32_t, kBlockPixels> pixel_of;  // per pixel k: its record in pending.pixels, or -1
      std::array<bool, kBlockPixels / kPacketPixels> packet_hit;  // per packet: some ray of it hit
      if (batching) batch.start_block(state.batch);
      // Packet p is traced, then shaded two packets later: the triangle indices its hits need are
      // requested after its trace, their vertices after the next one, so that the batch shader's
      // gathers find them in the cache. Packets are still shaded in order, so the records are the
      // same as when each is shaded right after its trace.
      const auto packet_of = [&](auto& block_array, int p) {  // packet p's part of rays, hits or timed
        const int first = packet_start[std::size_t(p)], count = packet_start[std::size_t(p) + 1] - first;
        return std::span(block_array).subspan(std::size_t(first), std::size_t(count));
      };
      const auto trace_packet = [&](int p) {
        const int first = packet_start[std::size_t(p)], count = packet_start[std::size_t(p) + 1] - first;
        const bool packet_timed = block_timed && std::any_of(timed.begin() + first, timed.begin() + first + count,
                                                             [](bool t) { return t; });
        const std::uint64_t start = packet_timed ? __rdtsc() : 0;
        accel.intersect_coherent(packet_of(rays, p), packet_of(hits, p));
        packet_hit[std::size_t(p)] = std::any_of(hits.begin() + first, hits.begin() + first + count,
                                                 [](const Hit& hit) { return hit.found(); });
        if (packet_timed) {
          const std::uint64_t share = (__rdtsc() - start) / std::uint64_t(count);
          if (counts.intersect_ticks_per_depth.empty()) counts.intersect_ticks_per_depth.resize(1, 0);
          for (int k = first; k < first + count; ++k)
            if (timed[k]) {
              counts.intersect_ticks_per_depth[0] += share;
              ticks[k] = share;
            }
        }
      };
      const auto shade_packet = [&](int p) {
        const int first = packet_start[std::size_t(p)], count = packet_start[std::size_t(p) + 1] - first;
        if (batching && !block_timed && !packet_hit[std::size_t(p)]) {  // the background, without records
          std::fill_n(pixel_of.begin() + first, count, -1);
          return;
        }
        if (batching)  // the timed pixels are left to shade_camera_hit, which times them
          batch.prepare(packet_of(rays, p), packet_of(hits, p), packet_of(timed, p), state.batch);
        for (int k = first; k < first + count; ++k) {
          const int lane = k - first;
          if (batching && !timed[k] && !hits[k].found()) {
            pixel_of[k] = -1;  // the background, without a record
            continue;
          }
          pixel_of[k] = static_cast<std::int32_t>(pending.pixels.size());
          if (batching && state.batch.lane_of[std::size_t(lane)] >= 0) {
            batch.finish_camera_hit(state.batch, lane, rays[std::size_t(k)], hits[std::size_t(k)],
                                    sampled_lights ? pixel_path_seed(xs[k], ys[k], s) : 0, counts, pending);
            continue;
          }
          const std::uint64_t start = timed[k] ? __rdtsc() : 0;
          shade_camera_hit(timed[k] ? timed_context : context, rays[k], hits[k],
                           sampled_lights ? pixel_path_seed(xs[k], ys[k], s) : 0, counts, pending);
          if (timed[k]) ticks[k] += __rdtsc() - start;
        }
      };
      for (int p = 0; p < packets + 2; ++p) {
        if (p < packets) {
          trace_packet(p);
          if (batching && packet_hit[std::size_t(p)]) batch.prefetch_triangles(packet_of(hits, p));
        }
        if (batching && p >= 1 && p <= packets && packet_hit[std::size_t(p - 1)])
          batch.prefetch_vertices(packet_of(hits, p - 1));
        if (p >= 2) shade_packet(p - 2);
      }
      if (batching) batch.trace_reflections(state.batch, counts, pending);

      const std::uint64_t shadow_ticks = state.shadows.trace(accel, pending, slot_count, block_timed);
      const std::size_t shadow_count = pending.shadow_rays.size();
      if (shadow_count > 0 && block_timed) {
        const std::uint64_t share = shadow_ticks / std::uint64_t(shadow_count);
        for (int k = 0; k < n; ++k) {
          if (!timed[k]) continue;
          const PendingShading::Pixel& p = pending.pixels[std::size_t(pixel_of[k])];
          for (std::uint32_t t = p.first_term; t < p.first_term + p.term_count; ++t) {
            const std::uint32_t query = pending.terms[t].query;
            if (query == PendingShading::kNoQuery) continue;
            counts.add_shadow_ticks(light_count, pending.shadow_lights[query], share);
            ticks[k] += share;
          }
        }
      }

      // The block's colours. What the loop reads of the state is held in locals, so that it is not
      // reloaded after every store of a colour.
      Color* const block_colors = state.block_colors.data();
      const std::span<const std::uint8_t> blocked = state.shadows.blocked;
      const auto color_of = [&](int k) {
        return guarded(pixel_of[k] < 0 ? background : finish_camera_hit(pending, std::size_t(pixel_of[k]), blocked), state,
                       xs[k], ys[k]);
      };
      const bool store_colors = spp == 1 || one_sample;
      if (store_colors && !block_timed) {  // the common case, without the timing and sum branches
        for (int p = 0; p < packets; ++p)
          if (batching && !packet_hit[std::size_t(p)] && background_is_finite)
            for (int k = packet_start[std::size_t(p)]; k < packet_start[std::size_t(p) + 1]; ++k)
              block_colors[cell[k]] = background;
          else
            for (int k = packet_start[std::size_t(p)]; k < packet_start[std::size_t(p) + 1]; ++k)
              block_colors[cell[k]] = color_of(k);
        continue;
      }
      for (int k = 0; k < n; ++k) {
        const std::uint64_t start = timed[k] ? __rdtsc() : 0;
        const Color c = color_of(k);
        if (store_colors)
          block_colors[cell[k]] = c;
        else
          sums[k] += Vec3d(c);
        if (timed[k]) counts.loop_ticks += ticks[k] + (__rdtsc() - start);
      }
    }
    if (spp > 1 && !one_sample)
      for (int k = 0; k < n; ++k) state.block_colors[std::size_t(cell[k])] = Color(sums[k] / double(spp));
    stream_block(state.block_colors.data(), kBlock, bx0 - region.x0, by0 - region.y0, bx1 - bx0, by1 - by0, result.image);
    counts.camera += std::uint64_t(end_sample - first_sample) * std::uint64_t(n);
  };

  auto render_tiles = [&](const tbb::blocked_range<int>& range) {
    ScopedFlushDenormals flush;
    ThreadState& state = thread_states.local();
    for (int t = range.begin(); t != range.end(); ++t) {
      const int x0 = region.x0 + (t % tiles_x) * tile, y0 = region.y0 + (t / tiles_x) * tile;
      const int x1 = std::min(x0 + tile, region.x1), y1 = std::min(y0 + tile, region.y1);
      bool abandoned = false;
      for (int by = y0; by < y1 && !abandoned; by += kBlock) {
        if (cancelled()) {
          abandoned = true;
          break;
        }
        for (int bx = x0; bx < x1; bx += kBlock)
          render_block(bx, by, std::min(bx + kBlock, x1), std::min(by + kBlock, y1), state);
      }
      if (abandoned) {  // unfinished tiles are black, whatever rows were done
        for (int y = y0; y < y1; ++y)
          for (int x = x0; x < x1; ++x) result.image.at(x - region.x0, y - region.y0) = Color(0.0f);
        continue;
      }
      result.tile_done[std::size_t(t)] = 1;
      const int done = ++tiles_done;
      if (done == 1)
        result.first_tile_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - entered).count();
      if (options.on_tile || options.on_progress) {
        std::lock_guard lock(progress_mutex);
        if (options.on_tile) options.on_tile(PixelRegion{x0, y0, x1, y1}, result.image);
        if (options.on_progress) options.on_progress(static_cast<double>(done) / tile_count);
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
  std::uint64_t first_non_finite = ~std::uint64_t(0);
  for (const ThreadState& state : thread_states) {
    result.rays += state.counts;
    result.non_finite_samples += state.non_finite;
    first_non_finite = std::min(first_non_finite, state.first_non_finite);
  }
  if (result.non_finite_samples > 0)
    result.first_non_finite_pixel = {int(first_non_finite % std::uint64_t(width)), int(first_non_finite / std::uint64_t(width))};
  return result;
}

std::vector<std::string> trace_pixel(const Scene& scene, const FlatScene& flat, const Accel& accel,
                                     const RenderOptions& options, int x, int y) {
  const int width = scene.settings.width, height = scene.settings.height;
  if (x < 0 || y < 0 || x >= width || y >= height)
    throw InputError(scene.source, "", fmt::format("pixel ({}, {}) is outside the {}x{} image", x, y, width, height));
  const CameraFrame frame = make_camera_frame(scene.camera, width, height, scene.source);
  const TextureSampler textures(scene, options.texture_cache_bytes);
  const EffectsPlan plan = plan_effects(scene, flat, options.ray_offset, options.effects, &textures);
  std::vector<std::string> lines;
  ShadingContext context{scene, flat, accel, plan, options.ray_offset, &textures, false};
  context.alpha = scene_alpha_of(accel);
  context.trace = &lines;
  const int spp = std::max(1, options.samples_per_pixel);
  ScopedFlushDenormals flush;  // as in render_image, so the trace shows the values the render computes
  RayCounts counts;
  Vec3d sum(0.0);
  for (int s = 0; s < spp; ++s) {
    const Vec2d offset = pixel_sample_offset(x, y, s, spp);
    lines.push_back(fmt::format("pixel ({}, {}) sample {} of {} at ({:.6g}, {:.6g}) in the pixel:", x, y, s + 1, spp,
                                offset.x, offset.y));
    const Color c = find_color(context, spp == 1 ? ray_through_pixel(frame, x, y)
                                                 : ray_through_pixel_sample(frame, x, y, s, spp), 0, counts,
                               Vec3d(1.0), pixel_path_seed(x, y, s));
    const bool finite = std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b);
    if (!finite) lines.push_back("  NOT FINITE: the render replaces this sample by black");
    sum += finite ? Vec3d(c) : Vec3d(0.0);
  }
  const Vec3d average = sum / double(spp);
  lines.push_back(fmt::format("pixel ({}, {}) = ({:.6g}, {:.6g}, {:.6g}) linear RGB, {} rays", x, y, average.x,
                              average.y, average.z, counts.total() + std::uint64_t(spp)));
  return lines;
}

int RenderResult::tiles_finished() const { return int(std::count(tile_done.begin(), tile_done.end(), 1)); }

}  // namespace rt
