#pragma once
// The batch shader's arithmetic over lanes (batch_shade.cpp), in a file of its own so that it can be
// built three times: for baseline x86-64 (SSE2), with AVX2 (batch_lanes_avx2.cpp) and with AVX-512
// (batch_lanes_avx512.cpp: eight lanes a register in surfaces, light and terms), chosen once by
// what the CPU has. Every build computes every lane with the same IEEE operations in the same
// order (lane_math.h), so they give the same bits; tests/test_batch_shade.cpp compares them.

#include <cstdint>
#include <vector>

#include "batch_shade.h"

namespace rt::batch_lanes {

constexpr int kLanes = BatchShader::kLanes;
using Lanes = BatchShader::Lanes;

// A triangle hit's inputs, gathered lane by lane: vertices and vertex normals (float32 widened to
// double, world space), the unit-less ray direction, the barycentrics and the back-face flip.
struct Gathered {
  Gathered() {}  // not zeroed: every lane in use is written
  Vec3Lanes<kLanes> p0, p1, p2, n0, n1, n2, d;
  LaneArray<kLanes> b1, b2;
  alignas(32) std::int64_t flip[kLanes];  // all ones: BackFace::flipped, else 0
};

// Where Kernels::gather reads the lanes' vertices: FlatScene's arrays (world space, float32).
struct VertexArrays {
  const Vec3f* positions = nullptr;
  const Vec3f* normals = nullptr;
  std::size_t count = 0;  // vertices in each
};

// One build of the arithmetic. gather: the vertices and vertex normals of triangles[i] (vertex
// indices), the direction of rays[i] and the barycentrics of hits[i] into `in`, for `count` lanes,
// lanes past it up to a multiple of 4 copying lane 0 (so that no uninitialised value enters the
// arithmetic); four lanes at a time, by 16-byte loads and transposes. surfaces:
// make_surface_point, the shading normal (interpolated, unit, flipped towards the viewer on a
// two-sided back face), the unit direction and the reflection ray of block.count lanes. light:
// one light's direction, unshadowed intensity, n.l, n.h, geometric cosine and shadow ray
// (shade_surface's, before the pow of the highlight). terms: the light's term, intensity (ambient
// + diffuse n.l + specular pow(n.h, s)), the highlight zero where it is skipped.
struct Kernels {
  void (*gather)(const VertexArrays& vertices, const Vec3u* triangles, const Ray* rays, const Hit* hits, int count,
                 Gathered& in);
  void (*surfaces)(const Gathered& in, const OriginPolicy& policy, Lanes& block);
  void (*light)(const LightLanes& light, const OriginPolicy& policy, const Lanes& block, Lanes::Light& out,
                Vec3Lanes<kLanes>& intensity, LaneArray<kLanes>& n_dot_l, LaneArray<kLanes>& n_dot_h);
  void (*terms)(const Lanes& block, const Vec3Lanes<kLanes>& intensity, const LaneArray<kLanes>& n_dot_l,
                const LaneArray<kLanes>& power, Lanes::Light& out);
};

// The baseline build, the AVX2 one (nullptr when the CPU lacks AVX2) and the AVX-512 one (nullptr
// when the CPU lacks AVX-512 F, DQ or VL).
const Kernels& baseline_kernels();
const Kernels* avx2_kernels();
const Kernels* avx512_kernels();
// The builds beyond the baseline that this CPU can run (for tests that compare builds).
std::vector<const Kernels*> wider_kernels();
// The widest build the CPU has: AVX-512, else AVX2, else the baseline.
const Kernels& best_kernels();

}  // namespace rt::batch_lanes
