#include "commands.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <new>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "rt/accel/accel.h"
#include "rt/accel/embree_accel.h"
#include "rt/app/progress.h"
#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/flatten/flatten.h"
#include "rt/io/atomic_file.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/io/merge.h"
#include "rt/render/surface_test.h"
#include "rt/render/fingerprint.h"
#include "rt/render/render.h"
#include "rt/view/viewer.h"
#include "ray_budget.h"

namespace rt {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// "1 sphere", "2 spheres", "0 spheres"; `plural` for irregular nouns.
std::string count_of(std::size_t n, const std::string& singular, const std::string& plural = "") {
  return fmt::format("{} {}", n, n == 1 ? singular : plural.empty() ? singular + "s" : plural);
}

// What the loaders noted (glTF: Scene::notices) and what was made up for the file (LoadReport).
void print_notices(const SceneOptions& options, const LoadReport& report, const Scene& scene) {
  for (const std::string& notice : scene.notices) fmt::print(stderr, "rt: notice: {}\n", notice);
  for (const std::string& notice : scene_notices(options, report, scene)) fmt::print(stderr, "rt: {}\n", notice);
}

// Output file when -o is absent: the scene's own "output", else "<scene stem>.png" in the working directory.
std::string default_output(const Scene& scene, const std::string& scene_path) {
  if (!scene.settings.output.empty()) return scene.settings.output;
  if (scene_path.empty()) return "default.png";
  return std::filesystem::path(scene_path).stem().string() + ".png";
}

void warn_about_dropped_triangles(const Scene& scene, const FlatScene& flat, bool quiet) {
  if (flat.degenerate_triangles_dropped > 0 && !quiet)
    fmt::print(stderr, "rt: warning: {}: dropped {} degenerate triangle(s) (zero area){}\n", scene.source,
               flat.degenerate_triangles_dropped,
               flat.degenerate_emitter_triangles_dropped == 0
                   ? ""
                   : fmt::format(", {} of them emissive (they emit no light)", flat.degenerate_emitter_triangles_dropped));
}

// SIGINT and SIGTERM during the render loop: the handler only records the signal; the loop polls
// the flag between rows of pixels and stops (render_image, RenderOptions::cancel).
std::atomic<bool> interrupted{false};
volatile std::sig_atomic_t interrupting_signal = 0;

extern "C" void on_interrupt(int signal) {
  interrupting_signal = signal;
  interrupted.store(true, std::memory_order_relaxed);
}

// Installs on_interrupt for SIGINT and SIGTERM for its lifetime, then restores what was there.
class ScopedInterruptHandler {
 public:
  ScopedInterruptHandler() {
    interrupted.store(false);
    interrupting_signal = 0;
    struct sigaction action {};
    action.sa_handler = &on_interrupt;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previous_int_);
    sigaction(SIGTERM, &action, &previous_term_);
  }
  ~ScopedInterruptHandler() {
    sigaction(SIGINT, &previous_int_, nullptr);
    sigaction(SIGTERM, &previous_term_, nullptr);
  }
  ScopedInterruptHandler(const ScopedInterruptHandler&) = delete;
  ScopedInterruptHandler& operator=(const ScopedInterruptHandler&) = delete;

 private:
  struct sigaction previous_int_ {}, previous_term_ {};
};

// "out.png" -> "out.partial.png": where --partial-output puts the finished tiles of an interrupted render.
std::string partial_output_path(const std::string& output) {
  const std::filesystem::path path(output);
  return (path.parent_path() / (path.stem().string() + ".partial" + path.extension().string())).string();
}


// The options that can change a pixel, beyond what the scene fingerprint covers (image size,
// depth and camera are in the scene): region files carry them and rt merge compares them.
// Threads, pruning, statistics and output names cannot change a pixel and are left out.
std::string settings_text(const RenderArgs& args) {
  return fmt::format("spp={} accel={} embree-robust={} embree-quality={} embree-kernel={} sphere-tessellation={} "
                     "ray-offset={} min-throughput={} min-light={} light-samples={} light-sampling={}",
                     args.spp, args.accel, args.embree_robust, args.embree_quality, args.embree_kernel,
                     args.sphere_tessellation, args.ray_offset, args.effects.min_throughput,
                     args.effects.min_light_contribution, args.effects.light_samples,
                     to_string(args.effects.light_sampling));
}

