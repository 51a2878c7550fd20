#include "accuracy.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numeric>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>

#include "rt/app/scene_options.h"
#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/io/atomic_file.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/render/surface_test.h"
#include "rt/render/render.h"

namespace rt::perf {

namespace fs = std::filesystem;

namespace {

// Values swept per knob (strings as they appear in the CSV and as the rt flags take them).
const std::vector<int> kSppValues{1, 4, 16, 64};
const std::vector<int> kSphereTessellations{8, 16, 32, 64, 128, 256};
const std::vector<std::string> kRayOffsets{"fixed:1e-2", "fixed:1e-3", "fixed:1e-4", "fixed:1e-5", "fixed:1e-6", "robust"};
const std::vector<double> kThresholds{0.0, 0.001, 0.01, 0.05, 0.1};
const std::vector<int> kLightSampleValues{1, 4, 16, 64, 256};
constexpr int kMaxDepthSwept = 8;

std::string format_threshold(double value) { return value == 0.0 ? "0" : fmt::format("{:g}", value); }

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n == 0 ? 0.0 : n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

struct Rendered {
  Image image;
  double render_s = 0.0;
  double build_s = 0.0;
  std::uint64_t rays = 0;
};

// A scene prepared for one configuration: its max depth set and flattened (sphere tessellation),
// once per sweep point rather than once per timed run.
struct Prepared {
  Scene scene;
  FlatScene flat;
};

Prepared prepare(const Scene& base, const RenderConfig& config) {
  Prepared prepared{base, {}};
  prepared.scene.settings.max_depth = config.max_depth;
  FlattenOptions flatten_options;
  flatten_options.sphere_tessellation = config.sphere_tessellation;
  prepared.flat = flatten_scene(prepared.scene, flatten_options);
  return prepared;
}

// Builds the Embree scene and renders once, timing both.
Rendered render_with(const Prepared& prepared, const RenderConfig& config, int threads) {
  const auto start = std::chrono::steady_clock::now();
  const SceneSurfaceTest surface_test(prepared.scene, prepared.flat);
  const std::unique_ptr<Accel> accel = build_accel(AccelKind::embree, prepared.flat, with_surface_test(config.accel, surface_test));
  Rendered rendered;
  rendered.build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  RenderOptions options;
  options.threads = threads;
  options.samples_per_pixel = config.spp;
  options.ray_offset = config.ray_offset;
  options.effects = config.effects;
  RenderResult result = render_image(prepared.scene, prepared.flat, *accel, options);
  rendered.image = std::move(result.image);
  rendered.render_s = result.seconds;
  rendered.rays = result.rays.total();
  return rendered;
}

struct AccuracyArgs {
  std::string scene;  // empty: the built-in default scene
  std::string out;
  int runs = 3;
  std::optional<int> width, height;
  int truth_spp = 256;
  int truth_depth = 10;
  int truth_light_samples = 4096;  // area-light samples per pixel of both ground truths
  int threads = 0;
  std::vector<std::string> knobs;
  bool plots = true;
};

int run_accuracy(const AccuracyArgs& args) {
  std::error_code error;
  fs::create_directories(args.out, error);
  if (error || !fs::is_directory(args.out))
    throw InputError(args.out, "", "cannot create the output directory" + (error ? ": " + error.message() : ""));

  Scene scene = args.scene.empty() ? make_default_scene() : load_scene(args.scene);
  ImageOverrides image;
  image.width = args.width;
  image.height = args.height;
  apply_image_overrides(image, scene);
  validate_scene(scene);
  const int scene_depth = scene.settings.max_depth;
  const FlatScene flat = flatten_scene(scene);
  const bool has_spheres = !flat.spheres.empty();
  const bool has_emitters = !collect_area_lights(scene, flat).empty();
  const std::vector<SweepPoint> points =
      plan_sweep(args.knobs.empty() ? knob_names() : args.knobs, scene_depth, has_spheres, has_emitters);

  if (args.truth_spp <= kSppValues.back() &&
      std::any_of(points.begin(), points.end(), [](const SweepPoint& p) { return p.knob == "spp"; }))
    fmt::print(stderr, "rt-perf: warning: --truth-spp {} does not exceed the largest swept spp ({}); that point "
               "shares the truth's samples and its error is not meaningful\n", args.truth_spp, kSppValues.back());
  fmt::print(stderr, "rt-perf: {} at {}x{}: ground truth at {} spp, depth {}\n", scene.source, scene.settings.width,
             scene.settings.height, args.truth_spp, std::max(scene_depth, args.truth_depth));
  // Both truths take truth_light_samples area-light samples per pixel: spread over the camera
  // samples of the many-sample truth (at least the default per camera sample), all on the pixel
  // centre's hit for the 1-spp one.
  const RenderConfig truth_many_config =
      truth_config(scene_depth, args.truth_depth, args.truth_spp,
                   std::max(EffectsOptions::kDefaultLightSamples, args.truth_light_samples / args.truth_spp));
  const RenderConfig truth_one_config = truth_config(scene_depth, args.truth_depth, 1, args.truth_light_samples);
  const Prepared truth_scene = prepare(scene, truth_many_config);
  const Rendered truth_many = render_with(truth_scene, truth_many_config, args.threads);
  const Rendered truth_one = render_with(truth_scene, truth_one_config, args.threads);
  fmt::print(stderr, "rt-perf: ground truths took {:.2f} s and {:.2f} s\n", truth_many.render_s, truth_one.render_s);
  // The light-sampling knobs' truth: the defaults but for truth_light_samples samples, so that their
  // error is the light sampling's alone, not also the intersection kernel's at silhouettes.
  std::optional<Rendered> truth_light;
  if (std::any_of(points.begin(), points.end(), [](const SweepPoint& p) { return p.truth == "light"; })) {
    RenderConfig config = default_config(scene_depth);
    config.effects.light_samples = args.truth_light_samples;
    truth_light = render_with(prepare(scene, config), config, args.threads);
    fmt::print(stderr, "rt-perf: light-sampling truth took {:.2f} s\n", truth_light->render_s);
  }
  write_image(truth_many.image, (fs::path(args.out) / "truth.exr").string());
  write_image(truth_many.image, (fs::path(args.out) / "truth.png").string());

  std::vector<Measurement> measurements;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const SweepPoint& point = points[i];
    Measurement m;
    m.point = point;
    std::vector<double> times, builds;
    const Prepared prepared = prepare(scene, point.config);
    Rendered last;
    for (int run = 0; run < args.runs; ++run) {
      last = render_with(prepared, point.config, args.threads);
      times.push_back(last.render_s);
      builds.push_back(last.build_s);
    }
    m.time_median = median(times);
    m.time_min = *std::min_element(times.begin(), times.end());
    m.time_max = *std::max_element(times.begin(), times.end());
    m.build_median = median(builds);
    m.rays = last.rays;
    m.error = compare_images(last.image, point.truth == "spp"     ? truth_many.image
                                         : point.truth == "light" ? truth_light->image
                                                                  : truth_one.image);
    fmt::print(stderr, "[{}/{}] {} = {}: {:.3f} s, {} rays, rmse {:.3g}, {:.2f}% pixels off by > 1/255\n", i + 1,
               points.size(), point.knob, point.value, m.time_median, m.rays, m.error.rmse, m.error.pct_over_1_255);
    measurements.push_back(m);
  }

