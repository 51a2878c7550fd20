#include "rt/app/cli.h"

#include <cstdio>
#include <cstdlib>
#include <new>
#include <optional>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "rt/accel/embree_accel.h"
#include "rt/app/scene_options.h"
#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "commands.h"
#include "usage.h"

namespace rt {

namespace {

// An option taking a positive size such as 512M or 8G (parse_bytes) into `bytes`.
CLI::Option* add_size_option(CLI::App* command, const std::string& name, std::uint64_t& bytes, const std::string& help) {
  return command
      ->add_option_function<std::string>(
          name,
          [name, &bytes](const std::string& text) {
            const std::optional<std::uint64_t> parsed = parse_bytes(text);
            if (!parsed || *parsed == 0)
              throw CLI::ValidationError(name, fmt::format("'{}' is not a size such as 512M or 8G", text));
            bytes = *parsed;
          },
          help)
      ->type_name("SIZE");
}

// "K/N" with 1 <= K <= N: --tile's argument.
std::string parse_tile(const std::string& text, RegionRequest& region) {
  int k = 0, n = 0;
  char rest = 0;
  if (std::sscanf(text.c_str(), "%d/%d%c", &k, &n, &rest) != 2 || k < 1 || n < 1 || k > n)
    return fmt::format("'{}': expected K/N with 1 <= K <= N, e.g. 3/16", text);
  region.k = k;
  region.n = n;
  return "";
}

}  // namespace

int run_cli(int argc, char** argv) {
  CLI::App app{"rt: a Whitted ray tracer on Embree, with a double-precision reference intersector"};
  app.set_version_flag("--version", fmt::format("rt {} (Embree {})", RT_VERSION, embree_version()));
  app.require_subcommand(1);

  RenderArgs render_args;
  CLI::App* render = app.add_subcommand("render", "Render a scene (the built-in default scene when none is given)");
  render->add_option("scene", render_args.scene_paths,
                     "Scene files (.json, .test, .gltf, .glb, .obj); several make a batch, rendered one after "
                     "another in one process (a failing scene is reported and the others go on)");
  const auto add_gltf_options = [](CLI::App* command, GltfOptions& gltf) {
    command->add_option("--gltf-scene", gltf.scene, "glTF only: index of the scene to show (default: the file's default)")
        ->check(whole_number_in(0, 1 << 30));
    command->add_option("--camera", gltf.camera,
                        "glTF only: camera name, camera node name or index into the file's cameras "
                        "(default: the first perspective camera in the scene)");
  };
  add_gltf_options(render, render_args.gltf);
  render->add_option("-o,--output", render_args.output,
                     "Output image, format by extension (any case): png, ppm (written by rt), exr, hdr (linear "
                     "float), tif, jpg, bmp, tga, webp, gif and the rest OpenImageIO writes. Default: the scene's "
                     "\"output\", else <scene name>.png");
  render->add_option("--outdir", render_args.outdir,
                     "Write each image to DIR/<scene name>.png (created if missing), ignoring the scenes' own "
                     "output names; regions: DIR/<scene name>.tile-K-of-N.exr");
  render->add_flag("--skip-existing", render_args.skip_existing,
                   "Skip scenes whose output file exists (outputs appear only when complete, so an interrupted "
                   "batch resumes where it stopped)");
  render->add_option_function<std::vector<int>>(
            "--crop",
            [&render_args](const std::vector<int>& v) {
              render_args.region.crop = PixelRegion{v[0], v[1], v[2], v[3]};
              if (render_args.region.crop->empty())
                throw CLI::ValidationError("--crop", fmt::format("{} {} {} {} is empty: expected X0 Y0 X1 Y1 with X0 < X1 "
                                                                 "and Y0 < Y1", v[0], v[1], v[2], v[3]));
            },
            "Render only pixels [X0, X1) x [Y0, Y1) of the image, each exactly as in the whole image; an .exr "
            "output keeps their place (data window) for rt merge. Default output: <scene name>.crop-X0-Y0-X1-Y1.exr")
      ->expected(4)
      ->check(whole_number_in(0, kMaxImageSide))
      ->type_name("X0 Y0 X1 Y1");
  render->add_option_function<std::string>(
            "--tile",
            [&render_args](const std::string& text) {
              if (const std::string problem = parse_tile(text, render_args.region); !problem.empty())
                throw CLI::ValidationError("--tile", problem);
            },
            "Render tile K (1..N) of N bands of whole rows, for rt merge (e.g. a Slurm job array: --tile "
            "$SLURM_ARRAY_TASK_ID/N). Output: OpenEXR, default <scene name>.tile-K-of-N.exr")
      ->type_name("K/N")
      ->excludes("--crop");
  render->add_option("--stats", render_args.stats_path,
                     "Write ray counts, the effects plan, the ray budget and phase timings as JSON to this file");
  render->add_flag("--partial-output", render_args.partial_output,
                   "If interrupted (Ctrl-C, SIGTERM), write the finished tiles to <output stem>.partial<ext>");
  render->add_option("--debug-pixel", render_args.debug_pixel,
                     "Print the ray tree of pixel X Y (every ray, light and colour) instead of rendering")
      ->expected(2)
      ->check(whole_number_in(0, kMaxImageSide - 1))
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
        ->check(number_in(0.0, 1.0));
    command->add_option("--min-light", effects.min_light_contribution,
                        "Approximation, off by default: drop a light at a hit when its term is below this "
                        "(linear RGB); error <= value x lights x path weight bound")
        ->check(number_in(0.0, 1.0));
    command->add_option("--light-samples", effects.light_samples,
                        "Area lights (emissive surfaces): shadow-ray samples per emitter per hit, stratified; more "
                        "gives smoother penumbrae at proportional cost")
        ->check(whole_number_in(1, EffectsOptions::kMaxLightSamples))
        ->capture_default_str();
    command->add_option_function<std::string>(
              "--light-sampling",
              [&effects](const std::string& text) { effects.light_sampling = parse_light_sampling(text); },
              "How an area-light sample picks its point: auto (by solid angle where the triangle looks large, "
              "else by area), area or solid-angle")
        ->check(one_of({"auto", "area", "solid-angle"}))
        ->default_str("auto");
  };
  // The settings of an image, shared by rt render and rt view.
  const auto add_image_options = [](CLI::App* command, RenderArgs& args) {
    command->add_option("--width", args.width, "Image width in pixels (alone: the height follows the scene's aspect ratio)")
        ->check(whole_number_in(1, kMaxImageSide));
    command->add_option("--height", args.height, "Image height in pixels (alone: the width follows the scene's aspect ratio)")
        ->check(whole_number_in(1, kMaxImageSide));
    add_size_option(command, "--texture-cache", args.texture_cache,
                    "Decoded textures kept in memory at most, e.g. 512M; scenes whose PNG and JPEG textures need "
                    "more are sampled through OpenImageIO's tiled cache of this size (slower); default: half the "
                    "available memory");
    command->add_option("--max-depth", args.max_depth, "Reflection depth (0 = no reflections)")
        ->check(whole_number_in(0, kMaxReflectionDepth));
    command->add_option_function<std::string>(
              "--display", [&args](const std::string& text) { args.display = parse_display_encoding(text); },
              "How 8-bit outputs and the window encode the linear image: srgb (what viewers assume; the default "
              "for glTF and OBJ) or linear (byte = floor(255 c), the CSE167x course's; the default for .test and "
              "native scenes). EXR and HDR stay linear")
        ->check(one_of({"linear", "srgb"}));
    command->add_option("--exposure", args.exposure_ev, "Scale the image by 2^EV before the tone map and the encoding")
        ->check(number_in(-64.0, 64.0))
        ->type_name("EV");
    command->add_option_function<std::string>(
              "--tonemap", [&args](const std::string& text) { args.tonemap = parse_tonemap(text); },
              "Tone map before the encoding: none (clip to 1), aces (Narkowicz's ACES fit) or pbr-neutral "
              "(Khronos PBR Neutral: colours up to 0.76 unchanged, highlights compressed)")
        ->check(one_of({"none", "aces", "pbr-neutral"}));
    command->add_option("--spp", args.spp,
                        "Samples per pixel: 1 = the pixel centre (the seed's camera); N > 1 = stratified jittered "
                        "samples averaged with a box filter (anti-aliasing), the same image for any thread count")
        ->check(whole_number_in(1, 1 << 16))
        ->capture_default_str();
    command->add_option("--accel", args.accel, "Intersector: embree (fast), reference (watertight, double, brute force) or "
                        "reference-barycentric (the seed's plain solve, double, brute force)")
        ->check(one_of({"embree", "reference", "reference-barycentric"}))
        ->capture_default_str();
    command->add_option("--embree-robust", args.embree_robust,
                        "Embree's robust mode: watertight triangle test, conservative boxes")
        ->check(one_of({"on", "off"}))
        ->capture_default_str();
    command->add_option("--embree-quality", args.embree_quality, "Embree BVH build quality")
        ->check(one_of({"low", "medium", "high"}))
        ->capture_default_str();
    command->add_option("--embree-kernel", args.embree_kernel,
                        "Triangle test inside Embree's BVH: watertight (float32, no ray slips through a closed mesh), "
                        "native (Embree's own: rays aimed at vertices can slip through) or exact (the reference's "
                        "double-precision test: hits equal the reference's, slower)")
        ->check(one_of({"watertight", "native", "exact"}))
        ->capture_default_str();
    command->add_option("--sphere-tessellation", args.sphere_tessellation,
                        "Spheres: 0 = exact quadrics, N >= 3 = UV spheres of N slices and N/2 stacks (for comparison)")
        ->check(CLI::Validator(
            [whole = whole_number_in(0, 4096)](std::string& value) {
              std::string problem = whole(value);
              if (const long n = std::atol(value.c_str()); problem.empty() && n > 0 && n < 3)
                problem = fmt::format("{} is neither 0 nor 3..4096", value);
              return problem;
            },
            "0 or 3..4096"))
        ->capture_default_str();
    command->add_option("--ray-offset", args.ray_offset,
                        "Self-intersection policy of secondary rays: robust (scale-independent error bound) "
                        "or fixed:EPS (a constant distance in scene units, e.g. fixed:1e-4)")
        ->check(kRayOffset)
        ->capture_default_str();
    command->add_option("--threads", args.threads, "Worker threads (0 = all cores)")
        ->check(whole_number_in(0, 1024))
        ->capture_default_str();
    add_size_option(command, "--memory-limit", args.memory_limit,
                    "Refuse (with a clear error, before allocating) work that needs more memory than this, e.g. 8G; "
                    "default: what the machine has available");
  };
  add_image_options(render, render_args);
  add_effects_options(render, render_args.effects);
  render->add_flag("-q,--quiet", render_args.quiet, "No progress bar, summary line, warnings or notes");
  add_scene_options(*render, render_args.scene);