// "scene.png" -> "scene.tile-2-of-8.exr" / "scene.crop-0-0-64-48.exr": a region's default name.
std::string region_output(const std::string& output, const RegionRequest& region) {
  const fs::path path(output);
  const std::string part = region.n > 0 ? fmt::format("tile-{}-of-{}", region.k, region.n)
                                        : fmt::format("crop-{}-{}-{}-{}", region.crop->x0, region.crop->y0,
                                                      region.crop->x1, region.crop->y1);
  return (path.parent_path() / (path.stem().string() + "." + part + ".exr")).string();
}

// Where a scene's image goes. With --outdir: DIR/<scene stem>.png, known before loading (so that
// --skip-existing loads nothing); otherwise -o, else the scene's own "output", else
// <scene stem>.png, which needs the loaded scene. Regions get region_output's name unless -o
// names the file.
std::optional<std::string> output_before_loading(const RenderArgs& args, const std::string& scene_path) {
  if (!args.output.empty()) return args.output;
  if (args.outdir.empty()) return std::nullopt;
  const std::string stem = scene_path.empty() ? "default" : fs::path(scene_path).stem().string();
  const std::string name = (fs::path(args.outdir) / (stem + ".png")).string();
  return args.region.given() ? region_output(name, args.region) : name;
}

// The output when the scene's own name for it is `own` (its "output", else <scene stem>.png).
std::string output_named(const RenderArgs& args, const std::string& scene_path, const std::string& own) {
  if (auto known = output_before_loading(args, scene_path)) return *known;
  return args.region.given() ? region_output(own, args.region) : own;
}

std::string output_after_loading(const RenderArgs& args, const std::string& scene_path, const Scene& scene) {
  return output_named(args, scene_path, default_output(scene, scene_path));
}

// What every scene of a batch renders with, the Embree device included.
struct BatchContext {
  int threads = 1;
  AccelKind accel_kind = AccelKind::embree;
  AccelOptions accel_options;
  RayOffset ray_offset;
};

// The batch settings of `args`: threads (0: all cores), intersector and ray offsets.
BatchContext make_batch_context(const RenderArgs& args) {
  BatchContext batch;
  batch.threads = args.threads > 0 ? args.threads : tbb::info::default_concurrency();
  batch.accel_kind = parse_accel_kind(args.accel);
  batch.accel_options.embree_robust = args.embree_robust == "on";
  batch.accel_options.embree_quality = parse_embree_quality(args.embree_quality);
  batch.accel_options.embree_kernel = parse_embree_kernel(args.embree_kernel);
  batch.ray_offset = parse_ray_offset(args.ray_offset);
  return batch;
}

// The render settings of `args` that every render of a scene shares (rt render, rt view).
RenderOptions render_options(const RenderArgs& args, const BatchContext& batch) {
  RenderOptions options;
  options.threads = batch.threads;
  options.samples_per_pixel = args.spp;
  options.ray_offset = batch.ray_offset;
  options.effects = args.effects;
  options.texture_cache_bytes = args.texture_cache;
  return options;
}

// The scene at `scene_path` (empty: the default scene) with the command line's image settings and
// scene options applied, validated.
Scene load_for_render(const RenderArgs& args, const std::string& scene_path, LoadReport& report) {
  const ImageOverrides image{args.width, args.height, args.max_depth, args.display, args.exposure_ev, args.tonemap};
  return load_scene_for_command(scene_path, args.gltf, image, args.scene, report);
}

