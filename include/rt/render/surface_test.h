#pragma once
// Which hits on a scene's triangles count for the intersectors: alpha cut-outs and see-through
// surfaces (rt/render/alpha.h) and the back faces of culled materials (Material::back_face).

#include <cstdint>
#include <vector>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/render/alpha.h"
#include "rt/scene/scene.h"

namespace rt {

// The SurfaceTest of a scene, as Embree's filter functions and the reference run it.
// Thread-safe after construction; `scene` may go, `flat` must outlive it.
class SceneSurfaceTest final : public SurfaceTest {
 public:
  SceneSurfaceTest(const Scene& scene, const FlatScene& flat);

  // True when some triangle is tested (else building an accel with it changes nothing).
  bool any() const { return any_; }
  // The alpha of the scene's materials, which the shader also reads (blend weights).
  const SceneAlpha& alpha() const { return alpha_; }

  bool tested(std::uint32_t triangle) const override { return culled(triangle) || alpha_.tested(triangle); }
  bool hit_counts(std::uint32_t triangle, float b1, float b2, const Vec3d& direction) const override {
    return !culled_from(triangle, direction) && (!alpha_.tested(triangle) || alpha_.hit_counts(triangle, b1, b2));
  }
  bool blocks(std::uint32_t triangle, float b1, float b2, const Vec3d& direction) const override {
    return !culled_from(triangle, direction) && (!alpha_.tested(triangle) || alpha_.blocks(triangle, b1, b2));
  }

 private:
  bool culled(std::uint32_t triangle) const { return culled_[flat_.material_ids[triangle]] != 0; }
  // The facing is computed only for culled materials: alpha-only candidates skip it.
  bool culled_from(std::uint32_t triangle, const Vec3d& direction) const {
    return culled(triangle) && arrives_from_behind(flat_, triangle, direction);
  }

  const FlatScene& flat_;
  SceneAlpha alpha_;
  std::vector<std::uint8_t> culled_;  // per material: Material::culls_back_faces
  bool any_ = false;
};

// `options` with `test` as the surface test when some triangle needs one (else unchanged, and the
// accel is built exactly as without a test).
inline AccelOptions with_surface_test(AccelOptions options, const SceneSurfaceTest& test) {
  if (test.any()) options.surface_test = &test;
  return options;
}

// The alpha of the SceneSurfaceTest `accel` was built with; null when it has none.
inline const SceneAlpha* scene_alpha_of(const Accel& accel) {
  const auto* test = dynamic_cast<const SceneSurfaceTest*>(accel.surface_test());
  return test ? &test->alpha() : nullptr;
}

}  // namespace rt
