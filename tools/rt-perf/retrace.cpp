#include "retrace.h"

#include <x86intrin.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_scene.h"
#include "rt/render/render.h"
#include "rt/render/surface_test.h"

namespace rt::perf {

namespace {

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n == 0 ? 0.0 : n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

// Flush-to-zero and denormals-are-zero for the scope, as render_image sets them on its threads.
class FlushDenormals {
 public:
  FlushDenormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | _MM_FLUSH_ZERO_ON | 0x0040 /* DAZ */); }
  ~FlushDenormals() { _mm_setcsr(saved_); }
  FlushDenormals(const FlushDenormals&) = delete;
  FlushDenormals& operator=(const FlushDenormals&) = delete;

 private:
  unsigned saved_;
};

struct RetraceArgs {
  std::string scene;
  int runs = 5;
  int threads = 0;
  bool json = false;
};

// Runs `work` on `threads` threads (0: all), timing it in wall-clock seconds.
template <class Work>
double timed_in_arena(int threads, Work&& work) {
  const auto start = std::chrono::steady_clock::now();
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(work);
  } else {
    work();
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

int run_retrace(const RetraceArgs& args) {
  const Scene scene = args.scene.empty() ? make_default_scene() : load_scene(args.scene);
  const FlatScene flat = flatten_scene(scene);
  const SceneSurfaceTest surface_test(scene, flat);  // alpha and culling, as rt render traces them
  const std::unique_ptr<Accel> accel = build_accel(AccelKind::embree, flat, with_surface_test({}, surface_test));
  RenderOptions options;
  options.threads = args.threads;

  const RecordingAccel recorder(*accel);
  const RenderResult recorded = render_image(scene, flat, recorder, options);
  const RecordingAccel::Queries queries = recorder.queries();
  std::uint64_t render_hits = 0;
  for (const std::uint64_t h : recorded.rays.hits_per_depth) render_hits += h;
  const RayCounts& rays = recorded.rays;
  const std::uint64_t closest = rays.camera + rays.reflection + rays.refraction + rays.see_through;
  const std::uint64_t shadow = rays.shadow + rays.area_light;  // point-light and area-light shadow rays
  const std::uint64_t recorded_closest = queries.coherent.size() + queries.closest.size();
  if (recorded_closest != closest || queries.shadow_total() != shadow)
    throw RuntimeError(fmt::format("recorded {} closest-hit and {} shadow queries, the render counted {} and {}",
                                   recorded_closest, queries.shadow_total(), closest, shadow));

  std::vector<double> render_s, retrace_s, ratios, coherent_s, closest_s, shadow_s;
  RetraceCounts counts;
  for (int run = 0; run < args.runs; ++run) {
    const double render = render_image(scene, flat, *accel, options).seconds;
    const double again = timed_in_arena(args.threads, [&] { counts = retrace(*accel, queries); });
    render_s.push_back(render);
    retrace_s.push_back(again);
    ratios.push_back(render / again);
    coherent_s.push_back(counts.coherent_s);
    closest_s.push_back(counts.closest_s);
    shadow_s.push_back(counts.shadow_s);
    if (!args.json)
      fmt::print(stderr, "rt-perf: run {} of {}: render {:.3f} s, re-trace {:.3f} s\n", run + 1, args.runs, render, again);
  }
  if (counts.hits != render_hits)
    throw RuntimeError(fmt::format("the re-trace found {} hits, the render {}", counts.hits, render_hits));

  nlohmann::ordered_json json;
  json["scene"] = scene.source;
  json["width"] = scene.settings.width;
  json["height"] = scene.settings.height;
  json["max_depth"] = scene.settings.max_depth;
  json["triangles"] = flat.triangle_count();
  json["rays"] = {{"camera", queries.coherent.size()}, {"reflection", queries.closest.size()},
                  {"shadow", queries.shadow_total()}, {"total", queries.total()}};
  json["runs"] = args.runs;
  json["render_s"] = median(render_s);
  json["retrace_s"] = median(retrace_s);
  json["ratio"] = median(ratios);
  json["retrace_camera_s"] = median(coherent_s);
  json["retrace_reflection_s"] = median(closest_s);
  json["retrace_shadow_s"] = median(shadow_s);
  json["render_s_all"] = render_s;
  json["retrace_s_all"] = retrace_s;
  if (args.json) {
    fmt::print("{}\n", json.dump());
  } else {
    fmt::print("{} ({}x{}, max depth {}, {} triangles): {} rays ({} camera, {} reflection, {} shadow)\n", scene.source,
               scene.settings.width, scene.settings.height, scene.settings.max_depth, flat.triangle_count(),
               queries.total(), queries.coherent.size(), queries.closest.size(), queries.shadow_total());
    fmt::print("render phase {:.4f} s, re-trace of its rays {:.4f} s (medians of {}); median ratio render / re-trace "
               "{:.2f}\n", median(render_s), median(retrace_s), args.runs, median(ratios));
    fmt::print("re-trace by kind (medians): camera packets {:.4f} s, reflection {:.4f} s, shadow {:.4f} s\n",
               median(coherent_s), median(closest_s), median(shadow_s));
  }
  return 0;
}

}  // namespace

struct RecordingAccel::Logs {
  struct Log {
    Queries queries;
  };
  tbb::enumerable_thread_specific<Log> per_thread;
};