// --crop, --tile and --debug-pixel against the image size, which is known once the scene is loaded.
void check_pixel_flags(const RenderArgs& args, const Scene& scene) {
  const int width = scene.settings.width, height = scene.settings.height;
  if (const std::optional<PixelRegion>& crop = args.region.crop; crop && !crop->inside(width, height)) {
    std::vector<std::string> problems;
    if (crop->x1 > width) problems.push_back(fmt::format("X1 {} > width {}", crop->x1, width));
    if (crop->y1 > height) problems.push_back(fmt::format("Y1 {} > height {}", crop->y1, height));
    throw UsageError(fmt::format("{}: --crop {} reaches outside the {}x{} image ({})", scene.source, to_string(*crop),
                                 width, height, fmt::join(problems, ", ")));
  }
  if (args.region.n > height)
    throw UsageError(fmt::format("{}: --tile {}/{}: the {}-row image cannot be cut into {} tiles of whole rows (at most {})",
                                 scene.source, args.region.k, args.region.n, height, args.region.n, height));
  if (const std::vector<int>& pixel = args.debug_pixel; !pixel.empty() && (pixel[0] >= width || pixel[1] >= height))
    throw UsageError(fmt::format("{}: --debug-pixel {} {} is outside the {}x{} image (X < {}, Y < {})", scene.source,
                                 pixel[0], pixel[1], width, height, width, height));
}

// check_output_path for an image about to be written; when `flag` (-o, --screenshot) named the
// path, a format rt cannot write is a usage error naming the flag.
void check_output(const std::string& path, const std::string& flag) {
  if (flag.empty()) return check_output_path(path);
  try {
    check_image_format(path);
  } catch (const InputError& error) {
    throw UsageError(fmt::format("{} {}", flag, error.what()));
  }
  check_parent_directory_writable(path);
}

enum class Outcome { rendered, skipped, cancelled };