  std::string csv = csv_header() + "\n";
  for (const Measurement& m : measurements) csv += csv_row(m) + "\n";
  const std::string csv_path = (fs::path(args.out) / "accuracy.csv").string();
  write_text_file_atomically(csv_path, csv);
  const std::string header = fmt::format(
      "Scene `{}`, {}x{}, {} render runs per point (median [min, max] render seconds), {} threads. Ground truth: "
      "Embree watertight kernel, robust, high-quality BVH, exact spheres, robust offsets, depth {}; {} spp for the "
      "spp sweep, 1 spp for the others{}.\n\n",
      scene.source, scene.settings.width, scene.settings.height, args.runs,
      args.threads > 0 ? fmt::to_string(args.threads) : "all", std::max(scene_depth, args.truth_depth), args.truth_spp,
      has_emitters ? fmt::format("; {} area-light samples per pixel in both ({} per camera sample in the first). The "
                                 "light_samples and light_sampling points are compared with the defaults at {} light "
                                 "samples (1 spp)",
                                 args.truth_light_samples, truth_many_config.effects.light_samples,
                                 args.truth_light_samples)
                   : "");
  std::string summary;
  if (const std::optional<double> slope = fit_spp_slope(measurements, args.truth_spp))
    summary = fmt::format(
        "\nError against samples per pixel: RMSE ~ spp^{:.2f} (least-squares fit of log RMSE on log spp over spp <= "
        "{}, where the truth's own sampling error is negligible; plain Monte Carlo gives -0.50).\n",
        *slope, args.truth_spp / 16);
  write_text_file_atomically((fs::path(args.out) / "accuracy.md").string(),
                             header + markdown_table(measurements) + summary);
  fmt::print("{}{}{}", header, markdown_table(measurements), summary);