  ViewArgs view_args;
  CLI::App* view = app.add_subcommand(
      "view", "Render a scene in a window, progressively (the built-in default scene when none is given); drag to "
              "orbit, wheel to zoom, R re-render, S save, Q quit");
  view->add_option("scene", view_args.scene_path, "Scene file (.json, .test, .gltf, .glb, .obj)");
  add_gltf_options(view, view_args.render.gltf);
  view->add_option("-o,--output", view_args.render.output,
                   "Where S saves the image shown; format by extension. Default: the scene's \"output\", else "
                   "<scene name>.png");
  view->add_option("--screenshot", view_args.screenshot,
                   "When the render is complete, read the window's pixels back, write them to this 8-bit image "
                   "(png, ppm, ...) and close the window (implies --exit-when-done)");
  view->add_flag("--exit-when-done", view_args.exit_when_done, "Close the window once the render is complete");
  add_image_options(view, view_args.render);
  add_effects_options(view, view_args.render.effects);
  view->add_flag("-q,--quiet", view_args.render.quiet, "No notes or summary lines on stderr");
  add_scene_options(*view, view_args.render.scene);

  std::vector<std::string> merge_paths;
  std::string merge_output;
  bool merge_quiet = false;
  CLI::App* merge = app.add_subcommand("merge", "Stitch region files (rt render --tile/--crop, .exr) into the whole image, "
                                                "checking they come from one scene and settings and cover it exactly once");
  merge->add_option("regions", merge_paths, "Region files (.exr)")->required();
  merge->add_option("-o,--output", merge_output, "Output image; format by extension (png, exr, ...)")->required();
  merge->add_flag("-q,--quiet", merge_quiet, "No summary line");

  std::string info_path;
  GltfOptions info_gltf;
  CLI::App* info = app.add_subcommand("info", "Print what a scene contains (the default scene when none is given)");
  info->add_option("scene", info_path, "Scene file (.json, .test, .gltf, .glb, .obj)");
  add_gltf_options(info, info_gltf);
  SceneOptions info_scene;
  add_scene_options(*info, info_scene);
  EffectsOptions info_effects;
  add_effects_options(info, info_effects);
  bool info_quiet = false;
  info->add_flag("-q,--quiet", info_quiet, "No warnings or notes on stderr (the description is still printed)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    if (error.get_exit_code() == 0) return app.exit(error);  // --help, --version
    fmt::print(stderr, "rt: error: {}\n", printable_line(usage_message(app, error, argc, argv)));
    return 2;
  }
  if (!view_args.screenshot.empty()) view_args.exit_when_done = true;

  try {
    if (*render) return run_render(render_args);
    if (*view) return run_view(view_args);
    if (*merge) return run_merge(merge_paths, merge_output, merge_quiet);
    if (*info) return run_info(info_path, info_gltf, info_scene, info_effects, info_quiet);
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
