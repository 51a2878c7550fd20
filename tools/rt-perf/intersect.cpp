#include "intersect.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <string>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "rt/accel/embree_accel.h"
#include "rt/core/error.h"
#include "rt/io/load_scene.h"
#include "rt/render/camera.h"
#include "rt/render/ray_offset.h"
#include "rt/scene/shapes.h"

namespace rt::perf {

std::vector<Ray> make_camera_rays(const Scene& scene, int width, int height) {
  const CameraFrame frame = make_camera_frame(scene.camera, width, height, scene.source);
  std::vector<Ray> rays;
  rays.reserve(std::size_t(width) * std::size_t(height));
  for (int j = 0; j < height; ++j)
    for (int i = 0; i < width; ++i) rays.push_back(ray_through_pixel(frame, i, j));
  return rays;
}

std::vector<Ray> make_shadow_rays(const Scene& scene, const FlatScene& flat, const Accel& accel,
                                  std::span<const Ray> camera_rays) {
  const RayOffset policy;
  std::vector<Ray> rays;
  for (const Ray& ray : camera_rays) {
    const Hit hit = accel.intersect(ray);
    if (!hit.found()) continue;
    SurfacePoint surface;
    if (flat.is_sphere(hit.primitive)) {
      surface = make_sphere_surface_point(flat.sphere_of(hit.primitive), Vec3d(ray.origin), Vec3d(ray.direction),
                                          hit.t);
    } else {
      const Vec3u tri = flat.triangles[hit.primitive];
      surface = make_surface_point(Vec3d(flat.positions[tri.x]), Vec3d(flat.positions[tri.y]),
                                   Vec3d(flat.positions[tri.z]), hit.u, hit.v);
    }
    for (const Light& light : scene.lights) {
      Vec3d to_light = Vec3d(light.position);
      if (!light.is_directional()) to_light -= surface.point;
      const double length = glm::length(to_light);
      if (!(length > 0.0)) continue;
      to_light /= length;
      Ray shadow;
      shadow.origin = offset_ray_origin(policy, surface, to_light);
      shadow.direction = Vec3f(to_light);
      if (!light.is_directional()) {
        const double tfar = shadow_ray_tfar(policy, Vec3d(shadow.origin), Vec3d(light.position));
        if (!(tfar > 0.0)) continue;
        shadow.tfar = static_cast<float>(tfar);
      }
      rays.push_back(shadow);
    }
  }
  return rays;
}

std::vector<Ray> make_incoherent_rays(const Bounds3d& box, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Vec3d lower = box.empty() ? Vec3d(0.0) : box.lo, upper = box.empty() ? Vec3d(0.0) : box.hi;
  std::vector<Ray> rays(count);
  for (Ray& ray : rays) {
    Vec3d origin;
    for (int k = 0; k < 3; ++k) origin[k] = lower[k] + unit(rng) * (upper[k] - lower[k]);
    // Uniform on the sphere: z uniform in [-1, 1] (Archimedes), azimuth uniform.
    const double z = 2.0 * unit(rng) - 1.0;
    const double phi = 2.0 * std::numbers::pi * unit(rng);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    ray.origin = Vec3f(origin);
    ray.direction = Vec3f(Vec3d(r * std::cos(phi), r * std::sin(phi), z));
  }
  return rays;
}

std::vector<std::size_t> spread_indices(std::size_t size, std::size_t count) {
  count = std::min(count, size);
  std::vector<std::size_t> indices(count);
  for (std::size_t k = 0; k < count; ++k)
    indices[k] = static_cast<std::size_t>((static_cast<long double>(k) * size) / count);
  return indices;
}

std::string sig3(double value) {
  if (value == 0.0 || !std::isfinite(value)) return fmt::format("{}", value);
  const int decimals = std::clamp(2 - static_cast<int>(std::floor(std::log10(std::abs(value)))), 0, 9);
  return fmt::format("{:.{}f}", value, decimals);
}

double Timing::median_seconds() const {
  if (seconds.empty()) return 0.0;
  std::vector<double> sorted = seconds;
  std::sort(sorted.begin(), sorted.end());
  const std::size_t n = sorted.size();
  return n % 2 == 1 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
}
double Timing::min_seconds() const { return seconds.empty() ? 0.0 : *std::min_element(seconds.begin(), seconds.end()); }
double Timing::max_seconds() const { return seconds.empty() ? 0.0 : *std::max_element(seconds.begin(), seconds.end()); }
double Timing::median_mrays_per_second() const {
  const double median = median_seconds();
  return median > 0.0 ? double(rays) / median * 1e-6 : 0.0;
}

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

template <class Cast>
Timing time_casts(std::size_t count, int runs, const Cast& cast) {
  Timing timing;
  timing.rays = count;
  for (int run = 0; run < runs; ++run) {
    const Clock::time_point start = Clock::now();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count), [&](const tbb::blocked_range<std::size_t>& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i) cast(i);
    });
    timing.seconds.push_back(seconds_since(start));
  }
  return timing;
}

}  // namespace

