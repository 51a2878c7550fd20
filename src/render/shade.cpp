#include "rt/render/shade.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace rt {

RayCounts& RayCounts::operator+=(const RayCounts& other) {
  camera += other.camera;
  shadow += other.shadow;
  reflection += other.reflection;
  return *this;
}

Color find_color(const ShadingContext& context, const Ray& ray, int depth, RayCounts& counts) {
  const Hit hit = context.accel.intersect(ray);
  if (!hit.found()) return context.scene.settings.background;

  // Surface at the hit, world space, double. The point is interpolated from the triangle's
  // vertices (or projected onto the sphere) rather than taken as o + t d: it then lies on the
  // surface up to rounding, whatever error t carries.
  const FlatScene& flat = context.flat;
  SurfacePoint surface;
  Vec3d normal;                    // shading normal, unit length
  std::optional<Vec2f> texcoord;   // interpolated texture coordinates, when the scene has them
  if (flat.is_sphere(hit.primitive)) {
    surface = make_sphere_surface_point(flat.sphere_of(hit.primitive), Vec3d(ray.origin), Vec3d(ray.direction), hit.t);
    normal = surface.geometric_normal;
  } else {
    const Vec3u tri = flat.triangles[hit.primitive];
    const Vec3d p0(flat.positions[tri.x]), p1(flat.positions[tri.y]), p2(flat.positions[tri.z]);
    const double b1 = hit.u, b2 = hit.v, b0 = 1.0 - b1 - b2;
    surface = make_surface_point(p0, p1, p2, b1, b2);
    normal = glm::normalize(b0 * Vec3d(flat.normals[tri.x]) + b1 * Vec3d(flat.normals[tri.y]) +
                            b2 * Vec3d(flat.normals[tri.z]));
    if (!flat.texcoords.empty())
      texcoord = float(b0) * flat.texcoords[tri.x] + float(b1) * flat.texcoords[tri.y] +
                 float(b2) * flat.texcoords[tri.z];
  }
  const Vec3d& point = surface.point;
  const Vec3d direction = glm::normalize(Vec3d(ray.direction));
  const Vec3d to_eye = -direction;
  const std::uint32_t material_id = flat.material_of(hit.primitive);
  const Material& material = context.scene.materials[material_id];
  // Texture space, float: the diffuse texture's colour at the hit (white without one; spheres
  // carry no texture coordinates).
  const Vec3d texel = texcoord && context.textures && context.textures->has_diffuse(material_id)
                          ? Vec3d(context.textures->diffuse(material_id, *texcoord))
                          : Vec3d(1.0);
  const Vec3d ambient = Vec3d(material.ambient) * texel, diffuse = Vec3d(material.diffuse) * texel;
  const Vec3d specular(material.specular);
  const Vec3d reflective(material.reflective.value_or(material.specular));

  Vec3d radiance(material.emission);
  for (const Light& light : context.scene.lights) {
    Vec3d to_light;
    Vec3d intensity(light.color);
    if (light.is_directional()) {
      to_light = glm::normalize(Vec3d(light.position));
    } else {
      const Vec3d offset = Vec3d(light.position) - point;
      const double d = glm::length(offset);
      if (!(d > 0.0)) continue;  // a light exactly at the point has no direction
      to_light = offset / d;
      intensity /= light.attenuation.x + light.attenuation.y * d + light.attenuation.z * d * d;
      if (light.is_spot()) {
        const double cone = std::clamp((glm::dot(light.spot_direction, -to_light) - light.spot_cos_outer) /
                                           std::max(light.spot_cos_inner - light.spot_cos_outer, 1e-3),
                                       0.0, 1.0);
        if (cone == 0.0) continue;
        intensity *= cone * cone;
      }
    }
    Ray shadow_ray;
    shadow_ray.origin = offset_ray_origin(context.ray_offset, surface, to_light);
    const double light_distance = light.is_directional()
                                      ? double(kInfinity)
                                      : shadow_ray_tfar(context.ray_offset, Vec3d(shadow_ray.origin), Vec3d(light.position));
    // A point light closer to the surface than the margin cannot be occluded; no ray is needed.
    if (light_distance > 0.0) {
      shadow_ray.direction = Vec3f(to_light);
      shadow_ray.tfar = static_cast<float>(light_distance);
      ++counts.shadow;
      if (context.accel.occluded(shadow_ray)) continue;
    }

    // l + v vanishes when the light is exactly behind the surface point as seen from the eye;
    // the half vector is then undefined and the highlight is taken as zero (n.h = 0), not NaN.
    const Vec3d half_sum = to_light + to_eye;
    const double half_length = glm::length(half_sum);
    const double n_dot_l = std::max(glm::dot(normal, to_light), 0.0);
    const double n_dot_h = half_length > 0.0 ? std::max(glm::dot(normal, half_sum) / half_length, 0.0) : 0.0;
    radiance += intensity * (ambient + diffuse * n_dot_l + specular * std::pow(n_dot_h, double(material.shininess)));
  }

  if (depth < context.scene.settings.max_depth && (!material.reflective || reflective != Vec3d(0.0))) {
    const Vec3d reflected = direction - 2.0 * glm::dot(direction, normal) * normal;
    Ray reflection_ray;
    reflection_ray.origin = offset_ray_origin(context.ray_offset, surface, reflected);
    reflection_ray.direction = Vec3f(reflected);
    ++counts.reflection;
    radiance += reflective * Vec3d(find_color(context, reflection_ray, depth + 1, counts));
  }
  return Color(radiance);
}

}  // namespace rt
