#pragma once
// Flattening: the scene graph becomes world-space triangle buffers in the layout Embree
// shares without copying (float3 positions, uint3 indices).

#include <cstdint>
#include <vector>

#include "rt/core/math.h"
#include "rt/scene/scene.h"

namespace rt {

// All geometry of a scene in world space, float32.
// positions.capacity() > positions.size(): one spare Vec3f past the end lets Embree read the
// last vertex with a 16-byte load without leaving the allocation.
struct FlatScene {
  std::vector<Vec3f> positions;              // world space
  std::vector<Vec3f> normals;                // world space, unit length, one per position
  std::vector<Vec2f> texcoords;              // empty, or one per position ((0, 0) where a mesh has none)
  std::vector<Vec3u> triangles;              // indices into positions, counter-clockwise
  std::vector<std::uint32_t> material_ids;   // one per triangle, index into Scene::materials
  std::size_t degenerate_triangles_dropped = 0;  // zero-area triangles left out (see flatten_scene)

  std::size_t triangle_count() const { return triangles.size(); }
};

// Walks the graph from scene.root depth-first with an explicit stack (no recursion, so depth is
// bounded by memory, not the call stack). Positions go through the accumulated world_from_object
// (double precision, rounded to float32 once); normals through its inverse transpose, then
// normalised. A negative-determinant transform (mirror) swaps two indices so the geometric normal
// keeps agreeing with the shading normals. Meshes without normals get smooth angle-weighted ones
// (see compute_vertex_normals).
// Triangles of zero area in world space (repeated or collinear float32 vertices) can never be hit
// and have no normal; they are dropped and counted in degenerate_triangles_dropped.
// Throws InputError on a cycle, a singular transform or non-finite results.
FlatScene flatten_scene(const Scene& scene);

}  // namespace rt