RecordingAccel::RecordingAccel(const Accel& inner) : inner_(inner), logs_(std::make_unique<Logs>()) {}
RecordingAccel::~RecordingAccel() = default;

Hit RecordingAccel::intersect(const Ray& ray) const {
  logs_->per_thread.local().queries.closest.push_back(ray);
  return inner_.intersect(ray);
}

void RecordingAccel::intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits) const {
  Queries& log = logs_->per_thread.local().queries;
  log.coherent.insert(log.coherent.end(), rays.begin(), rays.end());
  log.group_sizes.push_back(static_cast<std::uint32_t>(rays.size()));
  inner_.intersect_coherent(rays, hits);
}

void RecordingAccel::occluded_coherent(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const {
  Queries& log = logs_->per_thread.local().queries;
  log.coherent_shadow.insert(log.coherent_shadow.end(), rays.begin(), rays.end());
  log.shadow_group_sizes.push_back(static_cast<std::uint32_t>(rays.size()));
  inner_.occluded_coherent(rays, blocked);
}

bool RecordingAccel::occluded(const Ray& ray) const {
  logs_->per_thread.local().queries.shadow.push_back(ray);
  return inner_.occluded(ray);
}

RecordingAccel::Queries RecordingAccel::queries() const {
  Queries all;
  const auto append = [](auto& to, const auto& from) { to.insert(to.end(), from.begin(), from.end()); };
  for (const Logs::Log& log : logs_->per_thread) {
    append(all.coherent, log.queries.coherent);
    append(all.group_sizes, log.queries.group_sizes);
    append(all.closest, log.queries.closest);
    append(all.shadow, log.queries.shadow);
    append(all.coherent_shadow, log.queries.coherent_shadow);
    append(all.shadow_group_sizes, log.queries.shadow_group_sizes);
  }
  return all;
}

namespace {

std::vector<std::size_t> group_starts(const std::vector<std::uint32_t>& sizes) {
  std::vector<std::size_t> start(sizes.size() + 1, 0);
  for (std::size_t g = 0; g < sizes.size(); ++g) start[g + 1] = start[g] + sizes[g];
  return start;
}

}  // namespace

RetraceCounts retrace(const Accel& accel, const RecordingAccel::Queries& queries) {
  const std::vector<std::size_t> group_start = group_starts(queries.group_sizes);
  const std::vector<std::size_t> shadow_group_start = group_starts(queries.shadow_group_sizes);
  std::atomic<std::uint64_t> hits{0}, occluded{0};
  RetraceCounts counts;
  auto start = std::chrono::steady_clock::now();
  const auto lap = [&start] {
    const auto now = std::chrono::steady_clock::now();
    return std::chrono::duration<double>(now - std::exchange(start, now)).count();
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.group_sizes.size(), 64), [&](const auto& range) {
    FlushDenormals flush;
    Hit found[64];
    std::uint64_t n = 0;
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      const std::size_t count = queries.group_sizes[g];
      for (std::size_t first = 0; first < count; first += 64) {
        const std::size_t part = std::min<std::size_t>(64, count - first);
        accel.intersect_coherent(std::span(queries.coherent).subspan(group_start[g] + first, part), std::span(found, part));
        for (std::size_t i = 0; i < part; ++i) n += found[i].found();
      }
    }
    hits += n;
  });
  counts.coherent_s = lap();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.closest.size(), 1024), [&](const auto& range) {
    FlushDenormals flush;
    std::uint64_t n = 0;
    for (std::size_t i = range.begin(); i != range.end(); ++i) n += accel.intersect(queries.closest[i]).found();
    hits += n;
  });
  counts.closest_s = lap();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.shadow.size(), 1024), [&](const auto& range) {
    FlushDenormals flush;
    std::uint64_t n = 0;
    for (std::size_t i = range.begin(); i != range.end(); ++i) n += accel.occluded(queries.shadow[i]);
    occluded += n;
  });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.shadow_group_sizes.size(), 64), [&](const auto& range) {
    FlushDenormals flush;
    std::uint8_t blocked[64];
    std::uint64_t n = 0;
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      const std::size_t count = queries.shadow_group_sizes[g];
      for (std::size_t first = 0; first < count; first += 64) {
        const std::size_t part = std::min<std::size_t>(64, count - first);
        accel.occluded_coherent(std::span(queries.coherent_shadow).subspan(shadow_group_start[g] + first, part),
                                std::span(blocked, part));
        for (std::size_t i = 0; i < part; ++i) n += blocked[i];
      }
    }
    occluded += n;
  });
  counts.shadow_s = lap();
  counts.hits = hits.load();
  counts.occluded = occluded.load();
  return counts;
}

std::function<int()> add_retrace_command(CLI::App& app) {
  auto args = std::make_shared<RetraceArgs>();
  CLI::App* command = app.add_subcommand(
      "retrace", "Render phase against Embree alone: record every ray a render traces, re-trace them in a tight loop");
  command->add_option("scene", args->scene, "Scene file (any format rt reads; default: the built-in default scene)");
  command->add_option("--runs", args->runs, "Render / re-trace pairs (medians, median of pairwise ratios)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  command->add_option("--threads", args->threads, "Threads for both (0 = all cores)")->check(CLI::Range(0, 1024));
  command->add_flag("--json", args->json, "Print one JSON object instead of text");
  return [args] { return run_retrace(*args); };
}

}  // namespace rt::perf
