#pragma once
// The record of a camera pixel's light terms and shadow rays, shared by shade_surface's deferred
// shadows (shade.cpp) and the batch shader (batch_shade.cpp).

#include <cstddef>
#include <cstdint>

#include "rt/render/shade.h"

namespace rt {

// Appends light terms to `pending` in light order: lit() a term added without a query, query() one
// added only if `shadow_ray` (world space) is unblocked, recorded to be traced with the block's
// packets and counted at once (RayCounts::add_shadow_query; `slot` as there, `light_count` =
// Scene::lights.size()). Records are written in place, field by field: one built on the stack and
// copied is read back wider than it was written, which stalls store forwarding.
struct ShadowRecorder {
  PendingShading& pending;
  RayCounts& counts;
  std::size_t light_count;

  [[gnu::always_inline]] void lit(std::size_t, const Vec3d& term, int = 0) {
    PendingShading::Term& t = pending.terms.emplace_back();
    t.term = term;
    t.query = PendingShading::kNoQuery;
  }
  [[gnu::always_inline]] void query(std::size_t slot, const Vec3d& term, const Ray& shadow_ray, int = 0) {
    PendingShading::Term& t = pending.terms.emplace_back();
    t.term.x = term.x;  // component by component: `term` may have been spilled by 8-byte stores,
    t.term.y = term.y;  // and a wider load of it would stall store forwarding
    t.term.z = term.z;
    t.query = static_cast<std::uint32_t>(pending.shadow_rays.size());
    Ray& ray = pending.shadow_rays.emplace_back();
    ray.origin = shadow_ray.origin;
    ray.direction = shadow_ray.direction;
    ray.tnear = shadow_ray.tnear;
    ray.tfar = shadow_ray.tfar;
    pending.shadow_lights.push_back(static_cast<std::uint32_t>(slot));
    counts.add_shadow_query(light_count, slot);
  }
};

}  // namespace rt
