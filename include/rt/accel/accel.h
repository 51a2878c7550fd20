#pragma once
// The intersection interface shared by the Embree backend and the double-precision reference.
// Both answer the same two queries on the same FlatScene and return the same minimal hit;
// shading data (point, normal, material) is derived from the hit once, in shared code.

#include <cstdint>
#include <limits>
#include <memory>
#include <string_view>

#include "rt/core/math.h"
#include "rt/flatten/flatten.h"

namespace rt {

inline constexpr float kInfinity = std::numeric_limits<float>::infinity();
inline constexpr std::uint32_t kNoTriangle = 0xFFFFFFFFu;

// A ray in world space, float32 (exactly what Embree receives). direction need not be unit
// length; t is measured in multiples of it. Valid hits have tnear <= t <= tfar.
struct Ray {
  Vec3f origin{0.0f};
  Vec3f direction{0.0f, 0.0f, -1.0f};
  float tnear = 0.0f;
  float tfar = kInfinity;
};

// Closest hit: ray parameter t and barycentrics (u, v) of triangle vertices 1 and 2, so the
// point is (1 - u - v) p0 + u p1 + v p2. triangle == kNoTriangle (and t == inf) on a miss.
struct Hit {
  float t = kInfinity;
  float u = 0.0f;
  float v = 0.0f;
  std::uint32_t triangle = kNoTriangle;

  bool found() const { return triangle != kNoTriangle; }
};

enum class AccelKind { embree, reference };

// Thread-safe after construction: many threads may query one Accel concurrently.
class Accel {
 public:
  virtual ~Accel() = default;

  // Closest intersection along the ray within [tnear, tfar]; a miss returns Hit{}.
  // Ties in t go to the lowest triangle index in the reference; Embree gives no such promise.
  virtual Hit intersect(const Ray& ray) const = 0;

  // True when any triangle is hit within [tnear, tfar]. Cheaper than intersect().
  virtual bool occluded(const Ray& ray) const = 0;

  virtual std::string_view name() const = 0;
};

// Builds the chosen backend over `scene`, which must outlive the result (Embree shares its
// buffers without copying). Throws RuntimeError if the backend fails.
std::unique_ptr<Accel> build_accel(AccelKind kind, const FlatScene& scene);

// "embree" / "reference"; parse_accel_kind throws InputError on anything else.
std::string_view to_string(AccelKind kind);
AccelKind parse_accel_kind(std::string_view name);

}  // namespace rt
