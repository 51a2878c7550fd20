#include "rt/render/effects.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "rt/render/surface_maps.h"

namespace rt {

namespace {

bool is_black(const Color& c) { return c.r == 0.0f && c.g == 0.0f && c.b == 0.0f; }
double max_channel(const Color& c) { return std::max({double(c.r), double(c.g), double(c.b)}); }

Color reflection_weight(const Material& m) { return m.reflective.value_or(m.specular); }

// Largest number of (triangle, vertex) orientation tests is_convex_for_certain runs; a scene
// that would need more is not examined (about a second of work at this size).
constexpr double kMaxConvexityTests = 5e7;

// Where d lies relative to the plane through a, b, c with normal (b - a) x (c - a), decided for
// certain or not at all: +1 strictly behind, 0 exactly on the plane, -1 in front or undecided. Inputs are float32 coordinates held exactly in
// double; the determinant is Shewchuk's orient3d (a - d) . ((b - d) x (c - d)) evaluated in double,
// trusted only when its magnitude exceeds his a-priori bound (7 + 56 eps) eps * permanent,
// eps = 2^-53 (J. R. Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast Robust
// Geometric Predicates", Discrete Comput. Geom. 18, 1997, orient3dfast/errboundA). A permanent of
// zero means every product is exactly zero, so a zero determinant is then exact.
int behind_for_certain(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& d) {
  const Vec3d ad = a - d, bd = b - d, cd = c - d;
  const double bdxcdy = bd.x * cd.y, cdxbdy = cd.x * bd.y;
  const double cdxady = cd.x * ad.y, adxcdy = ad.x * cd.y;
  const double adxbdy = ad.x * bd.y, bdxady = bd.x * ad.y;
  const double det = ad.z * (bdxcdy - cdxbdy) + bd.z * (cdxady - adxcdy) + cd.z * (adxbdy - bdxady);
  const double permanent = (std::abs(bdxcdy) + std::abs(cdxbdy)) * std::abs(ad.z) +
                           (std::abs(cdxady) + std::abs(adxcdy)) * std::abs(bd.z) +
                           (std::abs(adxbdy) + std::abs(bdxady)) * std::abs(cd.z);
  constexpr double eps = std::numeric_limits<double>::epsilon() / 2.0;
  constexpr double error_bound_a = (7.0 + 56.0 * eps) * eps;
  if (permanent == 0.0) return det == 0.0 ? 0 : -1;
  // det > 0 means behind: a = (0,0,0), b = (1,0,0), c = (0,1,0) (normal +z) and d = (0,0,1) give -1.
  return det > error_bound_a * permanent ? 1 : -1;
}

}  // namespace

std::string to_string(SkipRule rule) {
  switch (rule) {
    case SkipRule::light_off: return "light_off";
    case SkipRule::zero_contribution: return "zero_contribution";
    case SkipRule::light_at_eye: return "light_at_eye";
    case SkipRule::convex_facing: return "convex_facing";
    case SkipRule::light_on_surface: return "light_on_surface";
    case SkipRule::black_reflection: return "black_reflection";
    case SkipRule::black_refraction: return "black_refraction";
    case SkipRule::dim_light: return "dim_light";
    case SkipRule::low_throughput: return "low_throughput";
    case SkipRule::emitter_off: return "emitter_off";
    case SkipRule::unlit_material: return "unlit_material";
    case SkipRule::emitter_behind: return "emitter_behind";
    case SkipRule::emitter_below_horizon: return "emitter_below_horizon";
    case SkipRule::sample_zero: return "sample_zero";
    case SkipRule::sample_on_surface: return "sample_on_surface";
  }
  return "?";
}

bool is_convex_for_certain(const FlatScene& flat) {
  if (flat.triangles.empty() || !flat.spheres.empty()) return false;
  // Only the vertices the triangles use (flatten may leave others unused).
  std::vector<char> used(flat.positions.size(), 0);
  for (const Vec3u& t : flat.triangles) used[t.x] = used[t.y] = used[t.z] = 1;
  std::vector<Vec3d> vertices;
  for (std::size_t i = 0; i < flat.positions.size(); ++i)
    if (used[i]) vertices.emplace_back(flat.positions[i]);
  if (double(flat.triangles.size()) * double(vertices.size()) > kMaxConvexityTests) return false;
  for (const Vec3u& t : flat.triangles) {
    const Vec3d p0(flat.positions[t.x]), p1(flat.positions[t.y]), p2(flat.positions[t.z]);
    for (const Vec3d& v : vertices)
      if (behind_for_certain(p0, p1, p2, v) < 0) return false;
  }
  return true;
}

namespace {

// `m` with the largest colours its per-hit maps can give it (texels and vertex colours lie in
// [0, 1]): a glTF metallic-roughness material's diffuse is at most its base colour, its highlight
// and mirror weight at most the larger of the base colour and the non-metal's F0
// (phong_from_metallic_roughness, whose weights 1 - m + m r and 1 - m r are at most 1).
Material largest_terms(const Material& m) {
  if (!m.metallic_roughness) return m;
  Material bound = m;
  const Color base = m.metallic_roughness->base_color;
  bound.diffuse = base;
  bound.specular = glm::max(base, Color(m.metallic_roughness->dielectric_f0));
  bound.reflective = bound.specular;
  return bound;
}

// The area-light part of plan_effects: the emitters and what is done with each. Area lights carry
// no ambient term (docs/area-lights.md), so an emitter lights only diffuse and specular colours.
void plan_area_lights(const Scene& scene, const FlatScene& flat, const TextureSampler* textures,
                      bool any_diffuse_or_specular, EffectsPlan& plan) {
  auto lights = std::make_shared<const AreaLights>(collect_area_lights(scene, flat, textures));
  if (lights->empty()) return;
  const EffectsOptions& options = plan.options;
  for (const Emitter& emitter : lights->emitters) {
    EmitterPlan ep;
    const std::string size =
        fmt::format("'{}': {} triangle{}, area {:.4g}, power ({:.4g}, {:.4g}, {:.4g}){}",
                    scene.materials[emitter.material].name, emitter.triangles.size(),
                    emitter.triangles.size() == 1 ? "" : "s", emitter.area, emitter.power.r, emitter.power.g,
                    emitter.power.b,
                    scene.materials[emitter.material].emission_texture.empty() ? ""
                    : emitter.texture_weighted ? " times its texture, which steers the samples"
                                               : " times its texture");
    if (!any_diffuse_or_specular && options.prune) {
      ep.contributes = false;
      ep.why = size + "; off: no material has a diffuse or specular colour";
    } else {
      plan.shadows = true;
      std::vector<std::string> rules;
      if (options.prune) {
        rules.push_back(emitter.planar ? "none behind its plane" : "none where a triangle's back faces the point");
        rules.push_back("none where it is below the horizon or the term is zero");
      }
      ep.why = fmt::format("{}; {} sample{} per hit ({}){}", size, options.light_samples,
                           options.light_samples == 1 ? "" : "s",
                           options.light_sampling == LightSampling::automatic ? "by solid angle where it pays, else by area"
                           : options.light_sampling == LightSampling::area    ? "by area"
                                                                              : "by solid angle",
                           rules.empty() ? "" : fmt::format(", {}", fmt::join(rules, "; ")));
    }
    plan.emitters.push_back(ep);
  }
  plan.area_lights = std::move(lights);
}

}  // namespace

double EffectsPlan::approximation_error_bound() const {
  double bound = 0.0;
  if (options.min_throughput > 0.0) bound += options.min_throughput * radiance_bound;
  if (options.min_light_contribution > 0.0)
    bound += options.min_light_contribution * double(lights.size()) * path_weight_bound;
  return bound;
}

EffectsPlan plan_effects(const Scene& scene, const FlatScene& flat, const RayOffset& ray_offset,
                         const EffectsOptions& options, const TextureSampler* textures) {
  EffectsPlan plan;
  plan.options = options;
  const bool geometry = !flat.triangles.empty() || !flat.spheres.empty();

  // Materials: which terms are non-zero. Texels only scale diffuse and ambient and are assumed
  // to lie in [0, 1] (8-bit and 16-bit images decode to that range) for the bounds below.
  bool any_lit_term = false, any_reflection = false, any_diffuse_or_specular = false;
  double largest_reflection = 0.0, largest_emission = 0.0, largest_lit_sum = 0.0;
  for (const Material& material : scene.materials) {
    const Material m = largest_terms(material);
    MaterialPlan mp;
    mp.ambient = !is_black(m.ambient);
    mp.diffuse = !is_black(m.diffuse);
    mp.specular = !is_black(m.specular);
    // A dielectric's reflection is weighted by its Fresnel reflectance, up to 1, and its refraction
    // by up to `transmission` (add_dielectric_rays).
    mp.reflection = (m.is_dielectric() || !is_black(reflection_weight(m))) && scene.settings.max_depth > 0;
    mp.refraction = m.is_dielectric() && scene.settings.max_depth > 0;
    mp.surface_maps = needs_surface_maps(flat, material);
    any_lit_term = any_lit_term || mp.ambient || mp.diffuse || mp.specular;
    any_diffuse_or_specular = any_diffuse_or_specular || mp.diffuse || mp.specular;
    any_reflection = any_reflection || mp.reflection;
    largest_reflection = std::max(largest_reflection, max_channel(reflection_weight(m)));
    if (m.is_dielectric()) largest_reflection = std::max({largest_reflection, 1.0, max_channel(m.transmission)});
    largest_emission = std::max(largest_emission, max_channel(m.emission));
    largest_lit_sum = std::max(largest_lit_sum, double(m.ambient.r) + m.diffuse.r + m.specular.r);
    largest_lit_sum = std::max(largest_lit_sum, double(m.ambient.g) + m.diffuse.g + m.specular.g);
    largest_lit_sum = std::max(largest_lit_sum, double(m.ambient.b) + m.diffuse.b + m.specular.b);
    plan.materials.push_back(mp);
  }
  plan.reflections = options.prune ? any_reflection && geometry : scene.settings.max_depth > 0;
  plan.useful_depth = plan.reflections ? scene.settings.max_depth : 0;

  // The geometric rules argue about exact segments; see the contract in effects.h.
  const bool robust_offsets = ray_offset.mode == RayOffset::Mode::robust;
  plan.convex = options.prune && robust_offsets && geometry &&
                ((flat.triangles.empty() && flat.spheres.size() == 1) || is_convex_for_certain(flat));
  if (!options.prune)
    plan.convex_why = "not used (--no-prune)";
  else if (!robust_offsets)
    plan.convex_why = "not used: fixed ray offsets can let a surface shadow itself";
  else if (plan.convex)
    plan.convex_why = flat.spheres.size() == 1 ? "one sphere or ellipsoid" : "one convex mesh, outward normals";
  else
    plan.convex_why = "no (more than one object, or a concave or unprovable mesh)";

  double largest_light = 0.0;  // brightest light at any lit point, linear RGB (inf: unbounded)
  for (const Light& light : scene.lights) {
    LightPlan lp;
    lp.color = Vec3d(light.color);
    if (light.is_directional()) lp.to_light = glm::normalize(Vec3d(light.position));
    lp.at_eye = !light.is_directional() && Vec3d(light.position) == scene.camera.eye;
    if (is_black(light.color)) {
      lp.contributes = false;
      lp.why = "off: black colour";
    } else if (!any_lit_term) {
      lp.contributes = false;
      lp.why = "off: no material has an ambient, diffuse or specular colour";
    } else if (!geometry) {
      lp.contributes = false;
      lp.why = "off: nothing to light";
    }
    if (!options.prune) lp.contributes = true;
    if (lp.contributes) {
      plan.shadows = true;
      std::vector<std::string> rules;
      if (options.prune) {
        rules.push_back("none where its term is zero");
        if (lp.at_eye) rules.push_back("none at primary hits (it sits at the eye)");
        if (plan.convex) rules.push_back("none where the surface faces it");
      }
      lp.why = rules.empty() ? "on: shadow ray at every hit" : "on: shadow rays at hits, " + fmt::format("{}", fmt::join(rules, "; "));
      const double attenuated = light.is_directional() ? 1.0 : light.attenuation.x;
      largest_light += attenuated > 0.0 ? max_channel(light.color) / attenuated : std::numeric_limits<double>::infinity();
    }
    plan.lights.push_back(lp);
  }
  // Geometry facing no light at all and no reflections would still need shadow rays for lights at
  // reflected hits, so `shadows` stays per light; it is false when no light contributes.

  plan_area_lights(scene, flat, textures, any_diffuse_or_specular, plan);

  // Error bounds of the approximations. Radiance of a hit at depth d <= D: emission + lights *
  // (ambient + diffuse + specular) + r * radiance at depth d + 1, or the background on a miss.
  const double local = largest_emission + largest_light * largest_lit_sum;
  const double background = max_channel(scene.settings.background);
  double radiance = std::max(background, local), weight = 1.0, power = 1.0;
  for (int d = plan.useful_depth - 1; d >= 0; --d) radiance = std::max(background, local + largest_reflection * radiance);
  for (int d = 1; d <= plan.useful_depth; ++d) weight += (power *= largest_reflection);
  plan.radiance_bound = plan.area_lights ? std::numeric_limits<double>::infinity() : radiance;
  plan.path_weight_bound = weight;
  return plan;
}

std::vector<std::string> describe_plan(const EffectsPlan& plan, const Scene& scene) {
  std::vector<std::string> lines;
  lines.push_back(fmt::format("pruning     {}", plan.options.prune ? "exact rules on (--no-prune traces every ray)"
                                                                      : "off (--no-prune): every ray is traced"));
  for (std::size_t j = 0; j < plan.lights.size(); ++j)
    lines.push_back(fmt::format("light {:<5} {}", j, plan.lights[j].why));
  for (std::size_t e = 0; e < plan.emitters.size(); ++e)
    lines.push_back(fmt::format("area {:<6} {}", e, plan.emitters[e].why));
  if (!plan.shadows)
    lines.push_back(fmt::format("shadows     off: {}", plan.lights.empty() && plan.emitters.empty() ? "no lights"
                                                                                                      : "no light contributes"));
  lines.push_back(fmt::format("convex      {}", plan.convex_why));
  if (plan.reflections) {
    std::size_t reflective = 0;
    for (const MaterialPlan& m : plan.materials) reflective += m.reflection;
    lines.push_back(fmt::format("reflections on: {} of {} materials reflect, rays up to depth {}{}", reflective,
                                plan.materials.size(), plan.useful_depth,
                                plan.options.prune ? ", none where the weight is black" : ""));
    std::size_t refractive = 0;
    for (const MaterialPlan& m : plan.materials) refractive += m.refraction;
    if (refractive > 0)
      lines.push_back(fmt::format("refraction  on: {} of {} materials are glass (Fresnel-weighted reflection and "
                                  "refraction)", refractive, plan.materials.size()));
  } else {
    lines.push_back(fmt::format("reflections off: {}", scene.settings.max_depth == 0 ? "max depth 0"
                                                                                       : "no material reflects"));
  }
  std::size_t masked = 0, blended = 0;
  for (const Material& m : scene.materials)
    if (m.has_alpha()) ++(m.alpha_mode == AlphaMode::mask ? masked : blended);
  if (masked + blended > 0)
    lines.push_back(fmt::format("alpha       on: {} of {} materials cut out (mask), {} blended; only their triangles "
                                "are alpha-tested", masked, scene.materials.size(), blended));
  std::size_t no_specular = 0;
  for (const MaterialPlan& m : plan.materials) no_specular += !m.specular;
  lines.push_back(fmt::format("terms       specular highlight skipped for {} of {} materials (black specular)",
                              no_specular, plan.materials.size()));
  if (plan.options.min_throughput > 0.0 || plan.options.min_light_contribution > 0.0)
    lines.push_back(fmt::format("approximate min throughput {}, min light contribution {}: error <= {:.3g} per "
                                "channel (linear)",
                                plan.options.min_throughput, plan.options.min_light_contribution,
                                plan.approximation_error_bound()));
  else
    lines.push_back("approximate none (see --min-throughput, --min-light)");
  return lines;
}

}  // namespace rt