Timing time_intersect(const Accel& accel, std::span<const Ray> rays, int runs, std::vector<Hit>& hits) {
  hits.assign(rays.size(), Hit{});
  return time_casts(rays.size(), runs, [&](std::size_t i) { hits[i] = accel.intersect(rays[i]); });
}

Timing time_occluded(const Accel& accel, std::span<const Ray> rays, int runs, std::vector<std::uint8_t>& occluded) {
  occluded.assign(rays.size(), 0);
  return time_casts(rays.size(), runs, [&](std::size_t i) { occluded[i] = accel.occluded(rays[i]) ? 1 : 0; });
}

Agreement compare_hits(std::span<const Hit> a, std::span<const Hit> b) {
  if (a.size() != b.size()) throw RuntimeError("compare_hits: answer sets of different sizes");
  Agreement agreement;
  agreement.rays = a.size();
  for (std::size_t i = 0; i < a.size(); ++i) {
    const bool both_found = a[i].found() && b[i].found();
    const double ta = a[i].t, tb = b[i].t;
    const bool same_t = both_found && std::abs(ta - tb) <= kTRelativeTolerance * std::max(std::abs(ta), std::abs(tb));
    if (a[i].primitive != b[i].primitive) {
      if (same_t) ++agreement.ties;
      continue;
    }
    ++agreement.same_hit;
    if (both_found && !same_t) ++agreement.t_mismatches;
  }
  return agreement;
}

Agreement compare_occlusion(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b) {
  if (a.size() != b.size()) throw RuntimeError("compare_occlusion: answer sets of different sizes");
  Agreement agreement;
  agreement.rays = a.size();
  for (std::size_t i = 0; i < a.size(); ++i)
    if ((a[i] != 0) == (b[i] != 0)) ++agreement.same_hit;
  return agreement;
}

ReferencePlan plan_reference(double seconds_per_ray, std::size_t rays, int runs, double budget_seconds) {
  ReferencePlan plan;
  plan.estimated_seconds = seconds_per_ray * double(rays) * double(std::max(runs, 1));
  if (plan.estimated_seconds <= budget_seconds) {
    plan.rays = rays;
    return plan;
  }
  const double affordable = std::floor(budget_seconds / (seconds_per_ray * double(std::max(runs, 1))));
  if (affordable < double(std::min(kMinReferenceRays, rays))) {
    plan.skipped = true;
    return plan;
  }
  plan.rays = std::min(rays, static_cast<std::size_t>(affordable));
  plan.reduced = plan.rays < rays;
  return plan;
}

std::vector<ScalingSize> scaling_sizes(double max_triangles) {
  if (!std::isfinite(max_triangles) || max_triangles < 100.0)
    throw InputError(fmt::format("--max-triangles {} is below 100", max_triangles));
  if (max_triangles > 1e9) throw InputError(fmt::format("--max-triangles {} is above 1e9", max_triangles));
  std::vector<double> targets;
  for (double target = 100.0; target <= max_triangles * (1.0 + 1e-9); target *= 10.0) targets.push_back(target);
  if (std::abs(targets.back() - max_triangles) >= 0.5) targets.push_back(std::floor(max_triangles));
  std::vector<ScalingSize> sizes;
  for (double target : targets) {
    ScalingSize size;
    size.target = static_cast<std::size_t>(target);
    // 2 slices (stacks - 1) triangles with stacks ~ slices / 2: slices ~ sqrt(target).
    size.slices = std::max(3, static_cast<int>(std::lround(std::sqrt(target))));
    size.stacks = std::max(2, static_cast<int>(std::lround(target / (2.0 * size.slices))) + 1);
    size.triangles = 2 * std::size_t(size.slices) * std::size_t(size.stacks - 1);
    sizes.push_back(size);
  }
  return sizes;
}

