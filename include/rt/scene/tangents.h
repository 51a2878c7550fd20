#pragma once
// Tangent frames for normal maps, generated as MikkTSpace does when a mesh has none (the glTF
// spec asks for MikkTSpace; Mikkelsen, "Simulation of Wrinkled Surfaces Revisited", 2008).

#include <cstddef>

#include "rt/scene/scene.h"

namespace rt {

// Fills mesh.tangents (object space) from positions, normals and texcoords (all one per
// position; a mesh without normals or texcoords is left unchanged). Per MikkTSpace: each
// triangle's tangent dP/du is projected into the tangent plane of each corner's normal and
// summed, weighted by the corner's angle, over the corners that share a vertex, where vertices
// with equal position, normal and texcoords count as one (welded) and triangles of opposite UV
// orientation (mirrored UVs) are kept apart; a vertex used by both orientations is split in two.
// The handedness w makes w * cross(normal, tangent) point along decreasing v, up the image (+Y of
// a glTF normal map): MikkTSpace run on (u, 1 - v), the bottom-left origin of the tools that
// bake normal maps, as glTF's top-left texture coordinates are. Returns the number of triangles
// whose UVs are degenerate (zero area), which contribute nothing.
std::size_t generate_tangents(TriangleMesh& mesh);

}  // namespace rt
