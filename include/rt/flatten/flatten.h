#pragma once
// Flattening: the scene graph becomes world-space triangle buffers in the layout Embree
// shares without copying (float3 positions, uint3 indices).

#include <cstdint>
#include <vector>

#include "rt/core/math.h"
#include "rt/scene/framing.h"
#include "rt/scene/scene.h"

namespace rt {

// An analytic sphere after flattening: the unit sphere at the object-space origin mapped by
// world_from_object (which includes the sphere's centre and radius), an ellipsoid in general.
// Double precision; intersect_sphere works in the unit sphere's space.
struct FlatSphere {
  Mat4d world_from_object{1.0};
  Mat4d object_from_world{1.0};
  Mat3d normal_from_object{1.0};  // inverse transpose of world_from_object's linear part
  std::uint32_t material = 0;     // index into Scene::materials
};

// World-space axis-aligned bounds of a FlatSphere (double; exact up to rounding): the unit sphere
// under M = world_from_object reaches +-sqrt(sum_j M_ij^2) from the centre along world axis i.
void sphere_bounds(const FlatSphere& sphere, Vec3d& lower, Vec3d& upper);

// All geometry of a scene in world space: float32 triangles and double-precision spheres.
// Primitives are numbered triangles first (0 .. T-1), then spheres (T .. T+S-1); Hit::primitive
// uses these numbers and ties go to the lowest.
// positions.capacity() > positions.size(): one spare Vec3f past the end lets Embree read the
// last vertex with a 16-byte load without leaving the allocation.
struct FlatScene {
  std::vector<Vec3f> positions;              // world space
  std::vector<Vec3f> normals;                // world space, unit length, one per position
  std::vector<Vec2f> texcoords;              // empty, or one per position ((0, 0) where a mesh has none)
  std::vector<Vec2f> texcoords1;             // empty, or one per position ((0, 0) where a mesh has none)
  std::vector<Vec4f> colors;                 // empty, or one per position (linear RGBA, 1 where a mesh has none)
  // Empty, or one per position: world space, xyz unit along the image's u (0 where a mesh has
  // none), w = +-1 the handedness (negated under a mirroring transform, so that w * cross(normal,
  // tangent) keeps pointing up the image).
  std::vector<Vec4f> tangents;
  std::vector<Vec3u> triangles;              // indices into positions, counter-clockwise
  std::vector<std::uint32_t> material_ids;   // one per triangle, index into Scene::materials
  std::vector<FlatSphere> spheres;
  std::size_t degenerate_triangles_dropped = 0;  // zero-area triangles left out (see flatten_scene)
  std::size_t degenerate_emitter_triangles_dropped = 0;  // of those, triangles of emitting materials

  std::size_t triangle_count() const { return triangles.size(); }
  bool is_sphere(std::uint32_t primitive) const { return primitive >= triangles.size(); }
  const FlatSphere& sphere_of(std::uint32_t primitive) const { return spheres[primitive - triangles.size()]; }
  std::uint32_t material_of(std::uint32_t primitive) const {
    return is_sphere(primitive) ? sphere_of(primitive).material : material_ids[primitive];
  }
};

// Whether the scene has texture coordinates (either set).
inline bool has_texcoords(const FlatScene& flat) { return !flat.texcoords.empty() || !flat.texcoords1.empty(); }

// The texture coordinates of triangle `triangle` at barycentrics (b0, b1, b2), interpolated in
// float32 (a set the scene lacks reads (0, 0)).
inline TexCoords texcoords_at(const FlatScene& flat, std::uint32_t triangle, float b0, float b1, float b2) {
  const Vec3u tri = flat.triangles[triangle];
  TexCoords uv;
  if (!flat.texcoords.empty())
    uv.uv0 = b0 * flat.texcoords[tri.x] + b1 * flat.texcoords[tri.y] + b2 * flat.texcoords[tri.z];
  if (!flat.texcoords1.empty())
    uv.uv1 = b0 * flat.texcoords1[tri.x] + b1 * flat.texcoords1[tri.y] + b2 * flat.texcoords1[tri.z];
  return uv;
}

// World-space axis-aligned bounds (double) of the triangles' vertices and the spheres; empty()
// when the scene has no primitive.
Bounds3d flat_bounds(const FlatScene& flat);

// How flatten_scene treats spheres: 0 keeps them analytic; N >= 3 tessellates every sphere into a
// UV sphere of N slices and max(2, N / 2) stacks (to compare against the exact quadric).
struct FlattenOptions {
  int sphere_tessellation = 0;
};

// Walks the graph from scene.root depth-first with an explicit stack (no recursion, so depth is
// bounded by memory, not the call stack). Positions go through the accumulated world_from_object
// (double precision, rounded to float32 once); normals through its inverse transpose, then
// normalised. A negative-determinant transform (mirror) swaps two indices so the geometric normal
// keeps agreeing with the shading normals. Meshes without normals get smooth angle-weighted ones
// (see compute_vertex_normals).
// Triangles of zero area in world space (repeated or collinear float32 vertices) can never be hit
// and have no normal; they are dropped and counted in degenerate_triangles_dropped.
// Spheres become FlatSpheres (or meshes, see FlattenOptions) with the same accumulated transform.
// Throws InputError on a cycle, a singular transform or non-finite results.
FlatScene flatten_scene(const Scene& scene, const FlattenOptions& options = {});

// Frees the graph's object-space meshes (every Model::mesh becomes null; materials, spheres,
// lights and camera stay) for callers that have flattened the scene and render from the FlatScene,
// which no longer needs them: 24 bytes per triangle less while the BVH is built.
void release_object_meshes(Scene& scene);

}  // namespace rt
