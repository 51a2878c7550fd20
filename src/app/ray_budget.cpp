#include "ray_budget.h"

#include <optional>

#include <fmt/format.h>

namespace rt {

namespace {

std::uint64_t at(const std::vector<std::uint64_t>& values, std::size_t index) {
  return index < values.size() ? values[index] : 0;
}

// One budget line: rays traced, hits (when meaningful) and, when timed, share of the loop's ticks
// and the same share of the render's wall-clock seconds.
// `group` is the ray_budget JSON key the row goes under, `index` its light, emitter or depth.
struct BudgetRow {
  enum class Group { camera, shadow, area_light, reflection } group;
  std::size_t index = 0;
  std::string kind;
  std::uint64_t rays = 0;
  std::optional<std::uint64_t> hits;
  double ticks = 0.0;
  // Depth rows of a scene with glass or blended surfaces: the refracted and see-through shares of `rays`.
  std::optional<std::uint64_t> refraction, see_through;
};

std::vector<BudgetRow> budget_rows(const RenderResult& result, const Scene& scene) {
  using Group = BudgetRow::Group;
  const RayCounts& rays = result.rays;
  std::vector<BudgetRow> rows;
  rows.push_back({Group::camera, 0, "camera", rays.camera, at(rays.hits_per_depth, 0),
                  double(at(rays.intersect_ticks_per_depth, 0)), std::nullopt, std::nullopt});
  for (std::size_t j = 0; j < scene.lights.size(); ++j)
    rows.push_back({Group::shadow, j, fmt::format("shadow light {}", j), at(rays.shadow_per_light, j), std::nullopt,
                    double(at(rays.shadow_ticks_per_light, j)), std::nullopt, std::nullopt});
  for (std::size_t e = 0; e < result.plan.emitters.size(); ++e)
    rows.push_back({Group::area_light, e, fmt::format("area light {}", e), at(rays.area_light_per_emitter, e),
                    std::nullopt, double(at(rays.area_light_ticks_per_emitter, e)), std::nullopt, std::nullopt});
  // Reflection, refraction and see-through rays of one depth share their closest-hit timing and
  // hit count.
  const std::size_t depths = std::max({rays.reflection_per_depth.size(), rays.refraction_per_depth.size(),
                                       rays.see_through_per_depth.size(), std::size_t(1)});
  const bool mixed = rays.refraction + rays.see_through > 0;
  for (std::size_t d = 1; d < depths; ++d) {
    const std::uint64_t refracted = at(rays.refraction_per_depth, d), onward = at(rays.see_through_per_depth, d);
    rows.push_back({Group::reflection, d, fmt::format("{} depth {}", mixed ? "secondary" : "reflection", d),
                    at(rays.reflection_per_depth, d) + refracted + onward, at(rays.hits_per_depth, d),
                    double(at(rays.intersect_ticks_per_depth, d)),
                    mixed ? std::optional<std::uint64_t>(refracted) : std::nullopt,
                    mixed ? std::optional<std::uint64_t>(onward) : std::nullopt});
  }
  return rows;
}

// Fraction of the timed pixels' ticks; 0 when the render was not timed.
double share(double ticks, const RayCounts& rays) {
  return rays.loop_ticks > 0 ? ticks / double(rays.loop_ticks) : 0.0;
}

}  // namespace

nlohmann::ordered_json effects_json(const EffectsPlan& plan, const Scene& scene) {
  nlohmann::ordered_json json;
  json["prune"] = plan.options.prune;
  nlohmann::ordered_json lights = nlohmann::ordered_json::array();
  for (std::size_t j = 0; j < plan.lights.size(); ++j)
    lights.push_back({{"light", j},
                      {"kind", scene.lights[j].is_directional() ? "directional"
                               : scene.lights[j].is_spot()     ? "spot"
                                                               : "point"},
                      {"contributes", plan.lights[j].contributes},
                      {"at_eye", plan.lights[j].at_eye},
                      {"why", plan.lights[j].why}});
  json["lights"] = lights;
  json["shadows"] = plan.shadows;
  json["convex"] = {{"on", plan.convex}, {"why", plan.convex_why}};
  std::size_t reflective = 0, specular = 0;
  for (const MaterialPlan& m : plan.materials) {
    reflective += m.reflection;
    specular += m.specular;
  }
  json["reflections"] = plan.reflections;
  json["useful_depth"] = plan.useful_depth;
  json["materials"] = {{"total", plan.materials.size()}, {"reflective", reflective}, {"specular", specular}};
  if (plan.area_lights) {
    nlohmann::ordered_json emitters = nlohmann::ordered_json::array();
    for (std::size_t e = 0; e < plan.emitters.size(); ++e) {
      const Emitter& emitter = plan.area_lights->emitters[e];
      emitters.push_back({{"emitter", e},
                          {"material", scene.materials[emitter.material].name},
                          {"triangles", emitter.triangles.size()},
                          {"area", emitter.area},
                          {"power", {emitter.power.r, emitter.power.g, emitter.power.b}},
                          {"planar", emitter.planar},
                          {"contributes", plan.emitters[e].contributes},
                          {"why", plan.emitters[e].why}});
    }
    json["area_lights"] = {{"samples_per_hit", plan.options.light_samples},
                           {"sampling", std::string(to_string(plan.options.light_sampling))},
                           {"emitters", emitters}};
  }
  json["approximations"] = {{"min_throughput", plan.options.min_throughput},
                            {"min_light_contribution", plan.options.min_light_contribution},
                            {"error_bound", plan.approximation_error_bound()}};
  return json;
}

nlohmann::ordered_json ray_budget_json(const RenderResult& result, const Scene& scene) {
  const RayCounts& rays = result.rays;
  const bool timed = rays.loop_ticks > 0;
  const auto row_json = [&](const BudgetRow& row) {
    nlohmann::ordered_json json = {{"rays", row.rays}};
    if (row.refraction) {
      json["reflection"] = row.rays - *row.refraction - *row.see_through;
      json["refraction"] = *row.refraction;
      json["see_through"] = *row.see_through;
    }
    if (row.hits) json["hits"] = *row.hits;
    if (timed) {
      json["time_s"] = share(row.ticks, rays) * result.seconds;
      json["share"] = share(row.ticks, rays);
    }
    return json;
  };
  nlohmann::ordered_json json;
  nlohmann::ordered_json shadow = nlohmann::ordered_json::array(), area = nlohmann::ordered_json::array(),
                         reflection = nlohmann::ordered_json::array();
  const auto append = [&](nlohmann::ordered_json& list, const char* key, const BudgetRow& row) {
    nlohmann::ordered_json entry = {{key, row.index}};
    entry.update(row_json(row));
    list.push_back(entry);
  };
  double query_ticks = 0.0;
  for (const BudgetRow& row : budget_rows(result, scene)) {
    query_ticks += row.ticks;
    switch (row.group) {
      case BudgetRow::Group::camera: json["camera"] = row_json(row); break;
      case BudgetRow::Group::shadow: append(shadow, "light", row); break;
      case BudgetRow::Group::area_light: append(area, "emitter", row); break;
      case BudgetRow::Group::reflection: append(reflection, "depth", row); break;
    }
  }
  json["shadow"] = shadow;
  if (!area.empty()) json["area_light"] = area;
  json["reflection"] = reflection;
  if (timed) {
    const double rest = std::max(0.0, double(rays.loop_ticks) - query_ticks);
    json["shading"] = {{"time_s", share(rest, rays) * result.seconds}, {"share", share(rest, rays)}};
  }
  nlohmann::ordered_json skipped;
  for (int r = 0; r < kSkipRuleCount; ++r) skipped[to_string(static_cast<SkipRule>(r))] = rays.skipped[r];
  json["skipped"] = skipped;
  json["traced"] = rays.total();
  return json;
}

std::string explain_render(const RenderResult& result, const Scene& scene) {
  const RayCounts& rays = result.rays;
  std::string text = "effects plan\n";
  for (const std::string& line : describe_plan(result.plan, scene)) text += "  " + line + "\n";
  text += fmt::format("ray budget ({:.3f} s render)\n", result.seconds);
  text += fmt::format("  {:<20} {:>14} {:>14} {:>9} {:>7}\n", "kind", "rays", "hits", "time s", "share");
  double query_ticks = 0.0;
  for (const BudgetRow& row : budget_rows(result, scene)) {
    query_ticks += row.ticks;
    text += fmt::format("  {:<20} {:>14} {:>14} {:>9.3f} {:>6.1f}%\n", row.kind, row.rays,
                        row.hits ? fmt::to_string(*row.hits) : "-", share(row.ticks, rays) * result.seconds,
                        100.0 * share(row.ticks, rays));
    if (row.refraction && *row.refraction) text += fmt::format("    {:<18} {:>14}\n", "of them refracted", *row.refraction);
    if (row.see_through && *row.see_through)
      text += fmt::format("    {:<18} {:>14}\n", "of them see-through", *row.see_through);
  }
  const double rest = std::max(0.0, double(rays.loop_ticks) - query_ticks);
  text += fmt::format("  {:<20} {:>14} {:>14} {:>9.3f} {:>6.1f}%\n", "shading, camera setup", "-", "-",
                      share(rest, rays) * result.seconds, 100.0 * share(rest, rays));
  text += fmt::format("  {:<20} {:>14}\n", "traced", rays.total());
  for (int r = 0; r < kSkipRuleCount; ++r)
    if (rays.skipped[r] > 0)
      text += fmt::format("  skipped {:<18} {:>8}\n", to_string(static_cast<SkipRule>(r)), rays.skipped[r]);
  if (rays.skipped_total() == 0) text += "  skipped              0\n";
  return text;
}

}  // namespace rt
