#pragma once
// Alpha: cut-outs (mask) and see-through surfaces (blend) of a scene's materials, evaluated at
// hits for the intersectors (through the SurfaceTest of rt/render/surface_test.h) and for the
// shader (a blend surface's weight). docs/alpha.md.

#include <atomic>
#include <cstdint>
#include <vector>

#include "rt/flatten/flatten.h"
#include "rt/scene/scene.h"

namespace rt {

// The alpha of every material of `scene` with Material::has_alpha, textures decoded to one float
// per texel when constructed. Thread-safe after construction.
class SceneAlpha {
 public:
  SceneAlpha(const Scene& scene, const FlatScene& flat);

  // True when some triangle is tested (else building an accel with it changes nothing).
  bool any() const { return any_; }

  // True when hits on `triangle` need the test: its material has an alpha below 1 somewhere.
  bool tested(std::uint32_t triangle) const { return materials_[flat_.material_ids[triangle]].tested; }
  // Closest-hit queries on a tested triangle. Mask: alpha >= cutoff. Blend: alpha > 0 (the shader
  // weighs the rest).
  bool hit_counts(std::uint32_t triangle, float b1, float b2) const;
  // Occlusion queries on a tested triangle. Mask: alpha >= cutoff. Blend: alpha >= 1/2, a
  // deterministic stand-in for the fraction a blended surface would let through (docs/alpha.md).
  bool blocks(std::uint32_t triangle, float b1, float b2) const;

  // The alpha of primitive `primitive` (a triangle, or a sphere: its material's constant) at
  // barycentrics (b1, b2), in [0, 1].
  double alpha_at(std::uint32_t primitive, float b1, float b2) const;

  // How many times the intersectors called hit_counts and blocks (the --stats "alpha_tests").
  std::uint64_t calls() const { return calls_.load(std::memory_order_relaxed); }

 private:
  struct MaterialAlpha {
    AlphaMode mode = AlphaMode::opaque;
    bool tested = false;
    float constant = 1.0f;
    float cutoff = 0.5f;
    int width = 0, height = 0;  // the texture's texels; 0: none
    std::vector<float> texels;
    Texture lookup;  // the alpha texture's wrap modes, coordinate set and transform
  };
  // The alpha of triangle `triangle`, whose material's is `alpha`, at barycentrics (b1, b2).
  double triangle_alpha(const MaterialAlpha& alpha, std::uint32_t triangle, float b1, float b2) const;

  const FlatScene& flat_;
  std::vector<MaterialAlpha> materials_;
  bool any_ = false;
  mutable std::atomic<std::uint64_t> calls_{0};
};

}  // namespace rt
