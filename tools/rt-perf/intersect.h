#pragma once
// rt-perf intersect: per scene, Embree build time and memory (per build quality, robust on/off),
// throughput of Embree and of the reference on camera, shadow and random rays, and agreement;
// a scaling mode over procedural meshes.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/scene/scene.h"

namespace rt::perf {

// Registers the `intersect` subcommand on `app`; the returned function runs it once parsed and
// returns the exit status.
std::function<int()> add_intersect_command(CLI::App& app);

// The camera's rays through the centres of a width x height pixel grid, row-major from the top-left
// pixel (rt::ray_through_pixel). Throws InputError if the camera or the size is unusable.
std::vector<Ray> make_camera_rays(const Scene& scene, int width, int height);

// Shadow rays as the renderer casts them: from each hit of `accel` on `camera_rays`, one per scene
// light, origin offset with the default RayOffset, unit direction towards the light; tfar from
// shadow_ray_tfar for point lights (skipped when <= 0) and infinite for directional ones.
std::vector<Ray> make_shadow_rays(const Scene& scene, const FlatScene& flat, const Accel& accel,
                                  std::span<const Ray> camera_rays);

// `count` rays with origins uniform in `bounds` (world space; the origin when empty) and unit
// directions uniform on the sphere, drawn from std::mt19937_64 seeded with `seed`: the same rays
// for the same seed. tnear 0, tfar infinite.
std::vector<Ray> make_incoherent_rays(const Bounds3d& bounds, std::size_t count, std::uint64_t seed);

// Every `rays.size() / count`-th ray, spread evenly over the set (all of them when count >= size).
std::vector<std::size_t> spread_indices(std::size_t size, std::size_t count);

// `value` with three significant digits (at most nine decimals), never in exponent form: "0.00170",
// "12.8", "4262". The tables of rt-perf's subcommands.
std::string sig3(double value);

// Wall-clock seconds of the timed runs and the throughput they give.
struct Timing {
  std::vector<double> seconds;  // one per run
  std::size_t rays = 0;         // rays per run
  double median_seconds() const;
  double min_seconds() const;
  double max_seconds() const;
  double median_mrays_per_second() const;  // rays / median run, in millions per second
};

// Casts `rays` through accel.intersect (closest hit) `runs` times, each run a tbb::parallel_for over
// the rays on all of TBB's threads, timing the casts only; `hits` receives the last run's answers.
Timing time_intersect(const Accel& accel, std::span<const Ray> rays, int runs, std::vector<Hit>& hits);

// As time_intersect, through accel.occluded; `occluded` receives 1 (occluded) or 0 per ray.
Timing time_occluded(const Accel& accel, std::span<const Ray> rays, int runs, std::vector<std::uint8_t>& occluded);

// Agreement of two intersectors' answers on the same rays. same_hit: both miss, or both hit the same
// primitive (for occlusion: the same occluded answer). t_mismatches: rays hitting the same primitive
// whose t differ by more than `kTRelativeTolerance` of the larger |t|. ties: rays where both hit
// but different primitives at t within that tolerance (a shared edge, coplanar or interpenetrating
// faces: both answers are valid), counted apart from real disagreements.
struct Agreement {
  std::size_t rays = 0;
  std::size_t same_hit = 0;
  std::size_t t_mismatches = 0;
  std::size_t ties = 0;
};
inline constexpr double kTRelativeTolerance = 1e-4;
Agreement compare_hits(std::span<const Hit> a, std::span<const Hit> b);
Agreement compare_occlusion(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b);

// How many rays the reference may cast so that rays x runs fits in the time budget, from the
// measured cost of one ray (seconds, wall clock, under the same parallel_for). Fewer than
// kMinReferenceRays (or all of `rays` when the set is smaller) is not worth timing: skipped.
struct ReferencePlan {
  std::size_t rays = 0;              // to cast per run; 0 when skipped
  bool reduced = false;              // rays < the set's size
  bool skipped = false;
  double estimated_seconds = 0.0;    // for the whole set, all runs
};
inline constexpr std::size_t kMinReferenceRays = 100;
ReferencePlan plan_reference(double seconds_per_ray, std::size_t rays, int runs, double budget_seconds);

// One size of the scaling mode: a UV sphere (make_sphere_mesh) of about `target` triangles.
struct ScalingSize {
  std::size_t target = 0;
  int slices = 0, stacks = 0;
  std::size_t triangles = 0;  // 2 slices (stacks - 1), before flattening drops degenerate ones
};

// One size per decade from 100 up to max_triangles (10^2, 10^3, ...), plus max_triangles itself
// when it is not a power of ten. Throws InputError when max_triangles < 100.
std::vector<ScalingSize> scaling_sizes(double max_triangles);

// A scene holding one unit sphere mesh of `size`, one grey material, a point light and a camera at
// (0, 0, 3) looking at the origin.
Scene make_scaling_scene(const ScalingSize& size);

}  // namespace rt::perf
