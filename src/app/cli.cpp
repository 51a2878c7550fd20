#include "rt/app/cli.h"

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <new>
#include <optional>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "rt/accel/accel.h"
#include "rt/app/progress.h"
#include "rt/app/scene_options.h"
#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/flatten/flatten.h"
#include "rt/io/atomic_file.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/render/render.h"
#include "ray_budget.h"

namespace rt {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct RenderArgs {
  std::string scene_path;  // empty: built-in default scene
  std::string output;
  std::optional<int> width, height, max_depth;
  std::string accel = "embree";
  std::string embree_robust = "on";
  std::string embree_quality = "medium";
  std::string embree_kernel = "native";
  int sphere_tessellation = 0;
  std::string ray_offset = "robust";
  int threads = 0;
  std::uint64_t memory_limit = 0;  // bytes; 0: what the machine has available
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

Scene load_scene_or_default(const std::string& path, const GltfOptions& gltf, LoadReport* report) {
  // --gltf-scene and --camera choose among what a glTF file holds; other formats have one of each.
  if ((gltf.scene || !gltf.camera.empty()) && !is_gltf_path(path))
    throw UsageError(fmt::format("--gltf-scene and --camera apply to .gltf/.glb scenes only, not '{}'",
                                 path.empty() ? "<built-in default>" : path));
  return path.empty() ? make_default_scene() : load_scene(path, gltf, report);
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
    fmt::print(stderr, "rt: warning: {}: dropped {} degenerate triangle(s) (zero area)\n", scene.source,
               flat.degenerate_triangles_dropped);
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

int run_render(const RenderArgs& args) {
  const auto start = Clock::now();
  set_memory_limit(args.memory_limit);
  const int threads = args.threads > 0 ? args.threads : tbb::info::default_concurrency();
  // Limits Embree's BVH build (TBB tasks) as well as the render loop.
  tbb::global_control thread_limit(tbb::global_control::max_allowed_parallelism, threads);
  const AccelKind accel_kind = parse_accel_kind(args.accel);
  AccelOptions accel_options;
  accel_options.embree_robust = args.embree_robust == "on";
  accel_options.embree_quality = parse_embree_quality(args.embree_quality);
  accel_options.embree_kernel = parse_embree_kernel(args.embree_kernel);
  const RayOffset ray_offset = parse_ray_offset(args.ray_offset);

  LoadReport report;
  Scene scene = load_scene_or_default(args.scene_path, args.gltf, &report);
  if (args.width) scene.settings.width = *args.width;
  if (args.height) scene.settings.height = *args.height;
  if (args.max_depth) scene.settings.max_depth = *args.max_depth;
  apply_scene_options(args.scene, report, scene);
  validate_scene(scene);
  const std::string output = args.output.empty() ? default_output(scene, args.scene_path) : args.output;
  check_output_path(output);  // fail before rendering, not after
  if (!args.stats_path.empty()) check_parent_directory_writable(args.stats_path);
  check_render_memory(scene);
  const double load_s = seconds_since(start);

  auto phase_start = Clock::now();
  FlattenOptions flatten_options;
  flatten_options.sphere_tessellation = args.sphere_tessellation;
  const FlatScene flat = flatten_scene(scene, flatten_options);
  const double flatten_s = seconds_since(phase_start);
  // Notes and warnings only once the scene has loaded and flattened: a failing run prints one line.
  if (!args.quiet) print_notices(args.scene, report, scene);
  warn_about_dropped_triangles(scene, flat, args.quiet);

  phase_start = Clock::now();
  const std::unique_ptr<Accel> accel = build_accel(accel_kind, flat, accel_options);
  const double build_s = seconds_since(phase_start);

  RenderOptions options;
  options.threads = threads;
  options.samples_per_pixel = args.spp;
  options.ray_offset = ray_offset;
  options.effects = args.effects;
  if (!args.debug_pixel.empty()) {
    for (const std::string& line : trace_pixel(scene, flat, *accel, options, args.debug_pixel[0], args.debug_pixel[1]))
      fmt::print("{}\n", line);
    return 0;
  }
  options.time_queries = args.explain || !args.stats_path.empty();
  ProgressBar progress("rendering", !args.quiet);
  options.on_progress = [&](double fraction) { progress.update(fraction); };
  const ScopedInterruptHandler interrupt_handler;
  options.cancel = &interrupted;
  const RenderResult result = render_image(scene, flat, *accel, options);
  progress.finish();
  if (result.cancelled()) {
    const int signal = interrupting_signal;
    const std::string what = fmt::format("rt: interrupted by {} after {} of {} tiles", signal == SIGTERM ? "SIGTERM" : "SIGINT",
                                         result.tiles_finished(), result.tile_count());
    if (args.partial_output) {
      const std::string partial = partial_output_path(output);
      write_image(result.image, partial);
      fmt::print(stderr, "{}; the finished tiles are in {} (unfinished tiles black); {} not written\n", what, partial,
                 output);
    } else {
      fmt::print(stderr, "{}; nothing written (--partial-output keeps the finished tiles)\n", what);
    }
    return 128 + (signal == SIGTERM ? SIGTERM : SIGINT);
  }
  if (result.non_finite_samples > 0 && !args.quiet)
    fmt::print(stderr, "rt: warning: {} sample(s) were NaN or infinite and were replaced by black; the first in pixel "
               "({}, {}): see its ray tree with --debug-pixel {} {}\n", result.non_finite_samples,
               result.first_non_finite_pixel->first, result.first_non_finite_pixel->second,
               result.first_non_finite_pixel->first, result.first_non_finite_pixel->second);

  phase_start = Clock::now();
  write_image(result.image, output);
  const double write_s = seconds_since(phase_start);
  const double total_s = seconds_since(start);
  const double mrays = result.rays.total() / std::max(result.seconds, 1e-9) / 1e6;

  if (!args.stats_path.empty()) {
    nlohmann::ordered_json stats;
    stats["scene"] = args.scene_path.empty() ? "<built-in default>" : args.scene_path;
    stats["output"] = output;
    stats["accel"] = to_string(accel_kind);
    if (accel_kind == AccelKind::embree)
      stats["embree"] = {{"robust", accel_options.embree_robust},
                         {"quality", to_string(accel_options.embree_quality)},
                         {"kernel", to_string(accel_options.embree_kernel)}};
    stats["ray_offset"] = to_string(ray_offset);
    stats["threads"] = threads;
    stats["image"] = {{"width", scene.settings.width}, {"height", scene.settings.height}};
    stats["max_depth"] = scene.settings.max_depth;
    stats["samples_per_pixel"] = args.spp;
    stats["triangles"] = flat.triangle_count();
    stats["spheres"] = flat.spheres.size();
    stats["sphere_tessellation"] = args.sphere_tessellation;
    stats["degenerate_triangles_dropped"] = flat.degenerate_triangles_dropped;
    stats["non_finite_samples"] = result.non_finite_samples;
    stats["lights"] = scene.lights.size();
    stats["rays"] = {{"camera", result.rays.camera},
                     {"shadow", result.rays.shadow},
                     {"reflection", result.rays.reflection},
                     {"total", result.rays.total()}};
    stats["effects"] = effects_json(result.plan, scene);
    stats["ray_budget"] = ray_budget_json(result, scene);
    stats["mrays_per_s"] = mrays;
    stats["time_s"] = {{"load", load_s},     {"flatten", flatten_s}, {"build", build_s},
                       {"render", result.seconds}, {"write", write_s},   {"total", total_s}};
    write_text_file_atomically(args.stats_path, stats.dump(2) + "\n");
  }
  if (args.explain) fmt::print("{}", explain_render(result, scene));
  if (!args.quiet)
    fmt::print(
        "{}: {}x{}, {} triangles, {} spheres, {} lights, {:.3f} s render, {:.3f} s total, {:.2f} Mrays/s ({}, {} "
        "threads)\n",
        output, scene.settings.width, scene.settings.height, flat.triangle_count(), flat.spheres.size(),
        scene.lights.size(), result.seconds, total_s, mrays, to_string(accel_kind), threads);
  return 0;
}

int run_info(const std::string& scene_path, const GltfOptions& gltf, const SceneOptions& scene_options,
             const EffectsOptions& effects) {
  LoadReport report;
  Scene scene = load_scene_or_default(scene_path, gltf, &report);
  apply_scene_options(scene_options, report, scene);
  validate_scene(scene);
  const FlatScene flat = flatten_scene(scene);
  print_notices(scene_options, report, scene);
  std::size_t models = 0;
  for (const Node& node : scene.nodes) models += node.models.size();
  const Bounds3d bounds = flat_bounds(flat);
  const Camera& c = scene.camera;
  fmt::print("scene       {}\n", scene.source);
  fmt::print("image       {}x{}, max depth {}, background ({}, {}, {})\n", scene.settings.width,
             scene.settings.height, scene.settings.max_depth, scene.settings.background.r,
             scene.settings.background.g, scene.settings.background.b);
  fmt::print("camera      eye ({}, {}, {}), target ({}, {}, {}), up ({}, {}, {}), fovy {} deg\n", c.eye.x, c.eye.y,
             c.eye.z, c.target.x, c.target.y, c.target.z, c.up.x, c.up.y, c.up.z, c.fovy_degrees);
  fmt::print("graph       {} nodes, {} models\n", scene.nodes.size(), models);
  fmt::print("geometry    {} triangles, {} vertices, {} degenerate triangles dropped, {} spheres (exact)\n",
             flat.triangle_count(), flat.positions.size(), flat.degenerate_triangles_dropped, flat.spheres.size());
  if (!bounds.empty())
    fmt::print("bounds      ({:.7g}, {:.7g}, {:.7g}) .. ({:.7g}, {:.7g}, {:.7g})\n", bounds.lo.x, bounds.lo.y,
               bounds.lo.z, bounds.hi.x, bounds.hi.y, bounds.hi.z);
  fmt::print("materials   {}\n", scene.materials.size());
  for (const Material& m : scene.materials)
    fmt::print("  {:<16} diffuse ({}, {}, {}), specular ({}, {}, {}), shininess {}{}\n", m.name, m.diffuse.r,
               m.diffuse.g, m.diffuse.b, m.specular.r, m.specular.g, m.specular.b, m.shininess,
               m.diffuse_texture.empty() ? "" : ", texture " + m.diffuse_texture.path);
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
  fmt::print("effects     (default ray offsets; see rt render --explain for the ray budget)\n");
  for (const std::string& line : describe_plan(plan_effects(scene, flat, RayOffset{}, effects), scene))
    fmt::print("  {}\n", line);
  return 0;
}

}  // namespace

int run_cli(int argc, char** argv) {
  CLI::App app{"rt: a Whitted ray tracer on Embree, with a double-precision reference intersector"};
  app.set_version_flag("--version", std::string("rt ") + RT_VERSION);
  app.require_subcommand(1);

  RenderArgs render_args;
  CLI::App* render = app.add_subcommand("render", "Render a scene (the built-in default scene when none is given)");
  render->add_option("scene", render_args.scene_path, "Scene file (.json, .test, .gltf, .glb, .obj)");
  const auto add_gltf_options = [](CLI::App* command, GltfOptions& gltf) {
    command->add_option("--gltf-scene", gltf.scene, "glTF only: index of the scene to show (default: the file's default)")
        ->check(CLI::NonNegativeNumber);
    command->add_option("--camera", gltf.camera,
                        "glTF only: camera name, camera node name or index into the file's cameras "
                        "(default: the first perspective camera in the scene)");
  };
  add_gltf_options(render, render_args.gltf);
  render->add_option("-o,--output", render_args.output,
                     "Output image; format by extension (png, jpg, exr, hdr, tif, ...). "
                     "Default: the scene's \"output\", else <scene name>.png");
  render->add_option("--width", render_args.width, "Image width in pixels")->check(CLI::Range(1, kMaxImageSide));
  render->add_option("--height", render_args.height, "Image height in pixels")->check(CLI::Range(1, kMaxImageSide));
  render->add_option("--max-depth", render_args.max_depth, "Reflection depth (0 = no reflections)")
      ->check(CLI::Range(0, kMaxReflectionDepth));
  render->add_option("--spp", render_args.spp,
                     "Samples per pixel: 1 = the pixel centre (the seed's camera); N > 1 = stratified jittered "
                     "samples averaged with a box filter (anti-aliasing), the same image for any thread count")
      ->check(CLI::Range(1, 1 << 16))
      ->capture_default_str();
  render->add_option("--accel", render_args.accel, "Intersector: embree (fast), reference (watertight, double, brute force) or "
                     "reference-barycentric (the seed's plain solve, double, brute force)")
      ->check(CLI::IsMember({"embree", "reference", "reference-barycentric"}))
      ->capture_default_str();
  render->add_option("--embree-robust", render_args.embree_robust,
                     "Embree's robust mode: watertight triangle test, conservative boxes")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  render->add_option("--embree-quality", render_args.embree_quality, "Embree BVH build quality")
      ->check(CLI::IsMember({"low", "medium", "high"}))
      ->capture_default_str();
  render->add_option("--embree-kernel", render_args.embree_kernel,
                     "Triangle test inside Embree's BVH: native (Embree's, fastest) or watertight (the reference's "
                     "double-precision watertight test: no ray slips through a closed mesh, slower)")
      ->check(CLI::IsMember({"native", "watertight"}))
      ->capture_default_str();
  render->add_option("--sphere-tessellation", render_args.sphere_tessellation,
                     "Spheres: 0 = exact quadrics, N >= 3 = UV spheres of N slices and N/2 stacks (for comparison)")
      ->check(CLI::Validator(
          [](std::string& value) {
            const int n = std::atoi(value.c_str());
            return n == 0 || (n >= 3 && n <= 4096) ? std::string() : "must be 0 or 3..4096";
          },
          "0 or 3..4096"))
      ->capture_default_str();
  render->add_option("--ray-offset", render_args.ray_offset,
                     "Self-intersection policy of secondary rays: robust (scale-independent error bound) "
                     "or fixed:EPS (a constant distance in scene units, e.g. fixed:1e-4)")
      ->capture_default_str();
  render->add_option("--threads", render_args.threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  render->add_option_function<std::string>(
            "--memory-limit",
            [&render_args](const std::string& text) {
              const std::optional<std::uint64_t> bytes = parse_bytes(text);
              if (!bytes || *bytes == 0) throw CLI::ValidationError("--memory-limit", "expected a size such as 512M or 8G");
              render_args.memory_limit = *bytes;
            },
            "Refuse (with a clear error, before allocating) work that needs more memory than this, e.g. 8G; "
            "default: what the machine has available")
      ->type_name("SIZE");
  render->add_option("--stats", render_args.stats_path,
                     "Write ray counts, the effects plan, the ray budget and phase timings as JSON to this file");
  render->add_flag("--partial-output", render_args.partial_output,
                   "If interrupted (Ctrl-C, SIGTERM), write the finished tiles to <output stem>.partial<ext>");
  render->add_option("--debug-pixel", render_args.debug_pixel,
                     "Print the ray tree of pixel X Y (every ray, light and colour) instead of rendering")
      ->expected(2)
      ->type_name("X Y");
  render->add_flag("--explain", render_args.explain,
                   "Print the effects plan and the ray budget (rays, hits, time per effect, skipped rays) at the end");
  const auto add_effects_options = [](CLI::App* command, EffectsOptions& effects) {
    command->add_flag("--no-prune", [&effects](std::int64_t) { effects.prune = false; },
                      "Trace every shadow and reflection ray, even those the exact rules prove useless "
                      "(same image, more rays)");
    command->add_option("--min-throughput", effects.min_throughput,
                        "Approximation, off by default: no reflection ray once the path's weight is below this "
                        "(e.g. 0.002 = half an 8-bit step); error <= value x the scene's radiance bound")
        ->check(CLI::Range(0.0, 1.0));
    command->add_option("--min-light", effects.min_light_contribution,
                        "Approximation, off by default: drop a light at a hit when its term is below this "
                        "(linear RGB); error <= value x lights x path weight bound")
        ->check(CLI::Range(0.0, 1.0));
  };
  add_effects_options(render, render_args.effects);
  render->add_flag("-q,--quiet", render_args.quiet, "No progress bar, summary line, warnings or notes");
  add_scene_options(*render, render_args.scene);

  std::string info_path;
  GltfOptions info_gltf;
  CLI::App* info = app.add_subcommand("info", "Print what a scene contains (the default scene when none is given)");
  info->add_option("scene", info_path, "Scene file (.json, .test, .gltf, .glb, .obj)");
  add_gltf_options(info, info_gltf);
  SceneOptions info_scene;
  add_scene_options(*info, info_scene);
  EffectsOptions info_effects;
  add_effects_options(info, info_effects);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const int code = app.exit(error);  // prints help/version (code 0) or the usage error
    return code == 0 ? 0 : 2;
  }

  try {
    if (*render) return run_render(render_args);
    if (*info) return run_info(info_path, info_gltf, info_scene, info_effects);
  } catch (const UsageError& error) {
    fmt::print(stderr, "rt: error: {}\n", printable_line(error.what()));
    return 2;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "rt: error: out of memory\n");
  } catch (const std::exception& error) {  // InputError, RuntimeError and anything else
    fmt::print(stderr, "rt: error: {}\n", printable_line(error.what()));
  }
  return 1;
}

}  // namespace rt
