#include "rt/render/dielectric.h"

#include <algorithm>
#include <cmath>

namespace rt {

double fresnel_dielectric(double cos_theta_i, double eta) {
  cos_theta_i = std::clamp(cos_theta_i, 0.0, 1.0);
  // Snell: sin^2 theta_t = sin^2 theta_i / eta^2; past 1 the wave cannot enter (TIR).
  const double sin2_theta_t = (1.0 - cos_theta_i * cos_theta_i) / (eta * eta);
  if (sin2_theta_t >= 1.0) return 1.0;
  const double cos_theta_t = std::sqrt(1.0 - sin2_theta_t);
  // Amplitude ratios for light polarised parallel and perpendicular to the plane of incidence,
  // with the relative index eta = n_t / n_i (pbrt-v4 FrDielectric).
  const double r_parallel = (eta * cos_theta_i - cos_theta_t) / (eta * cos_theta_i + cos_theta_t);
  const double r_perpendicular = (cos_theta_i - eta * cos_theta_t) / (cos_theta_i + eta * cos_theta_t);
  return 0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular);
}

double fresnel_thin_dielectric(double cos_theta_i, double eta) {
  const double r = fresnel_dielectric(cos_theta_i, eta);
  // The sheet's outer index is the same on both faces, so its inner face never totally reflects.
  return r < 1.0 ? r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r) : 1.0;
}

std::optional<Vec3d> refract_direction(const Vec3d& incident, const Vec3d& normal, double eta) {
  const double cos_theta_i = std::clamp(-glm::dot(incident, normal), 0.0, 1.0);
  const double sin2_theta_t = (1.0 - cos_theta_i * cos_theta_i) / (eta * eta);
  if (sin2_theta_t >= 1.0) return std::nullopt;
  const double cos_theta_t = std::sqrt(1.0 - sin2_theta_t);
  // The tangential part scales by 1 / eta, the normal part is set by cos theta_t (pbrt-v4 Refract).
  return glm::normalize(incident / eta + (cos_theta_i / eta - cos_theta_t) * normal);
}

Vec3d beer_lambert_transmittance(const Vec3d& attenuation_color, double attenuation_distance, double distance) {
  if (!std::isfinite(attenuation_distance) || distance <= 0.0) return Vec3d(1.0);
  Vec3d transmittance;
  for (int c = 0; c < 3; ++c) {
    // colour^(d / d_a) = exp(ln(colour) d / d_a); a black channel absorbs everything.
    const double colour = attenuation_color[c];
    transmittance[c] = colour >= 1.0 ? 1.0 : colour <= 0.0 ? 0.0 : std::pow(colour, distance / attenuation_distance);
  }
  return transmittance;
}

}  // namespace rt