  if (args.plots) {
    // Debian's interpreter, where install-deps puts matplotlib, before whatever python3 is on PATH.
    const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
    const std::string command = fmt::format("{} '{}/tools/plot-accuracy' '{}'", python, RT_SOURCE_DIR, csv_path);
    if (std::system(command.c_str()) != 0)
      fmt::print(stderr, "rt-perf: warning: plots not made (needs python3 with matplotlib): {}\n", command);
  }
  return 0;
}

}  // namespace

const std::vector<std::string>& knob_names() {
  static const std::vector<std::string> names{"spp",           "max_depth",      "sphere_tessellation",
                                              "embree_robust", "embree_quality", "embree_kernel",
                                              "ray_offset",    "min_throughput", "min_light",
                                              "light_samples", "light_sampling"};
  return names;
}

RenderConfig default_config(int scene_depth) {
  RenderConfig config;
  config.max_depth = scene_depth;
  return config;
}

RenderConfig truth_config(int scene_depth, int truth_depth, int spp, int light_samples) {
  RenderConfig config = default_config(std::max(scene_depth, truth_depth));
  config.spp = spp;
  config.effects.light_samples = light_samples;
  config.accel.embree_robust = true;
  config.accel.embree_quality = EmbreeQuality::high;
  config.accel.embree_kernel = EmbreeKernel::exact;
  return config;
}

std::vector<SweepPoint> plan_sweep(const std::vector<std::string>& knobs, int scene_depth, bool has_spheres,
                                   bool has_emitters) {
  for (const std::string& knob : knobs)
    if (std::find(knob_names().begin(), knob_names().end(), knob) == knob_names().end())
      throw std::invalid_argument(fmt::format("unknown knob '{}' (known: {})", knob, fmt::join(knob_names(), ", ")));
  const RenderConfig base = default_config(scene_depth);
  std::vector<SweepPoint> points;
  const auto add = [&](const std::string& knob, const std::string& value, const RenderConfig& config) {
    const bool is_default = config.spp == base.spp && config.max_depth == base.max_depth &&
                            config.sphere_tessellation == base.sphere_tessellation &&
                            config.accel.embree_robust == base.accel.embree_robust &&
                            config.accel.embree_quality == base.accel.embree_quality &&
                            config.accel.embree_kernel == base.accel.embree_kernel &&
                            to_string(config.ray_offset) == to_string(base.ray_offset) &&
                            config.effects.min_throughput == base.effects.min_throughput &&
                            config.effects.min_light_contribution == base.effects.min_light_contribution &&
                            config.effects.light_samples == base.effects.light_samples &&
                            config.effects.light_sampling == base.effects.light_sampling;
    const bool light = knob == "light_samples" || knob == "light_sampling";
    points.push_back({knob, value, is_default, config, knob == "spp" ? "spp" : light ? "light" : "1spp"});
  };
  for (const std::string& knob : knob_names()) {
    if (std::find(knobs.begin(), knobs.end(), knob) == knobs.end()) continue;
    RenderConfig c = base;
    if (knob == "spp") {
      for (int spp : kSppValues) c.spp = spp, add(knob, fmt::to_string(spp), c);
    } else if (knob == "max_depth") {
      std::vector<int> depths;
      for (int d = 0; d <= kMaxDepthSwept; ++d) depths.push_back(d);
      if (scene_depth > kMaxDepthSwept) depths.push_back(scene_depth);
      for (int d : depths) c.max_depth = d, add(knob, fmt::to_string(d), c);
    } else if (knob == "sphere_tessellation") {
      if (!has_spheres) continue;
      for (int n : kSphereTessellations) c.sphere_tessellation = n, add(knob, fmt::to_string(n), c);
      c.sphere_tessellation = 0, add(knob, "exact", c);
    } else if (knob == "embree_robust") {
      for (bool on : {true, false}) c.accel.embree_robust = on, add(knob, on ? "on" : "off", c);
    } else if (knob == "embree_quality") {
      for (EmbreeQuality q : {EmbreeQuality::low, EmbreeQuality::medium, EmbreeQuality::high})
        c.accel.embree_quality = q, add(knob, std::string(to_string(q)), c);
    } else if (knob == "embree_kernel") {
      for (EmbreeKernel k : {EmbreeKernel::watertight, EmbreeKernel::native, EmbreeKernel::exact})
        c.accel.embree_kernel = k, add(knob, std::string(to_string(k)), c);
    } else if (knob == "ray_offset") {
      for (const std::string& offset : kRayOffsets) c.ray_offset = parse_ray_offset(offset), add(knob, offset, c);
    } else if (knob == "min_throughput") {
      for (double t : kThresholds) c.effects.min_throughput = t, add(knob, format_threshold(t), c);
    } else if (knob == "min_light") {
      for (double t : kThresholds) c.effects.min_light_contribution = t, add(knob, format_threshold(t), c);
    } else if (knob == "light_samples") {
      if (!has_emitters) continue;
      for (int n : kLightSampleValues) c.effects.light_samples = n, add(knob, fmt::to_string(n), c);
    } else if (knob == "light_sampling") {
      if (!has_emitters) continue;
      for (LightSampling m : {LightSampling::area, LightSampling::solid_angle, LightSampling::automatic})
        c.effects.light_sampling = m, add(knob, std::string(to_string(m)), c);
    }
  }
  return points;
}