Scene make_scaling_scene(const ScalingSize& size) {
  Scene scene;
  scene.source = fmt::format("<sphere mesh {}x{}>", size.slices, size.stacks);
  Material grey;
  grey.name = "grey";
  grey.diffuse = Color(0.8f);
  scene.materials.push_back(grey);
  Node root;
  root.name = "sphere";
  root.models.push_back({std::make_shared<const TriangleMesh>(make_sphere_mesh(1.0, size.slices, size.stacks)), 0});
  scene.nodes.push_back(std::move(root));
  Light light;
  light.position = Vec4d(2.0, 2.0, 3.0, 1.0);
  scene.lights.push_back(light);
  scene.camera.eye = Vec3d(0.0, 0.0, 3.0);
  scene.camera.target = Vec3d(0.0);
  return scene;
}

// ------------------------------------------------------------------------------------------------
// The command.

namespace {

constexpr std::uint64_t kIncoherentSeed = 0x5eed'1234'abcdULL;
constexpr std::size_t kProbeRays = 16;

struct Options {
  std::vector<std::string> scenes;
  std::size_t rays = 10000;
  int runs = 5;
  int width = 64, height = 48;
  double budget = 20.0;
  std::string csv;
  bool scaling = false;
  double max_triangles = 1e7;
};

// One CSV row: a measurement of one scene. Empty strings for fields that do not apply.
struct Row {
  std::string scene, measurement, accel, options, rays, median, min, max, unit, note;
};

std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string mib(std::size_t bytes) { return sig3(double(bytes) / (1024.0 * 1024.0)); }

std::string on_off(bool value) { return value ? "on" : "off"; }

// The reference's throughput on a ray set, within the budget: the rays it cast (indices into the
// set), its timing and answers, or why it was skipped.
struct ReferenceRun {
  ReferencePlan plan;
  std::vector<std::size_t> indices;
  Timing timing;
};

double probe_seconds_per_ray(const std::function<void(std::span<const Ray>)>& cast_once, std::span<const Ray> rays) {
  // A probe of kProbeRays; when that is too quick to time well, one of 16 times as many.
  for (std::size_t probe : {kProbeRays, kProbeRays * 16}) {
    std::vector<Ray> sample;
    for (std::size_t i : spread_indices(rays.size(), probe)) sample.push_back(rays[i]);
    const Clock::time_point start = Clock::now();
    cast_once(sample);
    const double seconds = seconds_since(start);
    if (seconds > 0.05 || sample.size() == rays.size() || probe > kProbeRays) return seconds / double(sample.size());
  }
  return 0.0;
}

// Runs `cast` (one timed run each) up to `runs` times, stopping once the runs so far took more than
// `budget` seconds: the probe's estimate can be off when other processes share the cores.
Timing runs_within_budget(int runs, double budget, const std::function<Timing()>& cast) {
  Timing total;
  double spent = 0.0;
  for (int run = 0; run < runs && (run == 0 || spent <= budget); ++run) {
    const Timing one = cast();
    total.rays = one.rays;
    total.seconds.insert(total.seconds.end(), one.seconds.begin(), one.seconds.end());
    spent += one.seconds.empty() ? 0.0 : one.seconds.front();
  }
  return total;
}

std::vector<Ray> pick(std::span<const Ray> rays, const std::vector<std::size_t>& indices) {
  std::vector<Ray> picked;
  picked.reserve(indices.size());
  for (std::size_t i : indices) picked.push_back(rays[i]);
  return picked;
}

std::string plan_note(const ReferencePlan& plan, std::size_t total, double budget) {
  if (plan.skipped) return fmt::format("skipped: estimated {} s > budget {} s", sig3(plan.estimated_seconds), budget);
  if (plan.reduced)
    return fmt::format("reduced to {} of {} rays: estimated {} s for all > budget {} s", plan.rays, total,
                       sig3(plan.estimated_seconds), budget);
  return "";
}

std::string join_notes(const std::string& a, const std::string& b) {
  return a.empty() ? b : b.empty() ? a : a + "; " + b;
}

class Runner {
 public:
  explicit Runner(const Options& options) : o_(options), threads_(tbb::this_task_arena::max_concurrency()) {}

