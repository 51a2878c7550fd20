#include "rt/scene/shapes.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include "rt/core/error.h"

namespace rt {

TriangleMesh make_cube_mesh() {
  // Each face: outward normal and two in-plane axes with axis_a x axis_b == normal, so the
  // corners below run counter-clockwise seen from outside.
  struct Face {
    Vec3f normal, axis_a, axis_b;
  };
  const Face faces[6] = {
      {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},  {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
      {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}},  {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}},
      {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}},  {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}},
  };
  TriangleMesh mesh;
  for (const Face& face : faces) {
    const auto base = static_cast<unsigned>(mesh.positions.size());
    const float corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (const auto& c : corners) {
      mesh.positions.push_back(0.5f * (face.normal + c[0] * face.axis_a + c[1] * face.axis_b));
      mesh.normals.push_back(face.normal);
    }
    mesh.triangles.push_back({base, base + 1, base + 2});
    mesh.triangles.push_back({base, base + 2, base + 3});
  }
  return mesh;
}

TriangleMesh make_sphere_mesh(double radius, int slices, int stacks) {
  if (slices < 3 || stacks < 2) throw InputError("sphere tessellation needs slices >= 3 and stacks >= 2");
  TriangleMesh mesh;
  // Rings from the north pole (+y) to the south pole; each ring repeats its first vertex so
  // that the seam needs no index wrap-around.
  for (int s = 0; s <= stacks; ++s) {
    const double theta = std::numbers::pi * s / stacks;  // polar angle from +y
    for (int k = 0; k <= slices; ++k) {
      const double phi = 2.0 * std::numbers::pi * k / slices;
      const Vec3d n{std::sin(theta) * std::sin(phi), std::cos(theta), std::sin(theta) * std::cos(phi)};
      mesh.positions.push_back(Vec3f(radius * n));
      mesh.normals.push_back(Vec3f(n));
    }
  }
  const auto row = static_cast<unsigned>(slices + 1);
  for (int s = 0; s < stacks; ++s) {
    for (int k = 0; k < slices; ++k) {
      const unsigned a = s * row + k, b = a + row;  // a on this ring, b below it
      if (s != 0) mesh.triangles.push_back({a, b, a + 1});                // skip the pole's zero-area cap
      if (s != stacks - 1) mesh.triangles.push_back({a + 1, b, b + 1});
    }
  }
  return mesh;
}

void compute_vertex_normals(TriangleMesh& mesh) {
  // A triangle's three angle-weighted contributions depend on it alone, so they are computed in
  // parallel, a block of triangles at a time, while the previous block's are summed; each vertex
  // sums its contributions serially in triangle order, the order of the original serial loop, so
  // the result is the same bit for bit on any number of threads. A skipped corner contributes +0,
  // which leaves a sum unchanged (a sum starting at +0 never becomes -0).
  constexpr std::size_t kBlock = std::size_t(1) << 14;  // triangles: 1.1 MiB of contributions
  const std::size_t triangle_count = mesh.triangles.size();
  std::vector<Vec3d> sums(mesh.positions.size(), Vec3d(0.0));
  std::vector<Vec3d> contributions[2];
  for (std::vector<Vec3d>& buffer : contributions) buffer.resize(3 * std::min(kBlock, triangle_count));
  auto contribute = [&](std::size_t first, std::vector<Vec3d>& out) {
    const std::size_t count = std::min(kBlock, triangle_count - first);
    using Range = tbb::blocked_range<std::size_t>;
    tbb::parallel_for(Range(0, count, 1024), [&](const Range& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        const Vec3u& tri = mesh.triangles[first + i];
        const Vec3d p[3] = {Vec3d(mesh.positions[tri[0]]), Vec3d(mesh.positions[tri[1]]),
                            Vec3d(mesh.positions[tri[2]])};
        Vec3d* const corner = &out[3 * i];
        corner[0] = corner[1] = corner[2] = Vec3d(0.0);
        const Vec3d face = glm::cross(p[1] - p[0], p[2] - p[0]);
        const double length = glm::length(face);
        if (!(length > 0.0)) continue;
        const Vec3d unit_face = face / length;
        // |p[k+1] - p[k]| for k = 0, 1, 2; |p[k] - p[j]| == |p[j] - p[k]| exactly (negation is exact).
        const double edge[3] = {glm::length(p[1] - p[0]), glm::length(p[2] - p[1]), glm::length(p[0] - p[2])};
        for (int k = 0; k < 3; ++k) {
          const Vec3d e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
          const double l1 = edge[k], l2 = edge[(k + 2) % 3];
          if (!(l1 > 0.0 && l2 > 0.0)) continue;
          const double angle = std::acos(std::clamp(glm::dot(e1, e2) / (l1 * l2), -1.0, 1.0));
          corner[k] = angle * unit_face;
        }
      }
    });
  };
  if (triangle_count > 0) contribute(0, contributions[0]);
  for (std::size_t first = 0, block = 0; first < triangle_count; first += kBlock, ++block) {
    tbb::task_group next;
    if (first + kBlock < triangle_count)
      next.run([&, first, block] { contribute(first + kBlock, contributions[(block + 1) % 2]); });
    const std::vector<Vec3d>& in = contributions[block % 2];
    const std::size_t count = std::min(kBlock, triangle_count - first);
    for (std::size_t i = 0; i < count; ++i)
      for (int k = 0; k < 3; ++k) sums[mesh.triangles[first + i][k]] += in[3 * i + k];
    next.wait();
  }
  mesh.normals.resize(mesh.positions.size());
  using Range = tbb::blocked_range<std::size_t>;
  tbb::parallel_for(Range(0, sums.size(), 4096), [&](const Range& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const double length = glm::length(sums[i]);
      mesh.normals[i] = length > 0.0 ? Vec3f(sums[i] / length) : Vec3f(0.0f, 0.0f, 1.0f);
    }
  });
}

}  // namespace rt
