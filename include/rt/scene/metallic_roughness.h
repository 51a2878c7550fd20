#pragma once
// glTF's metallic-roughness material mapped to the seed's Blinn-Phong terms (the table and its
// reasons: docs/scene-formats.md, "Materials: PBR -> Blinn-Phong"). The loader maps constant
// materials once; the shader maps textured ones per hit (rt/render/surface_maps.h).

#include <algorithm>

#include "rt/core/math.h"

namespace rt {

// Roughness at and above which a surface gets no mirror reflection.
inline constexpr double kMirrorRoughness = 0.3;

// Blinn-Phong terms, linear RGB in [0, 1].
struct PhongTerms {
  Vec3d diffuse{0.0};
  Vec3d specular{0.0};
  Vec3d reflective{0.0};  // the mirror reflection's weight
  double shininess = 1.0;  // the Blinn-Phong exponent
};

// With b = `base` (factor x texture x vertex colour), m = `metallic` and r = `roughness` in
// [0, 1] and F0 = mix(`dielectric_f0`, b, m): diffuse b (1 - m + m r), specular F0 (1 - m r),
// shininess 2 / r^4 - 2 clamped to [1, 10^4] (Walter et al. 2007, eq. 30, with glTF's alpha = r^2),
// reflective F0 max(0, 1 - r / kMirrorRoughness).
inline PhongTerms phong_from_metallic_roughness(const Vec3d& base, double metallic, double roughness,
                                                double dielectric_f0) {
  const Vec3d f0 = glm::mix(Vec3d(dielectric_f0), base, metallic);
  const double alpha = roughness * roughness;
  PhongTerms terms;
  terms.diffuse = base * (1.0 - metallic + metallic * roughness);
  terms.specular = f0 * (1.0 - metallic * roughness);
  terms.shininess = std::clamp(2.0 / std::max(alpha * alpha, 1e-8) - 2.0, 1.0, 1e4);
  terms.reflective = f0 * std::max(0.0, 1.0 - roughness / kMirrorRoughness);
  return terms;
}

}  // namespace rt