// Renders one scene (or its region) to its output; returns the exit status of an interrupted
// render through `interrupted_status`. Throws on any error.
Outcome render_scene(const RenderArgs& args, const std::string& scene_path, const BatchContext& batch,
                     int& interrupted_status) {
  const auto start = Clock::now();
  if (args.skip_existing)
    if (const auto known = output_before_loading(args, scene_path); known && fs::exists(*known)) {
      if (!args.quiet) fmt::print(stderr, "rt: {} exists, skipped (--skip-existing)\n", *known);
      return Outcome::skipped;
    }
  LoadReport report;
  Scene scene = load_for_render(args, scene_path, report);
  const std::string output = output_after_loading(args, scene_path, scene);
  if (args.skip_existing && fs::exists(output)) {
    if (!args.quiet) fmt::print(stderr, "rt: {} exists, skipped (--skip-existing)\n", output);
    return Outcome::skipped;
  }
  check_pixel_flags(args, scene);
  std::optional<PixelRegion> region = args.region.crop;
  if (args.region.n > 0) {
    region = tile_region(args.region.k, args.region.n, scene.settings.width, scene.settings.height);
    std::string extension = fs::path(output).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
    if (extension != ".exr")
      throw UsageError(fmt::format("--tile writes an OpenEXR region file for rt merge; '{}' is not .exr", output));
  }
  check_output(output, args.output.empty() ? "" : "-o");  // fail before rendering, not after
  if (!args.stats_path.empty()) check_parent_directory_writable(args.stats_path);
  check_render_memory(scene, region);
  const double load_s = seconds_since(start);

  auto phase_start = Clock::now();
  FlattenOptions flatten_options;
  flatten_options.sphere_tessellation = args.sphere_tessellation;
  const FlatScene flat = flatten_scene(scene, flatten_options);
  release_object_meshes(scene);
  const double flatten_s = seconds_since(phase_start);
  // Notes and warnings only once the scene has loaded and flattened: a failing run prints one line.
  if (!args.quiet) {
    print_notices(args.scene, report, scene);
    if (const std::string note = lossy_format_note(output); !note.empty())
      fmt::print(stderr, "rt: note: {}: {}\n", output, note);
  }
  warn_about_dropped_triangles(scene, flat, args.quiet);

  phase_start = Clock::now();
  const SceneSurfaceTest surface_test(scene, flat);
  const std::unique_ptr<Accel> accel = build_accel(batch.accel_kind, flat, with_surface_test(batch.accel_options, surface_test));
  const double build_s = seconds_since(phase_start);

  RenderOptions options = render_options(args, batch);
  options.region = region;
  if (!args.debug_pixel.empty()) {
    for (const std::string& line : trace_pixel(scene, flat, *accel, options, args.debug_pixel[0], args.debug_pixel[1]))
      fmt::print("{}\n", line);
    return Outcome::rendered;
  }
  options.time_queries = args.explain || !args.stats_path.empty();
  ProgressBar progress(args.scene_paths.size() > 1 ? fmt::format("rendering {}", scene.source) : "rendering", !args.quiet);
  options.on_progress = [&](double fraction) { progress.update(fraction); };
  const ScopedInterruptHandler interrupt_handler;  // while rendering; before, a signal ends the process
  options.cancel = &interrupted;
  const double render_start_s = seconds_since(start);
  const RenderResult result = render_image(scene, flat, *accel, options);
  progress.finish();
  ImageHeader header;
  if (region) {
    header.data_window = region;
    header.full_width = scene.settings.width;
    header.full_height = scene.settings.height;
    header.attributes = {{kSceneAttribute, scene_fingerprint(scene, flat)},
                         {kSettingsAttribute, settings_text(args)},
                         {kVersionAttribute, RT_VERSION},
                         {kPartAttribute, args.region.n > 0 ? fmt::format("tile {}/{}", args.region.k, args.region.n)
                                                            : "crop " + to_string(*region)}};
  }
  if (result.cancelled()) {
    const int signal = interrupting_signal;
    const std::string what = fmt::format("rt: interrupted by {} after {} of {} tiles", signal == SIGTERM ? "SIGTERM" : "SIGINT",
                                         result.tiles_finished(), result.tile_count());
    if (args.partial_output) {
      const std::string partial = partial_output_path(output);
      write_image(result.image, partial, header, scene.settings.display);
      fmt::print(stderr, "{}; the finished tiles are in {} (unfinished tiles black); {} not written\n", what, partial,
                 output);
    } else {
      fmt::print(stderr, "{}; nothing written (--partial-output keeps the finished tiles)\n", what);
    }
    interrupted_status = 128 + (signal == SIGTERM ? SIGTERM : SIGINT);
    return Outcome::cancelled;
  }
  if (result.non_finite_samples > 0 && !args.quiet)
    fmt::print(stderr, "rt: warning: {} sample(s) were NaN or infinite and were replaced by black; the first in pixel "
               "({}, {}): see its ray tree with --debug-pixel {} {}\n", result.non_finite_samples,
               result.first_non_finite_pixel->first, result.first_non_finite_pixel->second,
               result.first_non_finite_pixel->first, result.first_non_finite_pixel->second);

  if (result.textures.tiled && !args.quiet)
    fmt::print(stderr, "rt: note: the PNG and JPEG textures take {} decoded, more than the {} texture cache "
               "(--texture-cache): they were sampled through OpenImageIO's tiled cache, bounded by it but slower\n",
               format_bytes(result.textures.decoded_bytes), format_bytes(result.textures.budget_bytes));

  phase_start = Clock::now();
  write_image(result.image, output, header, scene.settings.display);
  const double write_s = seconds_since(phase_start);
  const double total_s = seconds_since(start);
  const double mrays = result.rays.total() / std::max(result.seconds, 1e-9) / 1e6;

  if (!args.stats_path.empty()) {
    nlohmann::ordered_json stats;
    stats["scene"] = scene_path.empty() ? "<built-in default>" : scene_path;
    stats["output"] = output;
    stats["accel"] = to_string(batch.accel_kind);
    if (batch.accel_kind == AccelKind::embree)
      stats["embree"] = {{"robust", batch.accel_options.embree_robust},
                         {"quality", to_string(batch.accel_options.embree_quality)},
                         {"kernel", to_string(batch.accel_options.embree_kernel)}};
    stats["ray_offset"] = to_string(batch.ray_offset);
    stats["threads"] = batch.threads;
    stats["image"] = {{"width", scene.settings.width}, {"height", scene.settings.height}};
    if (region) stats["region"] = {region->x0, region->y0, region->x1, region->y1};
    stats["max_depth"] = scene.settings.max_depth;
    stats["samples_per_pixel"] = args.spp;
    stats["triangles"] = flat.triangle_count();
    stats["spheres"] = flat.spheres.size();
    stats["sphere_tessellation"] = args.sphere_tessellation;
    stats["degenerate_triangles_dropped"] = flat.degenerate_triangles_dropped;
    stats["non_finite_samples"] = result.non_finite_samples;
    stats["lights"] = scene.lights.size();
    stats["emitters"] = result.plan.emitters.size();
    stats["rays"] = {{"camera", result.rays.camera},
                     {"shadow", result.rays.shadow},
                     {"reflection", result.rays.reflection},
                     {"refraction", result.rays.refraction},
                     {"see_through", result.rays.see_through},
                     {"alpha_tests", surface_test.alpha().calls()},
                     {"area_light", result.rays.area_light},
                     {"total", result.rays.total()}};
    stats["effects"] = effects_json(result.plan, scene);
    stats["textures"] = {{"decoded", result.textures.decoded},
                         {"decoded_bytes", result.textures.decoded_bytes},
                         {"through_openimageio", result.textures.through_oiio},
                         {"cache_bytes", result.textures.budget_bytes},
                         {"tiled", result.textures.tiled}};
    stats["ray_budget"] = ray_budget_json(result, scene);
    stats["mrays_per_s"] = mrays;
    stats["time_s"] = {{"load", load_s},     {"flatten", flatten_s}, {"build", build_s},
                       {"render", result.seconds}, {"write", write_s},   {"total", total_s},
                       {"first_pixel", render_start_s + result.first_tile_seconds}};
    write_text_file_atomically(args.stats_path, stats.dump(2) + "\n");
  }
  if (args.explain) {
    fmt::print("{}", explain_render(result, scene));
    if (surface_test.alpha().any())
      fmt::print("  alpha tests          {:>8} (filter calls on the alpha-tested triangles)\n", surface_test.alpha().calls());
  }
  if (!args.quiet)
    fmt::print(
        "{}: {}x{}{}, {}, {}, {}{}, {:.3f} s render, {:.3f} s total, {:.2f} Mrays/s ({}, {})\n", output,
        scene.settings.width, scene.settings.height, region ? fmt::format(" pixels {}", to_string(*region)) : "",
        count_of(flat.triangle_count(), "triangle"), count_of(flat.spheres.size(), "sphere"),
        count_of(scene.lights.size(), "light"),
        result.plan.emitters.empty() ? "" : ", " + count_of(result.plan.emitters.size(), "emitter"), result.seconds, total_s, mrays,
        to_string(batch.accel_kind), count_of(std::size_t(batch.threads), "thread"));
  return Outcome::rendered;
}

