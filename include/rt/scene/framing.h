#pragma once
// Default viewpoints and lights for formats that carry none (OBJ, some glTF files): a camera
// that frames the geometry's bounding box and a headlight.

#include <limits>

#include "rt/scene/scene.h"

namespace rt {

// Axis-aligned box in double precision; empty (lo > hi) until a point is added.
struct Bounds3d {
  Vec3d lo{std::numeric_limits<double>::infinity()};
  Vec3d hi{-std::numeric_limits<double>::infinity()};

  void extend(const Vec3d& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  Vec3d center() const { return 0.5 * (lo + hi); }
  // Radius of the bounding sphere centred at center(): half the diagonal.
  double radius() const { return 0.5 * glm::length(hi - lo); }
};

// The object-space box of a mesh's positions.
Bounds3d mesh_bounds(const TriangleMesh& mesh);

// The world-space box of every vertex reachable from scene.root, each transformed exactly (in
// double) by its node's accumulated transform. The graph must be acyclic; indices must be in range.
Bounds3d world_bounds(const Scene& scene);

// A camera looking along `view` (need not be unit length) at the centre of `bounds`, with the
// given up vector and vertical field of view, placed at the distance where the bounding sphere
// just fits inside both the vertical and the horizontal field of view of an image of
// width / height = `aspect`. When `up` is parallel to `view`, +z (or +x) is used instead. An empty
// box is framed as the unit box around the origin; a single point as a sphere of radius 1.
Camera frame_bounds(const Bounds3d& bounds, double aspect, const Vec3d& view = {0.0, 0.0, -1.0},
                    const Vec3d& up = {0.0, 1.0, 0.0}, double fovy_degrees = 45.0);

// The lights of a scene file that has none (glTF, OBJ; docs/scene-formats.md, "Default
// lighting"): a key light, directional, from above the camera and behind it, a little to its
// right (towards it: 0.5 right + 1 up + 0.7 back, normalised; colour 0.8), which shades and
// shadows shape, and a headlight, a point light of colour 0.4 at the eye (unattenuated), which
// fills what the key light leaves dark. A surface facing the camera gets about 0.8 of a white
// headlight of 1, a surface facing up about 1.
std::vector<Light> make_default_lights(const Camera& camera);

}  // namespace rt
