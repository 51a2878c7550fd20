#pragma once
// Shared machinery of the numerical-robustness tests (test_numerics_*.cpp, test_crosscheck.cpp):
// closed test meshes, their world-space placements, the intersector configurations compared, and
// a deterministic multi-threaded loop for the long runs.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"

namespace rt_numerics {

using rt::Vec3d;
using rt::Vec3f;
using rt::Vec3u;

// Where a test puts its objects: translated by `offset`, sized by `scale` (world units), named
// for the printed tables. Far from the origin float32 spacing grows, which is what the tests probe.
struct Placement {
  const char* name;
  Vec3d offset;
  double scale;
};

// Unit roundoff of float32.
inline constexpr double kFloatRoundoff = 0x1p-24;

// ---------------------------------------------------------------------------------------------
// Closed meshes in object space, double precision, every vertex shared by all its triangles.

struct MeshD {
  std::vector<Vec3d> positions;
  std::vector<Vec3u> triangles;  // counter-clockwise seen from outside
};

// UV sphere around the origin with single-vertex poles on +-y and no seam duplicates: vertex j of
// every ring is shared by the triangles on both sides of it, and the last column wraps to the
// first. Every vertex gets its own radius, uniform in [r_min, r_max] (seeded). Star-shaped with
// respect to the origin: each triangle's spherical projection is a cell of the UV tessellation.
// Triangle count: 2 * slices * (stacks - 1).
inline MeshD jittered_uv_sphere(int slices, int stacks, double r_min, double r_max, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> radius(r_min, r_max);
  MeshD mesh;
  const double pi = 3.14159265358979323846;
  mesh.positions.push_back(radius(rng) * Vec3d(0, 1, 0));  // north pole, index 0
  for (int i = 1; i < stacks; ++i) {
    const double theta = pi * i / stacks;
    for (int j = 0; j < slices; ++j) {
      const double phi = 2.0 * pi * j / slices;
      const Vec3d unit(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
      mesh.positions.push_back(radius(rng) * unit);
    }
  }
  mesh.positions.push_back(radius(rng) * Vec3d(0, -1, 0));  // south pole
  const auto south = static_cast<unsigned>(mesh.positions.size() - 1);
  auto ring = [&](int i, int j) { return static_cast<unsigned>(1 + (i - 1) * slices + (j % slices)); };
  for (int j = 0; j < slices; ++j) mesh.triangles.push_back({0u, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i + 1 < stacks; ++i)
    for (int j = 0; j < slices; ++j) {
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < slices; ++j) mesh.triangles.push_back({south, ring(stacks - 1, j + 1), ring(stacks - 1, j)});
  return mesh;
}

// Icosahedron with each face split into 4^subdivisions triangles, new vertices (shared through an
// edge-keyed cache) pushed out to the unit sphere. 20 * 4^subdivisions triangles.
inline MeshD icosphere(int subdivisions) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  MeshD mesh;
  for (const Vec3d& v : {Vec3d(-1, g, 0), Vec3d(1, g, 0), Vec3d(-1, -g, 0), Vec3d(1, -g, 0), Vec3d(0, -1, g),
                         Vec3d(0, 1, g), Vec3d(0, -1, -g), Vec3d(0, 1, -g), Vec3d(g, 0, -1), Vec3d(g, 0, 1),
                         Vec3d(-g, 0, -1), Vec3d(-g, 0, 1)})
    mesh.positions.push_back(glm::normalize(v));
  mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                    {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<unsigned, unsigned>, unsigned> midpoints;
    auto midpoint = [&](unsigned a, unsigned b) {
      const auto key = std::minmax(a, b);
      const auto found = midpoints.find(key);
      if (found != midpoints.end()) return found->second;
      mesh.positions.push_back(glm::normalize(mesh.positions[a] + mesh.positions[b]));
      const auto index = static_cast<unsigned>(mesh.positions.size() - 1);
      midpoints.emplace(key, index);
      return index;
    };
    std::vector<Vec3u> finer;
    for (const Vec3u& t : mesh.triangles) {
      const unsigned ab = midpoint(t.x, t.y), bc = midpoint(t.y, t.z), ca = midpoint(t.z, t.x);
      finer.insert(finer.end(), {{t.x, ab, ca}, {t.y, bc, ab}, {t.z, ca, bc}, {ab, bc, ca}});
    }
    mesh.triangles = std::move(finer);
  }
  return mesh;
}

// The cube [-1, 1]^3, each face an n x n grid of quads (two triangles each). Vertices are the
// lattice points (-1 + 2i/n, ...) on the surface, one per point, so the edges and corners of the
// cube are shared between faces. 12 n^2 triangles.
inline MeshD cube_grid(int n) {
  MeshD mesh;
  std::map<std::array<int, 3>, unsigned> index;
  auto vertex = [&](std::array<int, 3> lattice) {
    const auto found = index.find(lattice);
    if (found != index.end()) return found->second;
    mesh.positions.push_back(Vec3d(-1.0 + 2.0 * lattice[0] / n, -1.0 + 2.0 * lattice[1] / n, -1.0 + 2.0 * lattice[2] / n));
    const auto i = static_cast<unsigned>(mesh.positions.size() - 1);
    index.emplace(lattice, i);
    return i;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // (a, b, axis) is right-handed
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          auto at = [&](int di, int dj) {
            std::array<int, 3> l{};
            l[axis] = side * n;
            l[a] = i + di;
            l[b] = j + dj;
            return vertex(l);
          };
          const unsigned v00 = at(0, 0), v10 = at(1, 0), v11 = at(1, 1), v01 = at(0, 1);
          // a x b = +axis: counter-clockwise (outward) on the + side, reversed on the - side.
          if (side == 1) {
            mesh.triangles.push_back({v00, v10, v11});
            mesh.triangles.push_back({v00, v11, v01});
          } else {
            mesh.triangles.push_back({v00, v11, v10});
            mesh.triangles.push_back({v00, v01, v11});
          }
        }
    }
  return mesh;
}

// Lower bound of the distance from the origin to the mesh surface: the smallest distance from the
// origin to a triangle's plane. For a mesh that is star-shaped about the origin (all three above)
// the ball of this radius is inside it.
inline double inradius(const MeshD& mesh) {
  double r = 1e300;
  for (const Vec3u& t : mesh.triangles) {
    const Vec3d p0 = mesh.positions[t.x], p1 = mesh.positions[t.y], p2 = mesh.positions[t.z];
    const Vec3d n = glm::normalize(glm::cross(p1 - p0, p2 - p0));
    r = std::min(r, std::abs(glm::dot(n, p0)));
  }
  return r;
}

// World-space float32 buffers: every position is offset + scale * p, computed in double and
// rounded to float32 once. Shared vertices stay shared, so a closed mesh stays closed. Normals
// are unused by the intersectors and set to +z. One spare position of capacity for Embree.
inline rt::FlatScene place(const MeshD& mesh, const Vec3d& offset, double scale) {
  rt::FlatScene flat;
  flat.positions.reserve(mesh.positions.size() + 1);
  for (const Vec3d& p : mesh.positions) flat.positions.push_back(Vec3f(offset + scale * p));
  flat.normals.assign(flat.positions.size(), Vec3f(0, 0, 1));
  flat.triangles = mesh.triangles;
  flat.material_ids.assign(flat.triangles.size(), 0u);
  return flat;
}

// A FlatScene holding exactly the given float32 triangles, unshared vertices, no filtering (the
// degenerate-input tests need zero-area triangles to reach the intersectors).
inline rt::FlatScene flat_soup(const std::vector<std::array<Vec3f, 3>>& corners) {
  rt::FlatScene flat;
  flat.positions.reserve(3 * corners.size() + 1);
  for (const auto& c : corners) {
    const auto base = static_cast<unsigned>(flat.positions.size());
    for (const Vec3f& p : c) flat.positions.push_back(p);
    flat.triangles.push_back({base, base + 1, base + 2});
  }
  flat.normals.assign(flat.positions.size(), Vec3f(0, 0, 1));
  flat.material_ids.assign(flat.triangles.size(), 0u);
  return flat;
}

// Triangles of zero area in float32 (the test flatten_scene applies).
inline std::size_t zero_area_triangles(const rt::FlatScene& flat) {
  std::size_t count = 0;
  for (const Vec3u& t : flat.triangles) {
    const Vec3d p0(flat.positions[t.x]), p1(flat.positions[t.y]), p2(flat.positions[t.z]);
    if (glm::cross(p1 - p0, p2 - p0) == Vec3d(0.0)) ++count;
  }
  return count;
}

// ---------------------------------------------------------------------------------------------
// Intersector configurations.

// embree_robust and embree_default: Embree's native triangle test with RTC_SCENE_FLAG_ROBUST on and
// off; embree_watertight and embree_exact: the kernels of those names (the float32 watertight test
// in clusters; the reference's own test inside Embree's BVH); rt_default: AccelOptions{} as rt
// render builds it, whatever the defaults are: the path whose watertightness the suite asserts.
enum class Path { reference, reference_barycentric, embree_robust, embree_default, embree_watertight, embree_exact, rt_default };

inline const char* name(Path path) {
  switch (path) {
    case Path::reference: return "reference (watertight)";
    case Path::reference_barycentric: return "reference-barycentric (seed solve)";
    case Path::embree_robust: return "Embree robust";
    case Path::embree_default: return "Embree default (robust off)";
    case Path::embree_watertight: return "Embree + watertight kernel (float32)";
    case Path::embree_exact: return "Embree + exact kernel (reference test)";
    case Path::rt_default: return "rt default (AccelOptions{})";
  }
  return "?";
}

inline std::unique_ptr<rt::Accel> build(Path path, const rt::FlatScene& flat) {
  rt::AccelOptions options;
  switch (path) {
    case Path::reference: return rt::build_accel(rt::AccelKind::reference, flat);
    case Path::reference_barycentric: return rt::build_accel(rt::AccelKind::reference_barycentric, flat);
    case Path::embree_robust:
    case Path::embree_default:
      options.embree_kernel = rt::EmbreeKernel::native;
      options.embree_robust = path == Path::embree_robust;
      return rt::build_accel(rt::AccelKind::embree, flat, options);
    case Path::embree_watertight:
    case Path::embree_exact:
      options.embree_kernel = path == Path::embree_watertight ? rt::EmbreeKernel::watertight : rt::EmbreeKernel::exact;
      return rt::build_accel(rt::AccelKind::embree, flat, options);
    case Path::rt_default: return rt::build_accel(rt::AccelKind::embree, flat, rt::AccelOptions{});
  }
  return nullptr;
}

// ---------------------------------------------------------------------------------------------
// Random sampling.

inline Vec3d random_unit_vector(std::mt19937& rng) {
  std::uniform_real_distribution<double> symmetric(-1.0, 1.0);
  for (;;) {
    const Vec3d v(symmetric(rng), symmetric(rng), symmetric(rng));
    const double length = glm::length(v);
    if (length > 1e-3 && length <= 1.0) return v / length;
  }
}

inline Vec3d random_in_ball(std::mt19937& rng, double radius) {
  std::uniform_real_distribution<double> symmetric(-1.0, 1.0);
  for (;;) {
    const Vec3d v(symmetric(rng), symmetric(rng), symmetric(rng));
    if (glm::length(v) <= 1.0) return radius * v;
  }
}

// Uniform point (barycentrics b1, b2) on a triangle.
inline std::pair<double, double> random_barycentrics(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double b1 = unit(rng), b2 = unit(rng);
  if (b1 + b2 > 1.0) {
    b1 = 1.0 - b1;
    b2 = 1.0 - b2;
  }
  return {b1, b2};
}

// ---------------------------------------------------------------------------------------------
// Runs body(chunk) for chunk = 0 .. chunks-1 on all hardware threads and adds the results in chunk
// order. Each chunk seeds its own generator from a literal base and its index, so the result does
// not depend on the thread count.
template <class Result, class Body>
Result parallel_chunks(std::size_t chunks, Body body) {
  std::vector<Result> results(chunks);
  const std::size_t threads = std::max<std::size_t>(1, std::min<std::size_t>(chunks, std::thread::hardware_concurrency()));
  std::vector<std::thread> workers;
  for (std::size_t w = 0; w < threads; ++w)
    workers.emplace_back([&, w] {
      for (std::size_t c = w; c < chunks; c += threads) results[c] = body(c);
    });
  for (std::thread& worker : workers) worker.join();
  Result total{};
  for (const Result& r : results) total += r;
  return total;
}

}  // namespace rt_numerics
