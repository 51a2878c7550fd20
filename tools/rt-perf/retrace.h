#pragma once
// rt-perf retrace: how close the render phase comes to the cost of its intersection queries alone.
// A render runs through a recording accel that keeps every query the shader makes; the recorded
// rays are then re-traced in a tight parallel loop through the same Embree accel, and the ratio
// render / re-trace is what ray generation, shading and bookkeeping add on top.

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <CLI/CLI.hpp>

#include "rt/accel/accel.h"

namespace rt::perf {

// Registers the `retrace` subcommand on `app`; the returned function runs it once parsed and
// returns the exit status.
std::function<int()> add_retrace_command(CLI::App& app);

// Every query made through it, forwarded to `inner` and recorded per thread. Thread-safe like any
// Accel. coherent groups keep the grouping intersect_coherent received, so the re-trace traces
// the same packets.
class RecordingAccel final : public Accel {
 public:
  explicit RecordingAccel(const Accel& inner);
  ~RecordingAccel() override;

  Hit intersect(const Ray& ray) const override;
  void intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits) const override;
  bool occluded(const Ray& ray) const override;
  void occluded_coherent(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const override;
  std::string_view name() const override { return inner_.name(); }

  // The queries of all threads, concatenated.
  struct Queries {
    std::vector<Ray> coherent;                 // intersect_coherent rays, group after group
    std::vector<std::uint32_t> group_sizes;    // rays per intersect_coherent call, in order
    std::vector<Ray> closest;                  // intersect rays
    std::vector<Ray> shadow;                   // occluded rays
    std::vector<Ray> coherent_shadow;          // occluded_coherent rays, group after group
    std::vector<std::uint32_t> shadow_group_sizes;
    std::uint64_t total() const { return coherent.size() + closest.size() + shadow.size() + coherent_shadow.size(); }
    std::uint64_t shadow_total() const { return shadow.size() + coherent_shadow.size(); }
  };
  Queries queries() const;

 private:
  struct Logs;
  const Accel& inner_;
  std::unique_ptr<Logs> logs_;
};

// What a re-trace found: hits of the closest-hit queries (coherent + closest) and occluded shadow
// rays, to check against the render's own counts.
struct RetraceCounts {
  std::uint64_t hits = 0, occluded = 0;
  double coherent_s = 0.0, closest_s = 0.0, shadow_s = 0.0;  // wall-clock seconds per kind of query
};

// Traces `queries` through `accel` as the renderer did (coherent groups as packets, the rest one
// by one), in parallel over TBB's threads (or the current task arena's).
RetraceCounts retrace(const Accel& accel, const RecordingAccel::Queries& queries);

}  // namespace rt::perf
