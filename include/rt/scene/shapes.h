#pragma once
// Procedural meshes in object space.

#include "rt/scene/scene.h"

namespace rt {

// Axis-aligned cube [-0.5, 0.5]^3 (side 1, centred at the origin): 24 vertices with flat
// per-face normals, 12 triangles, outward-facing.
TriangleMesh make_cube_mesh();

// Sphere of the given radius centred at the origin, tessellated as a UV sphere with `slices`
// segments around the pole axis (+y) and `stacks` rings; smooth (analytic) vertex normals.
// Requires slices >= 3, stacks >= 2. Triangle count: 2 * slices * (stacks - 1).
TriangleMesh make_sphere_mesh(double radius, int slices, int stacks);

}  // namespace rt

namespace rt {

// Replaces mesh.normals by smooth per-vertex normals: the angle-weighted average of the
// incident faces' normals (Thürmer & Wüthrich, "Computing vertex normals from polygonal
// facets", JGT 1998), which does not depend on how a polygon was triangulated. A vertex
// touched only by degenerate faces gets (0, 0, 1). Object space, computed in double; uses TBB's
// threads, with the same result bit for bit on any number of them.
void compute_vertex_normals(TriangleMesh& mesh);

}  // namespace rt
