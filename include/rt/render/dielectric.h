#pragma once
// Smooth dielectric interfaces (glass, water): Snell refraction, the exact Fresnel reflectance of
// unpolarised light, total internal reflection, and Beer–Lambert absorption inside a volume. The
// formulas follow pbrt-v4 (Pharr, Jakob, Humphreys, "Physically Based Rendering", 4th ed., §9.3:
// Refract, FrDielectric). All directions are world-space unit vectors in double precision.

#include <optional>

#include "rt/core/math.h"

namespace rt {

// Fraction of unpolarised light a smooth dielectric interface reflects: the mean of the squared
// s- and p-polarised Fresnel amplitudes. `cos_theta_i` is the cosine between the incident
// direction (pointing away from the surface, towards where the light came from) and the normal on
// the side the light arrives from, in [0, 1]; `eta` is the relative index n_transmitted /
// n_incident (> 0). Returns 1 under total internal reflection. At normal incidence it is
// ((eta - 1) / (eta + 1))^2.
double fresnel_dielectric(double cos_theta_i, double eta);

// Reflectance of a thin dielectric sheet (both faces, nothing bent): the single-interface
// reflectance R plus the light bounced back and forth inside, R + T^2 R / (1 - R^2) with T = 1 - R
// (pbrt-v4 ThinDielectricBxDF; Mitsuba 3's thindielectric), which is 2R / (1 + R). `eta` is the
// sheet's index relative to the outside.
double fresnel_thin_dielectric(double cos_theta_i, double eta);

// The direction transmitted through the interface by Snell's law (n_i sin theta_i = n_t sin
// theta_t). `incident` travels towards the surface; `normal` faces the side it comes from
// (dot(incident, normal) <= 0); `eta` = n_transmitted / n_incident. Unit length; nullopt under
// total internal reflection (sin theta_t > 1).
std::optional<Vec3d> refract_direction(const Vec3d& incident, const Vec3d& normal, double eta);

// The mirror direction of `incident` about `normal` (either orientation).
inline Vec3d reflect_direction(const Vec3d& incident, const Vec3d& normal) {
  return incident - 2.0 * glm::dot(incident, normal) * normal;
}

// Beer–Lambert transmittance exp(-sigma_a d) of a path of length `distance` (scene units) through
// a medium whose colour after `attenuation_distance` units is `attenuation_color` (the glTF
// KHR_materials_volume parameters): sigma_a = -ln(attenuation_color) / attenuation_distance per
// channel. An infinite attenuation_distance, or a colour of 1, absorbs nothing.
Vec3d beer_lambert_transmittance(const Vec3d& attenuation_color, double attenuation_distance, double distance);

}  // namespace rt
