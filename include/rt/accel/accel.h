#pragma once
// The intersection interface shared by the Embree backend and the double-precision reference.
// Both answer the same two queries on the same FlatScene and return the same minimal hit;
// shading data (point, normal, material) is derived from the hit once, in shared code.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string_view>

#include "rt/core/math.h"
#include "rt/flatten/flatten.h"

namespace rt {

inline constexpr float kInfinity = std::numeric_limits<float>::infinity();
inline constexpr std::uint32_t kNoPrimitive = 0xFFFFFFFFu;

// A ray in world space, float32 (exactly what Embree receives). direction need not be unit
// length; t is measured in multiples of it. Valid hits have tnear <= t <= tfar.
struct Ray {
  Vec3f origin{0.0f};
  Vec3f direction{0.0f, 0.0f, -1.0f};
  float tnear = 0.0f;
  float tfar = kInfinity;
};

// Closest hit: ray parameter t and the primitive hit, numbered as FlatScene numbers them (triangles
// first, then spheres). For a triangle, (u, v) are the barycentrics of vertices 1 and 2, so the
// point is (1 - u - v) p0 + u p1 + v p2; for a sphere they are 0. primitive == kNoPrimitive (and
// t == inf) on a miss.
struct Hit {
  float t = kInfinity;
  float u = 0.0f;
  float v = 0.0f;
  std::uint32_t primitive = kNoPrimitive;

  bool found() const { return primitive != kNoPrimitive; }
};

// embree: Embree 3.13 or 4, float32 triangles (see EmbreeKernel). reference: watertight ray/triangle test
// in double precision, brute force. reference_barycentric: the seed's plain barycentric solve in
// double, brute force (kept to show what the watertight formulation buys). Spheres are intersected
// by the same double-precision test (intersect_sphere) in every backend.
enum class AccelKind { embree, reference, reference_barycentric };

enum class EmbreeQuality { low, medium, high };

// Which ray/triangle test runs inside Embree's BVH. native: Embree's own triangle intersector
// (Pluecker in robust mode, Moller-Trumbore otherwise), float32; even in robust mode it can let a
// ray aimed exactly at a vertex slip through a closed mesh (docs/robustness.md). watertight: the
// watertight test of Woop et al. (2013) in float32, eight triangles at a time, with an exact
// recomputation of edge functions that round to zero: no ray slips through a closed mesh, edges
// and vertices included. exact: the reference's double-precision watertight test
// (intersect_triangle_watertight) as an Embree user geometry, so the Embree path returns exactly
// what the reference returns, at the price of speed (docs/performance.md).
enum class EmbreeKernel { native, watertight, exact };

// Options for building an Accel; the reference backends ignore the Embree ones.
class EmbreeDevice;  // rt/accel/embree_accel.h

// Which candidate hits on triangles count, as the intersectors see them: alpha cut-outs and
// see-through surfaces, and back faces that are culled. `triangle` is in FlatScene numbering,
// (b1, b2) are the candidate's barycentrics, and `direction` is the ray's (world space, any
// length), from which a culling test decides whether the ray meets the triangle from behind
// (arrives_from_behind). Implemented by rt/render/surface_test.h; thread-safe.
class SurfaceTest {
 public:
  virtual ~SurfaceTest() = default;
  // True when hits on `triangle` need the test (alpha below 1 somewhere, or culled back faces).
  virtual bool tested(std::uint32_t triangle) const = 0;
  // Closest-hit queries: whether the hit counts (a surface that is there at that point).
  virtual bool hit_counts(std::uint32_t triangle, float b1, float b2, const Vec3d& direction) const = 0;
  // Occlusion (shadow) queries: whether the hit blocks the ray.
  virtual bool blocks(std::uint32_t triangle, float b1, float b2, const Vec3d& direction) const = 0;
};

// Whether a ray along `direction` (world space) meets triangle `triangle` of `flat` from behind:
// against its geometric normal (p1 - p0) x (p2 - p0), computed in double from the float32
// vertices, so that the decision does not depend on the backend that asks.
inline bool arrives_from_behind(const FlatScene& flat, std::uint32_t triangle, const Vec3d& direction) {
  const Vec3u tri = flat.triangles[triangle];
  const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
  return glm::dot(glm::cross(p1 - p0, p2 - p0), direction) > 0.0;
}

struct AccelOptions {
  // RTC_SCENE_FLAG_ROBUST: Embree's watertight (Pluecker) triangle test and conservative box tests.
  // On by default: it removes Embree's misses along shared edges for a few per cent of time (see
  // docs/robustness.md for the measurements that chose this default).
  bool embree_robust = true;
  EmbreeQuality embree_quality = EmbreeQuality::medium;  // BVH build quality (RTCBuildQuality)
  EmbreeKernel embree_kernel = EmbreeKernel::watertight;
  // RTC_SCENE_FLAG_COMPACT from this many triangles on: BVH leaves index the shared vertex buffer
  // instead of copying vertices. On a 10M-triangle mesh it cut peak memory by 40 B/triangle and the
  // build time by half; on the 202k-triangle dragon it traced ~10% slower. The hits are the same
  // up to float rounding: bit-identical on some CPUs, up to 7 ulps in t (and a tie taken by the
  // other triangle) with Embree's AVX2 kernels (tests/test_accel.cpp, docs/robustness.md).
  std::size_t embree_compact_from_triangles = 2'000'000;
  // A device to build in, shared by the accels of a batch (make_embree_device); null: the accel
  // creates its own.
  std::shared_ptr<EmbreeDevice> embree_device;
  // Tested triangles (SurfaceTest::tested): Embree runs filter functions on a geometry of these
  // alone, the reference tests them as it goes. Null: every hit counts; Embree also builds exactly
  // as without a test when no triangle is tested. Must outlive the accel.
  const SurfaceTest* surface_test = nullptr;
};

// Thread-safe after construction: many threads may query one Accel concurrently. A ray with a NaN
// in it hits nothing and is blocked by nothing in every backend (Embree's: also one with a
// coordinate beyond +-1.844e18, which Embree itself would abort on).
class Accel {
 public:
  virtual ~Accel() = default;

