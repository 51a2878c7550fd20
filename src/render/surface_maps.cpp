#include "rt/render/surface_maps.h"

#include <cmath>

#include "rt/scene/metallic_roughness.h"

namespace rt {

namespace {

// Step (texture space) of the finite differences that differentiate a bump map's height: a
// Whitted renderer has no ray differentials to size it, so it is fixed at about a texel of a
// 1k map; bilinear lookups make the height piecewise linear, so the slope is that texel's.
constexpr float kBumpStep = 1.0f / 1024.0f;

// The normal of a height map h (MTL bump, scaled by bump_scale) at the hit, as pbrt's BumpMap:
// the surface displaced by h along the shading normal n has tangents dp/du + dh/du n and
// dp/dv + dh/dv n; their cross product, turned to n's side. dp/du and dp/dv come from the
// triangle's positions and the bump texture's coordinates. `normal` unchanged where either is degenerate.
Vec3d bumped_normal(const FlatScene& flat, const TextureSampler& textures, std::uint32_t material_id,
                    const Material& material, std::uint32_t triangle, const TexCoords& uv, const Vec3d& normal) {
  const Vec3u tri = flat.triangles[triangle];
  const std::vector<Vec2f>& set = material.bump_texture.texcoord == 1 ? flat.texcoords1 : flat.texcoords;
  if (set.empty()) return normal;
  const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
  const Vec2d t0(set[tri.x]), t1(set[tri.y]), t2(set[tri.z]);
  const Vec2d duv1 = t1 - t0, duv2 = t2 - t0;
  const Vec3d dp1 = p1 - p0, dp2 = p2 - p0;
  const double det = duv1.x * duv2.y - duv1.y * duv2.x;
  if (!(det != 0.0) || !std::isfinite(det)) return normal;
  const Vec3d dpdu = (duv2.y * dp1 - duv1.y * dp2) / det, dpdv = (duv1.x * dp2 - duv2.x * dp1) / det;
  const auto height = [&](const Vec2f& shift) {
    TexCoords shifted = uv;
    (material.bump_texture.texcoord == 1 ? shifted.uv1 : shifted.uv0) += shift;
    return double(material.bump_scale) * double(textures.sample(material_id, TextureRole::bump, shifted).r);
  };
  const double h = height(Vec2f(0.0f));
  const double dhdu = (height(Vec2f(kBumpStep, 0.0f)) - h) / kBumpStep;
  const double dhdv = (height(Vec2f(0.0f, kBumpStep)) - h) / kBumpStep;
  const Vec3d bumped = glm::cross(dpdu + dhdu * normal, dpdv + dhdv * normal);
  const double length = glm::length(bumped);
  if (!(length > 0.0) || !std::isfinite(length)) return normal;
  return glm::dot(bumped, normal) < 0.0 ? -bumped / length : bumped / length;
}

}  // namespace

Vec3d normal_from_map(const Vec3d& texel, double scale, const Vec3d& normal, const Vec3d& tangent, double sign) {
  const Vec3d in_tangent_space = (2.0 * texel - 1.0) * Vec3d(scale, scale, 1.0);
  const Vec3d bitangent = sign * glm::cross(normal, tangent);
  const Vec3d bent = in_tangent_space.x * tangent + in_tangent_space.y * bitangent + in_tangent_space.z * normal;
  const double length = glm::length(bent);
  return length > 0.0 && std::isfinite(length) ? bent / length : glm::normalize(normal);
}

void apply_surface_maps(const FlatScene& flat, const TextureSampler* textures, std::uint32_t material_id,
                        const Material& material, const Hit& hit, const std::optional<TexCoords>& texcoord,
                        const Vec3d& texel, SurfaceTerms& terms) {
  if (flat.is_sphere(hit.primitive)) return;  // spheres carry no texture coordinates or vertex attributes
  const Vec3u tri = flat.triangles[hit.primitive];
  const double b1 = hit.u, b2 = hit.v, b0 = 1.0 - b1 - b2;
  const auto interpolate = [&](const std::vector<Vec4f>& values) {
    return b0 * Vec4d(values[tri.x]) + b1 * Vec4d(values[tri.y]) + b2 * Vec4d(values[tri.z]);
  };
  const Vec3d vertex_colour = flat.colors.empty() ? Vec3d(1.0) : Vec3d(interpolate(flat.colors));
  const bool sampled = textures && texcoord;
  const auto sample = [&](TextureRole role) {
    return sampled && textures->has(material_id, role) ? std::optional<Vec3d>(textures->sample(material_id, role, *texcoord))
                                                       : std::nullopt;
  };

  if (const std::optional<MetallicRoughness>& inputs = material.metallic_roughness) {
    const Vec3d base = Vec3d(inputs->base_color) * texel * vertex_colour;
    const Vec3d mr = sample(TextureRole::metallic_roughness).value_or(Vec3d(1.0));
    terms.metallic = std::clamp(double(inputs->metallic) * mr.b, 0.0, 1.0);
    const PhongTerms phong = phong_from_metallic_roughness(base, terms.metallic,
                                                           std::clamp(double(inputs->roughness) * mr.g, 0.0, 1.0),
                                                           inputs->dielectric_f0);
    terms.diffuse = phong.diffuse;
    terms.specular = phong.specular;
    terms.reflective = phong.reflective;
    terms.shininess = phong.shininess;
    terms.ambient *= vertex_colour;
  } else if (!flat.colors.empty()) {
    terms.diffuse *= vertex_colour;
    terms.ambient *= vertex_colour;
  }
  if (terms.ambient != Vec3d(0.0))  // glTF materials have none: no lookup for nothing
    if (const auto occlusion = sample(TextureRole::occlusion))
      terms.ambient *= 1.0 + double(material.occlusion_strength) * (occlusion->r - 1.0);
  if (const auto specular = sample(TextureRole::specular)) terms.specular *= *specular;
  if (const auto shininess = sample(TextureRole::shininess)) terms.shininess *= shininess->r;

  const bool normal_mapped = sampled && !flat.tangents.empty() && textures->has(material_id, TextureRole::normal);
  if (normal_mapped) {
    const Vec4d tangent = interpolate(flat.tangents);
    const Vec3d normal = b0 * Vec3d(flat.normals[tri.x]) + b1 * Vec3d(flat.normals[tri.y]) + b2 * Vec3d(flat.normals[tri.z]);
    // Without a tangent frame (no tangent, or vertex normals that cancel) the unmapped normal stays.
    if (Vec3d(tangent) != Vec3d(0.0) && glm::dot(normal, normal) > 0.0)
      terms.normal = normal_from_map(*sample(TextureRole::normal), material.normal_scale, normal, Vec3d(tangent),
                                     tangent.w < 0.0 ? -1.0 : 1.0);
  } else if (sampled && textures->has(material_id, TextureRole::bump)) {
    terms.normal = bumped_normal(flat, *textures, material_id, material, hit.primitive, *texcoord, terms.normal);
  }
}

}  // namespace rt
