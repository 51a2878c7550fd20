#pragma once
// Embree backend (Embree 3.13 or 4). This header and embree_accel.cpp are the only places that know Embree exists;
// the Embree headers are included by the .cpp alone.

#include <cstddef>
#include <memory>
#include <string_view>

#include "rt/accel/accel.h"

namespace rt {

// The version of the Embree headers rt was built with, e.g. "4.3.3" (RTC_VERSION_STRING).
std::string_view embree_version();

// An Embree device (RTCDevice: Embree's thread pool and allocators). Several EmbreeAccels may
// use one, one after another (not at the same time), as a batch of renders does; a device's
// creation costs a few milliseconds (docs/render-farm.md).
class EmbreeDevice {
 public:
  EmbreeDevice();  // throws RuntimeError if Embree cannot create a device
  ~EmbreeDevice();
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

 private:
  friend class EmbreeAccel;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// An RTCDevice and one RTCScene holding a single geometry over `scene`'s triangles. With the
// native kernel it is an Embree triangle geometry sharing FlatScene's vertex and index buffers (no
// copies); with the watertight kernel (the default) a user geometry of clusters of up to eight
// triangles (float32 copies of their vertices, about 42 bytes per triangle) tested eight at a time;
// with the exact kernel a user geometry whose callbacks run the reference's double-precision
// watertight test on FlatScene's vertices, so hits equal the reference's exactly.
// Closest hit via rtcIntersect1, shadows via rtcOccluded1. Embree's error callback only records;
// the constructor throws RuntimeError with the recorded message if device creation or the BVH
// build failed.
//
// Embree itself does not say which of several triangles hit at exactly the same t it reports
// (that depends on the BVH layout). intersect() makes it deterministic, lowest index first like
// the reference: an intersection filter (native) or the user callback (watertight) orders
// candidate hits by (t, index).
class EmbreeAccel final : public Accel {
 public:
  EmbreeAccel(const FlatScene& scene, const AccelOptions& options);
  ~EmbreeAccel() override;
  EmbreeAccel(const EmbreeAccel&) = delete;
  EmbreeAccel& operator=(const EmbreeAccel&) = delete;

  Hit intersect(const Ray& ray) const override;
  // Packets of 16 (rtcIntersect16, coherent), ordered per ray like intersect().
  void intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits) const override;
  // Packets of 16 (rtcOccluded16, coherent).
  void occluded_coherent(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const override;
  bool occluded(const Ray& ray) const override;
  const SurfaceTest* surface_test() const override;
  std::string_view name() const override { return "embree"; }

  // Bytes Embree's device holds now (net of frees; the BVH, builder arenas and device state),
  // counted by a memory monitor callback (rtcSetDeviceMemoryMonitorFunction) from device creation
  // on (a shared device: from this accel's creation on), plus the watertight kernel's clusters
  // (copies of their triangles' vertices). FlatScene's vertex and index buffers are shared, not
  // copied, and are not included.
  std::size_t memory_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rt
