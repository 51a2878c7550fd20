#include "rt/render/surface_test.h"

#include <algorithm>

namespace rt {

SceneSurfaceTest::SceneSurfaceTest(const Scene& scene, const FlatScene& flat)
    : flat_(flat), alpha_(scene, flat), culled_(scene.materials.size(), 0) {
  for (std::size_t m = 0; m < scene.materials.size(); ++m) culled_[m] = scene.materials[m].culls_back_faces();
  any_ = alpha_.any();
  if (std::find(culled_.begin(), culled_.end(), 1) == culled_.end()) return;
  for (std::uint32_t t = 0; t < flat.triangle_count() && !any_; ++t) any_ = culled(t);
}

}  // namespace rt