  int run() {
    validate();
    fmt::print("# rt-perf intersect\n\nRays are cast with a TBB parallel_for over the rays on {} threads; times "
               "are wall clock of the casts only, median of {} runs (min-max in brackets). Embree: native kernel, "
               "robust on, quality medium unless stated. Reference: brute force, double precision, watertight test; "
               "budget {} s per ray set.\n\n",
               threads_, o_.runs, o_.budget);
    for (const std::string& path : o_.scenes) measure_scene(path);
    if (o_.scaling) measure_scaling();
    if (!o_.csv.empty()) write_csv();
    return 0;
  }

 private:
  void validate() const {
    if (o_.scenes.empty() && !o_.scaling) throw InputError("give at least one SCENE, or --scaling");
    if (o_.rays < 1) throw InputError("--rays must be at least 1");
    if (o_.runs < 1) throw InputError("--runs must be at least 1");
    if (o_.width < 1 || o_.height < 1 || o_.width > kMaxImageSide || o_.height > kMaxImageSide)
      throw InputError(fmt::format("--width and --height must be in [1, {}]", kMaxImageSide));
    if (!(o_.budget >= 0.0) || !std::isfinite(o_.budget))
      throw InputError("--reference-budget must be a finite number of seconds >= 0");
    if (o_.scaling) scaling_sizes(o_.max_triangles);
    for (const std::string& path : o_.scenes)
      if (!std::filesystem::is_regular_file(path)) throw InputError(fmt::format("{}: no such scene file", path));
  }

  void add(Row row) { rows_.push_back(std::move(row)); }