  // Closest intersection along the ray within [tnear, tfar]; a miss returns Hit{}. Among
  // primitives hit at the same computed t the lowest index wins, in every backend.
  virtual Hit intersect(const Ray& ray) const = 0;

  // intersect() of every ray, hits[i] for rays[i] (hits.size() >= rays.size()). For rays that start
  // together and point alike, as camera rays of neighbouring pixels do, a backend may trace them
  // as packets; the hits are the same as intersect()'s. This default calls intersect().
  virtual void intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits) const;

  // True when any primitive is hit within [tnear, tfar]. Cheaper than intersect().
  virtual bool occluded(const Ray& ray) const = 0;

  // occluded() of every ray, blocked[i] = 1 or 0 for rays[i], as intersect_coherent does for
  // closest hits (shadow rays of neighbouring pixels towards one light). This default calls occluded().
  virtual void occluded_coherent(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const;

  virtual std::string_view name() const = 0;

  // The surface test this accel was built with (AccelOptions::surface_test), null when none.
  virtual const SurfaceTest* surface_test() const { return nullptr; }
};

// Builds the chosen backend over `scene`, which must outlive the result (Embree shares its
// buffers without copying). Throws RuntimeError if the backend fails.
std::unique_ptr<Accel> build_accel(AccelKind kind, const FlatScene& scene, const AccelOptions& options = {});

// Names as used on the command line: "embree", "reference", "reference-barycentric"; "low",
// "medium", "high"; "native", "watertight". The parse functions throw InputError on anything else.
std::string_view to_string(AccelKind kind);
AccelKind parse_accel_kind(std::string_view name);
std::string_view to_string(EmbreeQuality quality);
EmbreeQuality parse_embree_quality(std::string_view name);
std::string_view to_string(EmbreeKernel kernel);
EmbreeKernel parse_embree_kernel(std::string_view name);

}  // namespace rt