// Where a batch scene's image will go, known before loading it: output_before_loading, else the
// file's declared "output" (read without loading the scene), else <scene stem>.png.
std::string planned_output(const RenderArgs& args, const std::string& scene_path) {
  return output_named(args, scene_path, declared_output(scene_path).value_or(fs::path(scene_path).stem().string() + ".png"));
}

// Batch mistakes found before any rendering: -o, --stats or --debug-pixel with several scenes,
// and two scenes that would write the same file (Duck.gltf and Duck.glb both make Duck.png).
void check_batch(const RenderArgs& args) {
  if (args.scene_paths.size() < 2) return;
  if (!args.output.empty()) throw UsageError("-o names one output file; with several scenes use --outdir DIR");
  if (!args.stats_path.empty() || !args.debug_pixel.empty())
    throw UsageError("--stats and --debug-pixel take one scene");
  std::map<fs::path, std::string> scene_of;  // absolute, normalised output path -> the scene writing it
  for (const std::string& path : args.scene_paths) {
    const std::string output = planned_output(args, path);
    if (const auto [it, inserted] = scene_of.emplace(fs::absolute(output).lexically_normal(), path); !inserted)
      throw UsageError(fmt::format("'{}' and '{}' would both write {}: render them in separate runs, each with -o",
                                   it->second, path, output));
  }
}

}  // namespace