  void measure_scene(const std::string& path) {
    const Scene scene = load_scene(path);
    const FlatScene flat = flatten_scene(scene);
    fmt::print("## {}\n\n{} triangles, {} spheres, {} lights", path, flat.triangle_count(), flat.spheres.size(),
               scene.lights.size());
    if (flat.degenerate_triangles_dropped > 0)
      fmt::print(" ({} zero-area triangles dropped)", flat.degenerate_triangles_dropped);
    fmt::print("\n\n");
    add({path, "triangles", "", "", "", fmt::format("{}", flat.triangle_count()), "", "", "count", ""});
    add({path, "spheres", "", "", "", fmt::format("{}", flat.spheres.size()), "", "", "count", ""});

    fmt::print("### Embree build\n\n| quality | robust | build ms | memory MiB |\n|---|---|---:|---:|\n");
    for (EmbreeQuality quality : {EmbreeQuality::low, EmbreeQuality::medium, EmbreeQuality::high})
      for (bool robust : {true, false}) {
        AccelOptions options;
        options.embree_quality = quality;
        options.embree_robust = robust;
        const auto [timing, memory] = time_build(flat, options);
        const std::string label = fmt::format("quality={} robust={}", to_string(quality), on_off(robust));
        fmt::print("| {} | {} | {} ({}-{}) | {} |\n", to_string(quality), on_off(robust),
                   sig3(timing.median_seconds() * 1e3), sig3(timing.min_seconds() * 1e3),
                   sig3(timing.max_seconds() * 1e3), mib(memory));
        add({path, "build_time", "embree", label, "", fmt::format("{}", timing.median_seconds() * 1e3),
             fmt::format("{}", timing.min_seconds() * 1e3), fmt::format("{}", timing.max_seconds() * 1e3), "ms", ""});
        add({path, "build_memory", "embree", label, "", fmt::format("{}", memory), "", "", "bytes", ""});
      }

    const EmbreeAccel embree(flat, AccelOptions{});
    const std::unique_ptr<Accel> reference = build_accel(AccelKind::reference, flat);
    const std::vector<Ray> camera = make_camera_rays(scene, o_.width, o_.height);
    const std::vector<Ray> shadow = make_shadow_rays(scene, flat, embree, camera);
    const std::vector<Ray> incoherent = make_incoherent_rays(flat_bounds(flat), o_.rays, kIncoherentSeed);

    fmt::print("\n### Throughput and agreement\n\n"
               "| rays | count | Embree Mrays/s | reference rays | reference Mrays/s | Embree / reference | "
               "same hit | other primitive, same t (tie) | t off > 1e-4 rel |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    std::vector<std::string> notes;
    throughput_row(path, fmt::format("camera {}x{}", o_.width, o_.height), "camera", embree, *reference, camera, true,
                   notes);
    throughput_row(path, "shadow", "shadow", embree, *reference, shadow, false, notes);
    throughput_row(path, "incoherent", "incoherent", embree, *reference, incoherent, true, notes);
    fmt::print("\n");
    for (const std::string& note : notes) fmt::print("- {}\n", note);
    if (!notes.empty()) fmt::print("\n");
  }

  struct BuildResult {
    Timing timing;
    std::size_t memory = 0;
  };

  BuildResult time_build(const FlatScene& flat, const AccelOptions& options) const {
    BuildResult result;
    for (int run = 0; run < o_.runs; ++run) {
      const Clock::time_point start = Clock::now();
      const EmbreeAccel accel(flat, options);
      result.timing.seconds.push_back(seconds_since(start));
      result.memory = accel.memory_bytes();
    }
    return result;
  }

  // Times the reference on `rays` within the budget; `cast` runs it on a ray set `runs` times.
  ReferenceRun run_reference(std::span<const Ray> rays,
                             const std::function<Timing(std::span<const Ray>, int)>& cast) const {
    ReferenceRun run;
    if (rays.empty()) return run;
    const double per_ray = probe_seconds_per_ray([&](std::span<const Ray> sample) { cast(sample, 1); }, rays);
    run.plan = plan_reference(per_ray, rays.size(), o_.runs, o_.budget);
    if (run.plan.skipped) return run;
    run.indices = spread_indices(rays.size(), run.plan.rays);
    return run;
  }

  void throughput_row(const std::string& path, const std::string& label, const std::string& kind,
                      const EmbreeAccel& embree, const Accel& reference, std::span<const Ray> rays, bool closest,
                      std::vector<std::string>& notes) {
    Timing embree_timing, reference_timing;
    std::optional<Agreement> agreement;
    std::vector<Hit> embree_hits, reference_hits;
    std::vector<std::uint8_t> embree_occluded, reference_occluded;
    ReferenceRun ref;
    if (!rays.empty()) {
      if (closest) {
        embree_timing = time_intersect(embree, rays, o_.runs, embree_hits);
        ref = run_reference(rays, [&](std::span<const Ray> set, int runs) {
          return time_intersect(reference, set, runs, reference_hits);
        });
      } else {
        embree_timing = time_occluded(embree, rays, o_.runs, embree_occluded);
        ref = run_reference(rays, [&](std::span<const Ray> set, int runs) {
          return time_occluded(reference, set, runs, reference_occluded);
        });
      }
      if (!ref.plan.skipped) {
        const std::vector<Ray> subset = pick(rays, ref.indices);
        if (closest) {
          reference_timing = runs_within_budget(o_.runs, o_.budget,
                                                [&] { return time_intersect(reference, subset, 1, reference_hits); });
          std::vector<Hit> embree_subset;
          for (std::size_t i : ref.indices) embree_subset.push_back(embree_hits[i]);
          agreement = compare_hits(embree_subset, reference_hits);
        } else {
          reference_timing = runs_within_budget(o_.runs, o_.budget,
                                                [&] { return time_occluded(reference, subset, 1, reference_occluded); });
          std::vector<std::uint8_t> embree_subset;
          for (std::size_t i : ref.indices) embree_subset.push_back(embree_occluded[i]);
          agreement = compare_occlusion(embree_subset, reference_occluded);
        }
      }
    }
    const std::string note =
        join_notes(plan_note(ref.plan, rays.size(), o_.budget), runs_note(reference_timing, ref.plan.skipped || rays.empty()));
    if (!note.empty()) notes.push_back(fmt::format("{} rays, reference: {}", label, note));
    const bool has_reference = !rays.empty() && !ref.plan.skipped;
    const double speedup =
        has_reference && reference_timing.median_mrays_per_second() > 0.0
            ? embree_timing.median_mrays_per_second() / reference_timing.median_mrays_per_second()
            : 0.0;
    fmt::print("| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", label, rays.size(),
               rays.empty() ? "-" : mrays_cell(embree_timing),
               rays.empty() ? "-" : ref.plan.skipped ? "skipped" : fmt::format("{}", ref.indices.size()),
               has_reference ? mrays_cell(reference_timing) : "-", has_reference ? sig3(speedup) + "x" : "-",
               agreement ? fmt::format("{}/{}", agreement->same_hit, agreement->rays) : "-",
               agreement && closest ? fmt::format("{}", agreement->ties) : "-",
               agreement && closest ? fmt::format("{}", agreement->t_mismatches) : "-");

    const std::string options = fmt::format("threads={}", threads_);
    const std::string measurement = "throughput_" + kind;
    if (!rays.empty())
      add(mrays_row(path, measurement, "embree", options + " quality=medium robust=on kernel=native", embree_timing,
                    ""));
    if (has_reference) add(mrays_row(path, measurement, "reference", options, reference_timing, note));
    else if (!rays.empty()) add({path, measurement, "reference", options, "0", "", "", "", "Mrays/s", note});
    if (agreement) {
      add({path, "agreement_" + kind + (closest ? "_same_primitive" : "_same_occluded"), "embree-vs-reference", "",
           fmt::format("{}", agreement->rays), fmt::format("{}", agreement->same_hit), "", "", "rays", note});
      if (closest) {
        add({path, "agreement_" + kind + "_t_off_1e-4_relative", "embree-vs-reference", "",
             fmt::format("{}", agreement->rays), fmt::format("{}", agreement->t_mismatches), "", "", "rays", note});
        add({path, "agreement_" + kind + "_tie_other_primitive", "embree-vs-reference", "",
             fmt::format("{}", agreement->rays), fmt::format("{}", agreement->ties), "", "", "rays", note});
      }
    }
  }

  // Says so when the budget ran out before all runs (the median is then of fewer runs).
  std::string runs_note(const Timing& timing, bool skipped) const {
    if (skipped || timing.seconds.size() >= std::size_t(o_.runs)) return "";
    return fmt::format("only {} of {} runs fit the budget (the probe underestimated; cores shared?)",
                       timing.seconds.size(), o_.runs);
  }

  static std::string mrays_cell(const Timing& timing) {
    const double rays = double(timing.rays) * 1e-6;
    return fmt::format("{} ({}-{})", sig3(timing.median_mrays_per_second()), sig3(rays / timing.max_seconds()),
                       sig3(rays / timing.min_seconds()));
  }

  static Row mrays_row(const std::string& path, const std::string& measurement, const std::string& accel,
                       const std::string& options, const Timing& timing, const std::string& note) {
    const double rays = double(timing.rays) * 1e-6;
    return {path,
            measurement,
            accel,
            options,
            fmt::format("{}", timing.rays),
            fmt::format("{}", timing.median_mrays_per_second()),
            fmt::format("{}", rays / timing.max_seconds()),
            fmt::format("{}", rays / timing.min_seconds()),
            "Mrays/s",
            note};
  }

  void measure_scaling() {
    fmt::print("## Scaling: UV sphere meshes, {} incoherent rays\n\n"
               "| target | triangles | Embree build ms | Embree memory MiB | Embree Mrays/s | reference rays | "
               "reference Mrays/s | Embree / reference |\n|---:|---:|---:|---:|---:|---:|---:|---:|\n",
               o_.rays);
    std::vector<std::string> notes;
    for (const ScalingSize& size : scaling_sizes(o_.max_triangles)) {
      const Scene scene = make_scaling_scene(size);
      const FlatScene flat = flatten_scene(scene);
      const std::string name = fmt::format("scaling:sphere-{}", size.target);
      const auto [build, memory] = time_build(flat, AccelOptions{});
      const EmbreeAccel embree(flat, AccelOptions{});
      const std::unique_ptr<Accel> reference = build_accel(AccelKind::reference, flat);
      const std::vector<Ray> rays = make_incoherent_rays(flat_bounds(flat), o_.rays, kIncoherentSeed);
      std::vector<Hit> embree_hits, reference_hits;
      const Timing embree_timing = time_intersect(embree, rays, o_.runs, embree_hits);
      const ReferenceRun ref = run_reference(rays, [&](std::span<const Ray> set, int runs) {
        return time_intersect(*reference, set, runs, reference_hits);
      });
      Timing reference_timing;
      if (!ref.plan.skipped) {
        const std::vector<Ray> subset = pick(rays, ref.indices);
        reference_timing = runs_within_budget(o_.runs, o_.budget,
                                              [&] { return time_intersect(*reference, subset, 1, reference_hits); });
      }
      const std::string note =
          join_notes(plan_note(ref.plan, rays.size(), o_.budget), runs_note(reference_timing, ref.plan.skipped));
      if (!note.empty()) notes.push_back(fmt::format("{} triangles: reference {}", flat.triangle_count(), note));
      const bool has_reference = !ref.plan.skipped;
      const double speedup = has_reference && reference_timing.median_mrays_per_second() > 0.0
                                 ? embree_timing.median_mrays_per_second() / reference_timing.median_mrays_per_second()
                                 : 0.0;
      fmt::print("| {} | {} | {} ({}-{}) | {} | {} | {} | {} | {} |\n", size.target, flat.triangle_count(),
                 sig3(build.median_seconds() * 1e3), sig3(build.min_seconds() * 1e3), sig3(build.max_seconds() * 1e3),
                 mib(memory), mrays_cell(embree_timing),
                 has_reference ? fmt::format("{}", ref.indices.size())
                               : fmt::format("skipped (estimated {} s > budget)", sig3(ref.plan.estimated_seconds)),
                 has_reference ? mrays_cell(reference_timing) : "-", has_reference ? sig3(speedup) + "x" : "-");
      const std::string defaults = "quality=medium robust=on kernel=native";
      add({name, "triangles", "", "", "", fmt::format("{}", flat.triangle_count()), "", "", "count", ""});
      add({name, "build_time", "embree", defaults, "", fmt::format("{}", build.median_seconds() * 1e3),
           fmt::format("{}", build.min_seconds() * 1e3), fmt::format("{}", build.max_seconds() * 1e3), "ms", ""});
      add({name, "build_memory", "embree", defaults, "", fmt::format("{}", memory), "", "", "bytes", ""});
      const std::string threads = fmt::format("threads={}", threads_);
      add(mrays_row(name, "throughput_incoherent", "embree", threads + " " + defaults, embree_timing, ""));
      if (has_reference) add(mrays_row(name, "throughput_incoherent", "reference", threads, reference_timing, note));
      else add({name, "throughput_incoherent", "reference", threads, "0", "", "", "", "Mrays/s", note});
    }
    fmt::print("\n");
    for (const std::string& note : notes) fmt::print("- {}\n", note);
    if (!notes.empty()) fmt::print("\n");
  }

  void write_csv() const {
    std::ofstream out(o_.csv, std::ios::binary);
    if (!out) throw RuntimeError(fmt::format("{}: cannot open for writing", o_.csv));
    out << "scene,measurement,accel,options,rays,median,min,max,unit,note\n";
    for (const Row& row : rows_)
      out << fmt::format("{},{},{},{},{},{},{},{},{},{}\n", csv_field(row.scene), csv_field(row.measurement),
                         csv_field(row.accel), csv_field(row.options), csv_field(row.rays), csv_field(row.median),
                         csv_field(row.min), csv_field(row.max), csv_field(row.unit), csv_field(row.note));
    out.close();
    if (!out) throw RuntimeError(fmt::format("{}: writing failed", o_.csv));
  }

  const Options& o_;
  int threads_;
  std::vector<Row> rows_;
};

}  // namespace

std::function<int()> add_intersect_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand("intersect", "Embree against the reference: build, memory, Mrays/s, agreement");
  auto options = std::make_shared<Options>();
  command->add_option("scenes", options->scenes, "Scene files (.json, .test, .gltf, .glb, .obj)");
  command->add_option("--rays", options->rays, "Incoherent rays per scene (default 10000)");
  command->add_option("--runs", options->runs, "Timed runs per measurement; the median is reported (default 5)");
  command->add_option("--width", options->width, "Camera ray grid width in pixels (default 64)");
  command->add_option("--height", options->height, "Camera ray grid height in pixels (default 48)");
  command->add_option("--reference-budget", options->budget,
                      "Seconds the reference may take per ray set, all runs (default 20); beyond, fewer rays or skipped");
  command->add_option("--csv", options->csv, "Also write the measurements as CSV to this file");
  command->add_flag("--scaling", options->scaling, "Measure UV sphere meshes of 1e2, 1e3, ... triangles");
  command->add_option("--max-triangles", options->max_triangles, "Largest scaling mesh, in triangles (default 1e7)");
  return [options] { return Runner(*options).run(); };
}

}  // namespace rt::perf
