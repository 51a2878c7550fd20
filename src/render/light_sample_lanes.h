#pragma once
// The area-light terms' arithmetic over lanes, a chunk of up to 16 light samples of one emitter
// seen from one shading point at a time (area_lights.cpp draws them, shade.cpp uses them): Arvo's
// spherical warp (its sine and cosine from lane_libm.h, as SphericalTriangle::sample takes them),
// the barycentrics where the direction meets the triangle, the sample's surface point, direction,
// distance and emitted radiance over pdf; then the Blinn-Phong factors, the terms and the shadow
// rays. World space, double (the rays float32). Built three times: baseline x86-64, AVX2
// (light_sample_lanes_avx2.cpp, like batch_lanes.cpp) and AVX-512 (light_sample_lanes_avx512.cpp,
// eight lanes a register in the sample kernel), chosen once by what the CPU has; each lane takes
// the scalar code's IEEE operations in the same order, so every build gives
// EmitterSampler::sample's, shade.cpp's and shadow_ray_to_sample's bits.

#include <cstdint>
#include <vector>

#include "batch_shade.h"

namespace rt::light_sample_lanes {

constexpr int kLanes = 16;  // samples per call at most; a multiple of 4
using Lanes = LaneArray<kLanes>;
using Vec3 = Vec3Lanes<kLanes>;

// A chunk's samples as EmitterSampler gathers them. The per-sample fields have one entry per lane.
// The per-triangle fields (Arvo's warp set-up, the triangle, its weights) have one per lane too
// when slots == 0; when the emitter has at most kSlots triangles, slots is their number, entry s
// is triangle s's and each lane reads the entry of its `slot` (gathered once, not per sample).
struct Input {
  Input() {}  // not zeroed: every lane and slot in use is written
  static constexpr int kSlots = 4;
  int slots = 0;
  Lanes slot;  // where slots > 0: the lane's triangle (0 .. slots - 1)
  double point[3];  // the shading point, the same for every lane
  // Per sample: Arvo's angle u.x * area - alpha (radians) and second sample coordinate, read only
  // where by_solid_angle; elsewhere the barycentrics b1, b2 of the point (sample_triangle_uniform).
  Lanes angle, v, b1, b2;
  alignas(32) std::int64_t by_solid_angle[kLanes];  // all ones or 0
  // Per triangle: the rest of the warp (SphericalTriangle's members: the angle at A's cosine and
  // sine, cos of side AB, and the unit vectors A, B and C's part orthogonal to A), read only where
  // by_solid_angle; the triangle (p0, p1, p2) and make_triangle_frame's edge term; and
  // EmitterSampler::weigh's inputs: the triangle's unit normal (its front side), area (scene
  // units^2) and probability, and where by_solid_angle the emission over pdf (View's).
  Lanes cos_alpha, sin_alpha, cos_c;
  Vec3 a, b, c_perp;
  Vec3 p0, p1, p2;
  Lanes edge_term;
  Vec3 normal;
  Lanes area, probability;
  Vec3 solid_radiance;
  double emission[3];  // the emitter's emission (linear RGB), the same in every lane
  // Kernels::choose's inputs, where every slot is sampled by solid angle: per lane the sample's
  // point u = (ux, uy) in [0, 1)^2; per slot the power cdf's interval [low, high) and the
  // spherical triangle's area (steradians) and angle at A (radians).
  Lanes ux, uy;
  Lanes low, high, solid_area, alpha;
};

// Per lane: the sample's barycentrics b1, b2, surface point and error bound (make_surface_point),
// its unit direction and distance from the shading point, and whether it has one (valid: the
// direction met the triangle's plane and the point is not the shading point); where valid, its
// emitted radiance over pdf (LightSample's, zero where the triangle's back faces the point) and
// whether the front does; the triangle's normal.
struct Output {
  Output() {}
  Vec3 point, direction, normal;
  Lanes b1, b2, error_bound, distance;
  alignas(32) std::int64_t valid[kLanes];  // all ones or 0
  Vec3 radiance_over_pdf;
  alignas(32) std::int64_t front[kLanes];  // all ones or 0
};

// A chunk of light samples of one emitter seen from one point, in lanes: what
// EmitterSampler::draw gathers and the sample kernel computes.
struct Chunk {
  Chunk() {}
  int count = 0;  // lanes in use
  Input in;
  Output out;
  std::uint32_t triangle[kLanes];  // index into Emitter::triangles
  double b0[kLanes];  // the barycentric of p0 (1 - b1 - b2, or sample_triangle_uniform's)
};

// SphericalTriangle's set-up (sampling.cpp) for four triangles (a, b, c), each seen from its own
// point, one per lane: the unit directions A and B, C's part orthogonal to A (unit), the angle at A
// (radians) with its cosine and sine, the cosine of side AB and the area (steradians). A lane whose
// triangle has none (a vertex at the point, the point on a side's line, no positive area) is all
// zeros. Each lane's results depend on its own inputs only.
struct SphericalInput {
  SphericalInput() {}
  Vec3Lanes<4> point, a, b, c;
};
struct SphericalOutput {
  SphericalOutput() {}
  Vec3Lanes<4> a, b, c_perp;
  LaneArray<4> alpha, cos_alpha, sin_alpha, cos_c, area;
};

// What the area-light terms read of the shading point (shade.cpp; world space, double): the
// Blinn-Phong inputs, the surface (SurfacePoint's point, geometric normal and error bound), the
// ray offset policy and the shadow rays' origins on either side (float32, set_origins').
struct Shading {
  Shading() {}
  double normal[3], to_eye[3];  // shading normal, unit; towards the ray's origin, unit
  double point[3], geometric_normal[3], error_bound = 0.0;
  double diffuse[3], specular[3];  // C_d (texture applied) and C_s
  double shininess = 0.0;
  double scale = 0.0;  // 1 / (pi N), N samples per hit
  bool highlights = true;  // the specular term is evaluated
  float origin[2][3];  // leaving on the geometric normal's side ([0], n . direction >= 0) or the other ([1])
  bool fixed_offset = false;  // RayOffset::Mode::fixed, by `epsilon` world units
  double epsilon = 0.0;
};

// Per lane of a chunk: n.l = normal . direction and, where valid and n.l > 0, the highlight
// max(n.h, 0)^shininess, h the normalised direction + to_eye (elsewhere, or without highlights, 1),
// with shade.cpp's scalar operations in its order.
struct FacingOutput {
  FacingOutput() {}
  Lanes n_dot_l, power;
};

// Per lane of a chunk: the sample's term L / pdf (C_d n.l + C_s power) / (pi N) (zero where n.l <= 0
// or `lit` is false) and its shadow ray (shadow_ray_to_sample from the origin on the side the
// direction leaves by; tfar <= 0: nothing can be in between).
struct EmitOutput {
  EmitOutput() {}
  Vec3 term;
  Vec3fLanes<kLanes> origin, direction;
  alignas(64) float tfar[kLanes];
};

// One build of the lanes: `choose` makes EmitterSampler::choose's choice for `count` lanes of `in`
// (slots > 0, every slot by solid angle: see Input) and the warp's inputs, bit for bit: the lane's
// slot (the triangle: triangle[k]), angle ux * area - alpha, v uy rescaled to the slot's interval,
// by_solid_angle set (b1, b2 zero: read but not used); `sample` computes `count` lanes (<= kLanes)
// of `in` into `out`;
// `powers` sets out[k] = pow(x[k], y) for k < kLanes (lane_libm.h: binary powering for a whole y up
// to kMaxIntegerPower, within (y - 1) 2^-53 relative; else its pow, within 1 ulp of glibc's; the
// same bits in both builds); `spherical` sets up four spherical triangles; `facing` computes
// the n.l and highlights of a chunk's lanes in use, `emit` their terms (with `lit`) and shadow rays.
struct Kernels {
  void (*choose)(Input& in, int count, std::uint32_t* triangle);
  void (*sample)(const Input& in, int count, Output& out);
  void (*powers)(const double* x, double y, double* out);
  void (*spherical)(const SphericalInput& in, SphericalOutput& out);
  void (*facing)(const Shading& shading, const Chunk& chunk, FacingOutput& out);
  void (*emit)(const Shading& shading, const Chunk& chunk, const FacingOutput& facing, bool lit, EmitOutput& out);
  // shading.origin[s] = offset_ray_origin(policy, surface, s == 0 ? n : -n), n the geometric normal.
  void (*set_origins)(Shading& shading);
};

const Kernels& baseline_kernels();
const Kernels* avx2_kernels();    // nullptr when the CPU lacks AVX2
const Kernels* avx512_kernels();  // nullptr when the CPU lacks AVX-512 F, DQ or VL
// The builds beyond the baseline that this CPU can run (for tests that compare builds).
std::vector<const Kernels*> wider_kernels();
// The widest build the CPU has: AVX-512, else AVX2, else the baseline.
const Kernels& best_kernels();

}  // namespace rt::light_sample_lanes