int run_render(const RenderArgs& args) {
  check_batch(args);
  set_memory_limit(args.memory_limit);
  BatchContext batch = make_batch_context(args);
  // Limits Embree's BVH build (TBB tasks) as well as the render loop.
  tbb::global_control thread_limit(tbb::global_control::max_allowed_parallelism, batch.threads);
  if (!args.outdir.empty()) {
    std::error_code error;
    fs::create_directories(args.outdir, error);
    if (!fs::is_directory(args.outdir))
      throw InputError(args.outdir, "", fmt::format("cannot create the output directory{}",
                                                    error ? " (" + error.message() + ")" : ""));
  }
  const std::vector<std::string> scenes = args.scene_paths.empty() ? std::vector<std::string>{""} : args.scene_paths;
  int interrupted_status = 0;
  if (scenes.size() == 1) {  // errors propagate: the CLI prints them with their exit status
    render_scene(args, scenes[0], batch, interrupted_status);
    return interrupted_status;
  }

  // A batch: one Embree device for all scenes; a failing scene does not stop the others.
  if (batch.accel_kind == AccelKind::embree) batch.accel_options.embree_device = std::make_shared<EmbreeDevice>();
  const auto start = Clock::now();
  int rendered = 0, skipped = 0;
  std::vector<std::string> failed;
  for (const std::string& scene_path : scenes) {
    try {
      const Outcome outcome = render_scene(args, scene_path, batch, interrupted_status);
      if (outcome == Outcome::cancelled) {
        fmt::print(stderr, "rt: batch interrupted: {} rendered, {} skipped, {} failed, {} not started\n", rendered,
                   skipped, failed.size(), scenes.size() - std::size_t(rendered + skipped) - failed.size() - 1);
        return interrupted_status;
      }
      ++(outcome == Outcome::skipped ? skipped : rendered);
    } catch (const std::bad_alloc&) {
      fmt::print(stderr, "rt: error: {}: out of memory\n", printable_line(scene_path));
      failed.push_back(scene_path);
    } catch (const std::exception& error) {
      fmt::print(stderr, "rt: error: {}\n", printable_line(error.what()));
      failed.push_back(scene_path);
    }
  }
  if (!args.quiet || !failed.empty())
    fmt::print(stderr, "rt: batch of {} scenes in {:.1f} s: {} rendered, {} skipped, {} failed{}{}\n", scenes.size(),
               seconds_since(start), rendered, skipped, failed.size(), failed.empty() ? "" : ": ",
               printable_line(fmt::format("{}", fmt::join(failed, ", "))));
  return failed.empty() ? 0 : 1;
}

int run_view(const ViewArgs& args) {
  check_display();  // before loading anything: without a window system, one line and exit 1
  set_memory_limit(args.render.memory_limit);
  const BatchContext batch = make_batch_context(args.render);
  tbb::global_control thread_limit(tbb::global_control::max_allowed_parallelism, batch.threads);
  LoadReport report;
  Scene scene = load_for_render(args.render, args.scene_path, report);
  ViewOptions options;
  options.save_path = args.render.output.empty() ? default_output(scene, args.scene_path) : args.render.output;
  check_output(options.save_path, args.render.output.empty() ? "" : "-o");
  if (!args.screenshot.empty()) {
    check_output(args.screenshot, "--screenshot");
    if (writes_float(args.screenshot))
      throw InputError(args.screenshot, "", "a screenshot holds the window's 8-bit pixels; use .png, .ppm or .tif");
  }
  check_render_memory(scene);
  const FlatScene flat = flatten_scene(scene, FlattenOptions{.sphere_tessellation = args.render.sphere_tessellation});
  release_object_meshes(scene);
  if (!args.render.quiet) print_notices(args.render.scene, report, scene);
  warn_about_dropped_triangles(scene, flat, args.render.quiet);
  const SceneSurfaceTest surface_test(scene, flat);
  const std::unique_ptr<Accel> accel = build_accel(batch.accel_kind, flat, with_surface_test(batch.accel_options, surface_test));

  options.render = render_options(args.render, batch);
  options.screenshot_path = args.screenshot;
  options.exit_when_done = args.exit_when_done;
  options.scene_name = args.scene_path.empty() ? "<built-in default>" : fs::path(args.scene_path).filename().string();
  options.quiet = args.render.quiet;
  return run_viewer(scene, flat, *accel, options);
}

int run_merge(const std::vector<std::string>& paths, const std::string& output, bool quiet) {
  check_output_path(output);
  const auto start = Clock::now();
  DisplayTransform display;
  const Image image = merge_regions(paths, &display);
  write_image(image, output, {}, display);
  if (!quiet)
    fmt::print("{}: {}x{} from {} region file(s), {:.3f} s\n", output, image.width, image.height, paths.size(),
               seconds_since(start));
  return 0;
}

