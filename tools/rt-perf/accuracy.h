#pragma once
// rt-perf accuracy: renders a ground truth with the most accurate settings, then sweeps one knob at
// a time and reports render time, rays and error against the ground truth (CSV, Markdown, plots).

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "metrics.h"
#include "rt/accel/accel.h"
#include "rt/render/effects.h"
#include "rt/render/ray_offset.h"

namespace rt::perf {

// Everything a render's accuracy and cost depend on besides the scene.
struct RenderConfig {
  int spp = 1;
  int max_depth = 5;
  int sphere_tessellation = 0;  // 0: exact quadrics
  AccelOptions accel;
  RayOffset ray_offset;
  EffectsOptions effects;
};

// One point of a sweep: `knob` set to `value` (as the CSV names them), every other setting at
// the renderer's default. `truth` says which ground truth it is compared with ("spp" for the
// samples-per-pixel sweep, "light" for the area-light sampling knobs, "1spp" for the others, see
// plan_sweep).
struct SweepPoint {
  std::string knob;
  std::string value;
  bool is_default = false;
  RenderConfig config;
  std::string truth;
};

// Knob names, in the order they are swept: spp, max_depth, sphere_tessellation, embree_robust,
// embree_quality, embree_kernel, ray_offset, min_throughput, min_light, light_samples, light_sampling.
const std::vector<std::string>& knob_names();

// The renderer's defaults for a scene whose own max depth is `scene_depth`.
RenderConfig default_config(int scene_depth);

// The ground truth: Embree with the watertight kernel (hits bit-identical to the double-precision
// reference), robust mode, high-quality BVH, exact spheres, robust offsets, no approximation,
// depth max(scene_depth, truth_depth), `spp` samples per pixel, `light_samples` area-light samples
// per emitter per hit.
RenderConfig truth_config(int scene_depth, int truth_depth, int spp, int light_samples);

// The points of the sweeps for `knobs` (a subset of knob_names; throws std::invalid_argument
// naming an unknown one). sphere_tessellation is swept only when the scene has spheres, light_samples
// and light_sampling only when it has emitters.
// Errors of the spp sweep are measured against the many-sample truth; those of light_samples and
// light_sampling against the defaults with many light samples (so the intersection kernel's
// differences at silhouettes do not swamp the light sampling's noise); all others against the
// truth rendered at 1 sample per pixel, so that aliasing does not swamp what the knob changes.
std::vector<SweepPoint> plan_sweep(const std::vector<std::string>& knobs, int scene_depth, bool has_spheres,
                                   bool has_emitters);

// One measured point, as a CSV row: the header is csv_header().
struct Measurement {
  SweepPoint point;
  double time_median = 0.0, time_min = 0.0, time_max = 0.0;  // render seconds over the runs
  double build_median = 0.0;                                  // Embree build seconds
  std::uint64_t rays = 0;
  ImageError error;
};
std::string csv_header();
std::string csv_row(const Measurement& measurement);
std::string markdown_table(const std::vector<Measurement>& measurements);

// How error falls with samples per pixel: the least-squares slope of log(RMSE) against log(spp)
// over the spp points with spp <= truth_spp / 16, whose RMSE the truth's own sampling error
// (about a quarter of theirs or less) biases by a few percent at most. nullopt when fewer than two
// such points have a positive RMSE. Plain Monte Carlo gives -0.5; stratified jitter tends to
// -0.75 in pixels crossed by an edge and -1 in smooth ones (Mitchell, "Consequences of
// stratified sampling in graphics", SIGGRAPH 1996).
std::optional<double> fit_spp_slope(const std::vector<Measurement>& measurements, int truth_spp);

// Registers the `accuracy` subcommand on `app`; the returned function runs it once parsed and
// returns the exit status.
std::function<int()> add_accuracy_command(CLI::App& app);

}  // namespace rt::perf