std::string csv_header() {
  return "knob,value,default,truth,time_s_median,time_s_min,time_s_max,build_s_median,rays,rmse,psnr,max_abs,"
         "pct_over_1_255";
}

std::string csv_row(const Measurement& m) {
  return fmt::format("{},{},{},{},{:.6f},{:.6f},{:.6f},{:.6f},{},{:.6g},{:.4f},{:.6g},{:.4f}", m.point.knob,
                     m.point.value, m.point.is_default ? 1 : 0, m.point.truth, m.time_median, m.time_min, m.time_max,
                     m.build_median, m.rays, m.error.rmse, m.error.psnr, m.error.max_abs, m.error.pct_over_1_255);
}

std::string markdown_table(const std::vector<Measurement>& measurements) {
  std::string table =
      "| knob | value | render s, median [min, max] | build s | rays | RMSE | PSNR dB | max abs | % px > 1/255 |\n"
      "|---|---|---|---|---|---|---|---|---|\n";
  for (const Measurement& m : measurements)
    table += fmt::format("| {} | {}{} | {:.3f} [{:.3f}, {:.3f}] | {:.3f} | {} | {:.3g} | {:.1f} | {:.3g} | {:.2f} |\n",
                         m.point.knob, m.point.value, m.point.is_default ? " (default)" : "", m.time_median,
                         m.time_min, m.time_max, m.build_median, m.rays, m.error.rmse, m.error.psnr, m.error.max_abs,
                         m.error.pct_over_1_255);
  return table;
}

std::optional<double> fit_spp_slope(const std::vector<Measurement>& measurements, int truth_spp) {
  std::vector<double> xs, ys;
  for (const Measurement& m : measurements)
    if (m.point.knob == "spp" && m.point.config.spp * 16 <= truth_spp && m.error.rmse > 0.0) {
      xs.push_back(std::log(double(m.point.config.spp)));
      ys.push_back(std::log(m.error.rmse));
    }
  const double n = double(xs.size());
  if (xs.size() < 2) return std::nullopt;
  const double mean_x = std::accumulate(xs.begin(), xs.end(), 0.0) / n;
  const double mean_y = std::accumulate(ys.begin(), ys.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    sxy += (xs[i] - mean_x) * (ys[i] - mean_y);
    sxx += (xs[i] - mean_x) * (xs[i] - mean_x);
  }
  if (sxx == 0.0) return std::nullopt;
  return sxy / sxx;
}

std::function<int()> add_accuracy_command(CLI::App& app) {
  auto args = std::make_shared<AccuracyArgs>();
  CLI::App* command = app.add_subcommand(
      "accuracy", "Render a ground truth, then sweep one knob at a time: render time, rays and error (CSV, Markdown, plots)");
  command->add_option("scene", args->scene, "Scene file (any format rt reads; default: the built-in default scene)");
  command->add_option("--out", args->out, "Directory for accuracy.csv, accuracy.md, the plots and the truth image")
      ->required();
  command->add_option("--runs", args->runs, "Render runs per point (median, min, max)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  command->add_option("--width", args->width, "Image width (height follows the aspect ratio unless given)")
      ->check(CLI::Range(1, kMaxImageSide));
  command->add_option("--height", args->height, "Image height")->check(CLI::Range(1, kMaxImageSide));
  command->add_option("--truth-spp", args->truth_spp, "Samples per pixel of the ground truth")
      ->check(CLI::Range(1, 1 << 16))
      ->capture_default_str();
  command->add_option("--truth-depth", args->truth_depth, "Reflection depth of the ground truth (at least the scene's)")
      ->check(CLI::Range(0, kMaxReflectionDepth))
      ->capture_default_str();
  command->add_option("--truth-light-samples", args->truth_light_samples,
                      "Area-light samples per pixel of the ground truths (scenes with emitters)")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  command->add_option("--threads", args->threads, "Render threads (0 = all cores)")->check(CLI::Range(0, 1024));
  command->add_option("--knobs", args->knobs, "Only these knobs (default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember(knob_names()));
  command->add_flag("--no-plots", [args](std::int64_t) { args->plots = false; }, "Do not run tools/plot-accuracy");
  return [args] { return run_accuracy(*args); };
}

}  // namespace rt::perf