namespace {

// ", glass ior 1.5, transmission (1, 1, 1), thin" for `rt info`; empty for an opaque material.
std::string glass_text(const Material& m) {
  if (!m.is_dielectric()) return "";
  std::string text = fmt::format(", glass ior {}, transmission ({}, {}, {})", m.ior, m.transmission.r, m.transmission.g,
                                 m.transmission.b);
  if (m.transmission_mix)
    text += fmt::format(" x base colour, covering {}{}", m.transmission_factor,
                        m.transmission_texture.empty() ? "" : " x texture " + m.transmission_texture.path);
  if (m.thin_walled) text += ", thin-walled (no bending)";
  if (std::isfinite(m.attenuation_distance))
    text += fmt::format(", absorbing to ({}, {}, {}) over {}", m.attenuation_color.r, m.attenuation_color.g,
                        m.attenuation_color.b, m.attenuation_distance);
  return text;
}

// The per-hit maps of `m` for `rt info` (", normal map N (scale 1), metallic-roughness M x map R"),
// empty when it has none; with a texture transform or the second coordinate set, said per map.
std::string maps_text(const Material& m) {
  const auto map = [](const Texture& t) {
    std::string text = t.path;
    if (t.texcoord == 1) text += " on TEXCOORD_1";
    if (!t.transform.identity())
      text += fmt::format(" (offset ({}, {}), rotation {}, scale ({}, {}))", t.transform.offset.x, t.transform.offset.y,
                          t.transform.rotation, t.transform.scale.x, t.transform.scale.y);
    return text;
  };
  std::string text;
  if (const auto& mr = m.metallic_roughness)
    text += fmt::format(", per hit: base ({}, {}, {}) metallic {} roughness {}{}", mr->base_color.r, mr->base_color.g,
                        mr->base_color.b, mr->metallic, mr->roughness,
                        mr->texture.empty() ? "" : " x map " + map(mr->texture));
  if (!m.normal_texture.empty()) text += fmt::format(", normal map {} (scale {})", map(m.normal_texture), m.normal_scale);
  if (!m.occlusion_texture.empty())
    text += fmt::format(", occlusion map {} (strength {})", map(m.occlusion_texture), m.occlusion_strength);
  if (!m.specular_texture.empty()) text += ", specular map " + map(m.specular_texture);
  if (!m.shininess_texture.empty()) text += ", shininess map " + map(m.shininess_texture);
  if (!m.bump_texture.empty()) text += fmt::format(", bump map {} (scale {})", map(m.bump_texture), m.bump_scale);
  return text;
}

// ", back faces flipped" or ", back faces culled" for `rt info`; empty for the course's unflipped.
std::string back_face_text(const Material& m) {
  if (m.is_dielectric() || m.back_face == BackFace::unflipped) return "";
  return m.back_face == BackFace::flipped ? ", back faces flipped" : ", back faces culled";
}

// ", mask at 0.5, alpha 1 x texture T" for `rt info`; empty for an opaque material.
std::string alpha_text(const Material& m) {
  if (!m.has_alpha()) return "";
  return fmt::format(", {} alpha {}{}", m.alpha_mode == AlphaMode::mask ? fmt::format("mask at {}", m.alpha_cutoff) : "blend",
                     m.alpha, m.alpha_texture.empty() ? "" : " x texture " + m.alpha_texture.path);
}

}  // namespace

