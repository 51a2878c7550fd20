#include "rt/scene/tangents.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace rt {

namespace {

// A vertex's identity for welding: the bit patterns of its position, normal and texcoords.
struct VertexKey {
  std::uint32_t bits[8];
  bool operator==(const VertexKey& other) const { return std::equal(bits, bits + 8, other.bits); }
};

struct VertexKeyHash {
  std::size_t operator()(const VertexKey& key) const {
    std::uint64_t h = 0x9E3779B97F4A7C15ull;
    for (const std::uint32_t b : key.bits) h = (h ^ b) * 0x100000001B3ull;
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};

VertexKey key_of(const TriangleMesh& mesh, std::uint32_t v) {
  const Vec3f& p = mesh.positions[v];
  const Vec3f& n = mesh.normals[v];
  const Vec2f& t = mesh.texcoords[v];
  return {{std::bit_cast<std::uint32_t>(p.x), std::bit_cast<std::uint32_t>(p.y), std::bit_cast<std::uint32_t>(p.z),
           std::bit_cast<std::uint32_t>(n.x), std::bit_cast<std::uint32_t>(n.y), std::bit_cast<std::uint32_t>(n.z),
           std::bit_cast<std::uint32_t>(t.x), std::bit_cast<std::uint32_t>(t.y)}};
}

// `v` without its component along unit `n`, normalised; zero when nothing is left.
Vec3d project_to_plane(const Vec3d& v, const Vec3d& n) {
  const Vec3d p = v - n * glm::dot(n, v);
  const double length = glm::length(p);
  return length > 0.0 && std::isfinite(length) ? p / length : Vec3d(0.0);
}

// Any unit vector perpendicular to unit `n` (for vertices whose triangles give no tangent).
Vec3d any_perpendicular(const Vec3d& n) {
  const Vec3d axis = std::abs(n.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
  return project_to_plane(axis, n);
}

}  // namespace

std::size_t generate_tangents(TriangleMesh& mesh) {
  const std::size_t vertex_count = mesh.positions.size();
  if (mesh.normals.size() != vertex_count || mesh.texcoords.size() != vertex_count) return 0;

  // Welded vertex ids.
  std::vector<std::uint32_t> welded(vertex_count);
  std::unordered_map<VertexKey, std::uint32_t, VertexKeyHash> ids;
  ids.reserve(vertex_count);
  for (std::uint32_t v = 0; v < vertex_count; ++v)
    welded[v] = ids.try_emplace(key_of(mesh, v), static_cast<std::uint32_t>(ids.size())).first->second;

  // Angle-weighted sums per (welded vertex, orientation): index 2 * id + (orientation preserving).
  std::vector<Vec3d> sums(2 * ids.size(), Vec3d(0.0));
  std::vector<std::uint8_t> orientation(mesh.triangles.size(), 1);  // 1: preserving in (u, 1 - v)
  std::size_t degenerate = 0;
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const std::uint32_t corner[3] = {mesh.triangles[f].x, mesh.triangles[f].y, mesh.triangles[f].z};
    Vec3d p[3];
    Vec2d uv[3];
    for (int k = 0; k < 3; ++k) {
      p[k] = Vec3d(mesh.positions[corner[k]]);
      uv[k] = Vec2d(mesh.texcoords[corner[k]].x, 1.0 - double(mesh.texcoords[corner[k]].y));
    }
    // mikktspace.c's InitTriInfo: vOs = t31.y d1 - t21.y d2, dP/du times twice the signed UV area.
    const Vec3d d1 = p[1] - p[0], d2 = p[2] - p[0];
    const Vec2d t21 = uv[1] - uv[0], t31 = uv[2] - uv[0];
    const double signed_area = t21.x * t31.y - t21.y * t31.x;
    if (!(signed_area != 0.0) || !std::isfinite(signed_area)) {
      ++degenerate;
      continue;
    }
    orientation[f] = signed_area > 0.0 ? 1 : 0;
    // Scaled by the area's sign, as mikktspace.c does (fS): then it points along dP/du either way.
    const Vec3d os = (signed_area > 0.0 ? 1.0 : -1.0) * (t31.y * d1 - t21.y * d2);
    for (int k = 0; k < 3; ++k) {
      const Vec3d n = glm::normalize(Vec3d(mesh.normals[corner[k]]));
      const Vec3d tangent = project_to_plane(os, n);
      // The corner's angle between its two edges, both projected into the tangent plane.
      const Vec3d e1 = project_to_plane(p[(k + 1) % 3] - p[k], n), e2 = project_to_plane(p[(k + 2) % 3] - p[k], n);
      const double angle = std::acos(std::clamp(glm::dot(e1, e2), -1.0, 1.0));
      sums[2 * welded[corner[k]] + orientation[f]] += angle * tangent;
    }
  }

  // One output vertex per (vertex, orientation) used: the first keeps the index, a second
  // orientation gets a copy of the vertex.
  std::vector<std::int64_t> copy_of(vertex_count, -1);   // the vertex standing for orientation 0 where split
  std::vector<std::int8_t> first_orientation(vertex_count, -1);
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    std::uint32_t* corner = &mesh.triangles[f].x;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = corner[k];
      if (first_orientation[v] < 0) first_orientation[v] = static_cast<std::int8_t>(orientation[f]);
      if (first_orientation[v] == orientation[f]) continue;
      if (copy_of[v] < 0) {
        copy_of[v] = static_cast<std::int64_t>(mesh.positions.size());
        mesh.positions.push_back(mesh.positions[v]);
        mesh.normals.push_back(mesh.normals[v]);
        mesh.texcoords.push_back(mesh.texcoords[v]);
        if (!mesh.texcoords1.empty()) mesh.texcoords1.push_back(mesh.texcoords1[v]);
        if (!mesh.colors.empty()) mesh.colors.push_back(mesh.colors[v]);
        welded.push_back(welded[v]);
        first_orientation.push_back(static_cast<std::int8_t>(orientation[f]));
      }
      corner[k] = static_cast<std::uint32_t>(copy_of[v]);
    }
  }

  mesh.tangents.assign(mesh.positions.size(), Vec4f(0.0f));
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const int o = first_orientation[v] < 0 ? 1 : first_orientation[v];
    const Vec3d n = glm::normalize(Vec3d(mesh.normals[v]));
    const Vec3d sum = sums[2 * welded[v] + std::size_t(o)];
    const double length = glm::length(sum);
    const Vec3d tangent = length > 0.0 && std::isfinite(length) ? sum / length : any_perpendicular(n);
    mesh.tangents[v] = Vec4f(Vec3f(tangent), o == 1 ? 1.0f : -1.0f);
  }
  return degenerate;
}

}  // namespace rt
