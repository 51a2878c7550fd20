#pragma once
// EmitterSampler::sample_many's arithmetic over lanes (area_lights.cpp): Arvo's spherical warp (its
// sine and cosine from lane_libm.h, as SphericalTriangle::sample takes them), the barycentrics
// where the direction meets the triangle, the sample's surface point and its direction and
// distance from the shading point. World space, double. Built twice, like batch_lanes.cpp:
// baseline x86-64 and AVX2 (light_sample_lanes_avx2.cpp), chosen once by what the CPU has; each
// lane takes the scalar code's IEEE operations in the same order, so both builds give
// SphericalTriangle::sample's, barycentrics_along's and make_surface_point's bits.

#include <cstdint>

#include "batch_shade.h"

namespace rt::light_sample_lanes {

constexpr int kLanes = 16;  // samples per call at most; a multiple of 4
using Lanes = LaneArray<kLanes>;
using Vec3 = Vec3Lanes<kLanes>;

// Per lane: the sample's emitter triangle and how it is drawn (gathered by EmitterSampler).
struct Input {
  Input() {}  // not zeroed: every lane in use is written
  double point[3];  // the shading point, the same for every lane
  // Arvo's warp (SphericalTriangle's members): the angle u.x * area - alpha (radians), the second
  // sample coordinate, the angle at A's cosine and sine, cos of side AB, and the unit vectors A, B
  // and C's part orthogonal to A. Read only where by_solid_angle.
  Lanes angle, v, cos_alpha, sin_alpha, cos_c;
  Vec3 a, b, c_perp;
  // The triangle (p0, p1, p2) and make_triangle_frame's edge term.
  Vec3 p0, p1, p2;
  Lanes edge_term;
  // Where !by_solid_angle: the barycentrics b1, b2 of the point (sample_triangle_uniform).
  Lanes b1, b2;
  alignas(32) std::int64_t by_solid_angle[kLanes];  // all ones or 0
};

// Per lane: the sample's barycentrics b1, b2, surface point and error bound (make_surface_point),
// its unit direction and distance from the shading point, and whether it has one (valid: the
// direction met the triangle's plane and the point is not the shading point).
struct Output {
  Output() {}
  Vec3 point, direction;
  Lanes b1, b2, error_bound, distance;
  alignas(32) std::int64_t valid[kLanes];  // all ones or 0
};

// SphericalTriangle's set-up (sampling.cpp) for four triangles (a, b, c) seen from one point, one
// per lane: the unit directions A and B, C's part orthogonal to A (unit), the angle at A (radians)
// with its cosine and sine, the cosine of side AB and the area (steradians). A lane whose triangle
// has none (a vertex at the point, the point on a side's line, no positive area) is all zeros.
struct SphericalInput {
  SphericalInput() {}
  double point[3];
  Vec3Lanes<4> a, b, c;
};
struct SphericalOutput {
  SphericalOutput() {}
  Vec3Lanes<4> a, b, c_perp;
  LaneArray<4> alpha, cos_alpha, sin_alpha, cos_c, area;
};

// The Blinn-Phong factors of a chunk of light samples seen from one shading point (shade.cpp's
// area-light terms; world space): per lane n.l = normal . direction and, where `needed` and
// n.l > 0, the highlight max(n.h, 0)^shininess, h the normalised direction + to_eye (elsewhere 1),
// with shade.cpp's operations in its order.
struct FacingInput {
  FacingInput() {}
  double normal[3], to_eye[3];  // unit
  double shininess;
  bool highlights = true;  // false: no lane needs its highlight (all powers 1)
  Vec3 direction;          // unit
  alignas(32) std::int64_t needed[kLanes];  // all ones or 0
};
struct FacingOutput {
  FacingOutput() {}
  Lanes n_dot_l, power;
};

// One build of the lanes: `sample` computes `count` lanes (<= kLanes) of `in` into `out`;
// `powers` sets out[k] = pow(x[k], y) for k < kLanes (lane_libm.h's pow: within 1 ulp of glibc's,
// the same bits in both builds); `spherical` sets up four spherical triangles; `facing` computes
// the n.l and highlights of a chunk of samples.
struct Kernels {
  void (*sample)(const Input& in, int count, Output& out);
  void (*powers)(const double* x, double y, double* out);
  void (*spherical)(const SphericalInput& in, SphericalOutput& out);
  void (*facing)(const FacingInput& in, FacingOutput& out);
};

const Kernels& baseline_kernels();
const Kernels* avx2_kernels();  // nullptr when the CPU lacks AVX2
// The AVX2 build where the CPU has it, else the baseline.
const Kernels& best_kernels();

}  // namespace rt::light_sample_lanes
