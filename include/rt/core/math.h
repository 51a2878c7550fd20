#pragma once
// Vector and matrix aliases over GLM. The precision is part of the name: `f` is float32
// (what Embree and the flattened buffers store), `d` is float64 (scene graph transforms,
// camera, shading geometry and the reference intersector).

#include <glm/glm.hpp>

namespace rt {

using Vec2f = glm::vec2;
using Vec3f = glm::vec3;
using Vec4f = glm::vec4;
using Vec2d = glm::dvec2;
using Vec3d = glm::dvec3;
using Vec4d = glm::dvec4;
using Vec3u = glm::uvec3;
using Mat3d = glm::dmat3;
using Mat4d = glm::dmat4;

// Linear RGB radiance or reflectance, float32 per channel, unbounded above.
using Color = glm::vec3;

}  // namespace rt