int run_info(const std::string& scene_path, const GltfOptions& gltf, const SceneOptions& scene_options,
             const EffectsOptions& effects, bool quiet) {
  LoadReport report;
  const Scene scene = load_scene_for_command(scene_path, gltf, {}, scene_options, report);
  const FlatScene flat = flatten_scene(scene);
  if (!quiet) print_notices(scene_options, report, scene);
  std::size_t models = 0;
  for (const Node& node : scene.nodes) models += node.models.size();
  const Bounds3d bounds = flat_bounds(flat);
  const Camera& c = scene.camera;
  fmt::print("scene       {}\n", scene.source);
  fmt::print("image       {}x{}, max depth {}, background ({}, {}, {}), display {}\n", scene.settings.width,
             scene.settings.height, scene.settings.max_depth, scene.settings.background.r,
             scene.settings.background.g, scene.settings.background.b, to_string(scene.settings.display));
  fmt::print("camera      eye ({}, {}, {}), target ({}, {}, {}), up ({}, {}, {}), fovy {} deg\n", c.eye.x, c.eye.y,
             c.eye.z, c.target.x, c.target.y, c.target.z, c.up.x, c.up.y, c.up.z, c.fovy_degrees);
  fmt::print("graph       {}, {}\n", count_of(scene.nodes.size(), "node"), count_of(models, "model"));
  fmt::print("geometry    {}, {}, {} dropped, {} (exact)\n", count_of(flat.triangle_count(), "triangle"),
             count_of(flat.positions.size(), "vertex", "vertices"),
             count_of(flat.degenerate_triangles_dropped, "degenerate triangle"), count_of(flat.spheres.size(), "sphere"));
  if (!bounds.empty())
    fmt::print("bounds      ({:.7g}, {:.7g}, {:.7g}) .. ({:.7g}, {:.7g}, {:.7g})\n", bounds.lo.x, bounds.lo.y,
               bounds.lo.z, bounds.hi.x, bounds.hi.y, bounds.hi.z);
  fmt::print("materials   {}\n", scene.materials.size());
  for (const Material& m : scene.materials)
    fmt::print("  {:<16} diffuse ({}, {}, {}), specular ({}, {}, {}), shininess {}{}{}{}{}{}\n", m.name, m.diffuse.r,
               m.diffuse.g, m.diffuse.b, m.specular.r, m.specular.g, m.specular.b, m.shininess,
               m.diffuse_texture.empty() ? "" : ", texture " + m.diffuse_texture.path, maps_text(m), glass_text(m),
               alpha_text(m), back_face_text(m));
  fmt::print("lights      {}\n", scene.lights.size());
  for (const Light& l : scene.lights) {
    if (l.is_directional())
      fmt::print("  directional towards ({}, {}, {}), colour ({}, {}, {})\n", l.position.x, l.position.y,
                 l.position.z, l.color.r, l.color.g, l.color.b);
    else
      fmt::print("  {} at ({}, {}, {}), colour ({}, {}, {}), attenuation ({}, {}, {}){}\n", l.is_spot() ? "spot" : "point",
                 l.position.x, l.position.y, l.position.z, l.color.r, l.color.g, l.color.b, l.attenuation.x,
                 l.attenuation.y, l.attenuation.z,
                 l.is_spot() ? fmt::format(", towards ({}, {}, {}), cone cosines {} .. {}", l.spot_direction.x,
                                           l.spot_direction.y, l.spot_direction.z, l.spot_cos_inner, l.spot_cos_outer)
                             : "");
  }
  const EffectsPlan plan = plan_effects(scene, flat, RayOffset{}, effects);
  const std::size_t emitters = plan.emitters.size();
  fmt::print("area lights {}, {}\n", count_of(emitters, "emitter"),
             count_of(plan.area_lights ? plan.area_lights->triangle_count : 0, "emissive triangle"));
  for (std::size_t e = 0; e < emitters; ++e) {
    const Emitter& emitter = plan.area_lights->emitters[e];
    const Material& m = scene.materials[emitter.material];
    fmt::print("  {:<16} {}, area {:.6g}, radiance ({}, {}, {}){}, power ({:.6g}, {:.6g}, {:.6g}){}\n", m.name,
               count_of(emitter.triangles.size(), "triangle"), emitter.area, m.emission.r,
               m.emission.g, m.emission.b, m.emission_texture.empty() ? "" : " x texture " + m.emission_texture.path,
               emitter.power.r, emitter.power.g, emitter.power.b, emitter.planar ? ", planar" : "");
  }
  fmt::print("effects     (default ray offsets; see rt render --explain for the ray budget)\n");
  for (const std::string& line : describe_plan(plan, scene)) fmt::print("  {}\n", line);
  return 0;
}

}  // namespace rt
