#pragma once
// How `rt` shows the effects plan and the ray budget: JSON for --stats, a table for --explain.
// Internal to the app module (the JSON type stays out of the public headers).

#include <string>

#include <nlohmann/json.hpp>

#include "rt/render/render.h"

namespace rt {

// The plan: per light on/off and why, convex rule, reflections, useful depth, approximations
// with their error bound.
nlohmann::ordered_json effects_json(const EffectsPlan& plan, const Scene& scene);

// Rays, hits and (when the render timed its queries) seconds and share of render time per effect:
// camera, shadow per light, reflection per depth, the rest ("shading"); rays skipped per rule.
nlohmann::ordered_json ray_budget_json(const RenderResult& result, const Scene& scene);

// The plan and the ray budget as a short table for the terminal.
std::string explain_render(const RenderResult& result, const Scene& scene);

}  // namespace rt
