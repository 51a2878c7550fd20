// Dielectric interfaces (rt/render/dielectric.h) against the closed forms of optics: Snell's law,
// the Fresnel equations (checked against the independently derived transmission amplitudes, so
// that R + T = 1 is a real test), Brewster's angle, total internal reflection at the critical angle
// and Beer–Lambert absorption.

#include "catch.h"

#include <cmath>
#include <optional>
#include <random>

#include "rt/render/dielectric.h"

namespace {

using rt::Vec3d;

// A unit direction travelling towards a surface with normal +z, at angle `theta` from the normal,
// in the xz plane.
Vec3d incoming(double theta) { return {std::sin(theta), 0.0, -std::cos(theta)}; }

// Transmitted power fraction from the Fresnel transmission amplitudes (Born and Wolf §1.5.2),
// derived separately from the reflection amplitudes fresnel_dielectric uses:
// T = (n_t cos_t) / (n_i cos_i) * (t_s^2 + t_p^2) / 2, with n_i = 1 and n_t = eta.
double fresnel_transmittance(double cos_i, double eta) {
  const double sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
  const double cos_t = std::sqrt(1.0 - sin2_t);
  const double t_s = 2.0 * cos_i / (cos_i + eta * cos_t);
  const double t_p = 2.0 * cos_i / (eta * cos_i + cos_t);
  return eta * cos_t / cos_i * 0.5 * (t_s * t_s + t_p * t_p);
}

}  // namespace

TEST_CASE("Fresnel: ((n - 1) / (n + 1))^2 at normal incidence, from either side", "[dielectric]") {
  for (const double n : {1.33, 1.5, 2.4}) {
    const double expected = std::pow((n - 1.0) / (n + 1.0), 2.0);
    CHECK(rt::fresnel_dielectric(1.0, n) == Approx(expected).epsilon(1e-14));
    CHECK(rt::fresnel_dielectric(1.0, 1.0 / n) == Approx(expected).epsilon(1e-14));
  }
  CHECK(rt::fresnel_dielectric(1.0, 1.5) == Approx(0.04).epsilon(1e-14));
  CHECK(rt::fresnel_dielectric(0.3, 1.0) == Approx(0.0).margin(1e-15));  // no interface, no reflection
}

TEST_CASE("Fresnel: R + T = 1 with T from the transmission amplitudes, R -> 1 at grazing incidence", "[dielectric]") {
  for (const double eta : {1.2, 1.5, 1.0 / 1.5 + 0.0001, 2.4})
    for (double cos_i = 0.05; cos_i <= 1.0; cos_i += 0.05) {
      if ((1.0 - cos_i * cos_i) / (eta * eta) >= 1.0) continue;  // TIR: tested below
      INFO("eta " << eta << " cos_i " << cos_i);
      CHECK(rt::fresnel_dielectric(cos_i, eta) + fresnel_transmittance(cos_i, eta) == Approx(1.0).epsilon(1e-12));
    }
  CHECK(rt::fresnel_dielectric(1e-9, 1.5) == Approx(1.0).epsilon(1e-6));
}

TEST_CASE("Fresnel: at Brewster's angle only the s-polarised half reflects", "[dielectric]") {
  const double n = 1.5;
  const double theta_b = std::atan(n);  // tan theta_B = n: the p amplitude vanishes
  const double cos_i = std::cos(theta_b), cos_t = std::sqrt(1.0 - std::pow(std::sin(theta_b) / n, 2.0));
  const double r_s = (cos_i - n * cos_t) / (cos_i + n * cos_t);
  CHECK(rt::fresnel_dielectric(cos_i, n) == Approx(0.5 * r_s * r_s).epsilon(1e-12));
  // Away from it the p-polarised part adds to the s-polarised one.
  const double cos_off = std::cos(theta_b + 0.2), cos_off_t = std::sqrt(1.0 - std::pow(std::sin(theta_b + 0.2) / n, 2.0));
  const double r_s_off = (cos_off - n * cos_off_t) / (cos_off + n * cos_off_t);
  CHECK(rt::fresnel_dielectric(cos_off, n) > 0.5 * r_s_off * r_s_off * (1.0 + 1e-6));
}

TEST_CASE("total internal reflection begins exactly at the critical angle", "[dielectric]") {
  const double eta = 1.0 / 1.5;  // glass to air
  const double critical = std::asin(eta);
  const double below = std::nextafter(critical, 0.0) - 1e-9, beyond = critical + 1e-9;
  CHECK(rt::refract_direction(incoming(below), {0, 0, 1}, eta).has_value());
  CHECK(rt::fresnel_dielectric(std::cos(below), eta) < 1.0);
  CHECK_FALSE(rt::refract_direction(incoming(beyond), {0, 0, 1}, eta).has_value());
  CHECK(rt::fresnel_dielectric(std::cos(beyond), eta) == 1.0);
  CHECK(rt::fresnel_dielectric(std::cos(1.2), eta) == 1.0);
  // Just below the critical angle the refracted ray grazes the surface.
  const Vec3d grazing = *rt::refract_direction(incoming(critical - 1e-7), {0, 0, 1}, eta);
  CHECK(std::abs(grazing.z) < 1e-3);
}

TEST_CASE("refract_direction obeys Snell's law, stays in the plane of incidence and reverses", "[dielectric]") {
  std::mt19937_64 random(20261201);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int i = 0; i < 1000; ++i) {
    const Vec3d normal = glm::normalize(Vec3d(uniform(random), uniform(random), uniform(random)));
    Vec3d incident = glm::normalize(Vec3d(uniform(random), uniform(random), uniform(random)));
    if (glm::dot(incident, normal) > 0.0) incident = -incident;
    if (glm::dot(incident, normal) > -1e-3) continue;
    const double eta = i % 2 == 0 ? 1.5 : 1.0 / 1.5;
    const std::optional<Vec3d> refracted = rt::refract_direction(incident, normal, eta);
    const double sin_i = glm::length(glm::cross(incident, normal));
    if (!refracted) {
      CHECK(sin_i / eta >= 1.0 - 1e-12);
      continue;
    }
    INFO("incident " << incident.x << " " << incident.y << " " << incident.z << " eta " << eta);
    CHECK(glm::length(*refracted) == Approx(1.0).epsilon(1e-14));
    CHECK(glm::dot(*refracted, normal) < 0.0);                                   // crosses the surface
    CHECK(std::abs(glm::dot(*refracted, glm::cross(incident, normal))) < 1e-12);  // plane of incidence
    CHECK(eta * glm::length(glm::cross(*refracted, normal)) == Approx(sin_i).epsilon(1e-12));  // n_t sin t = n_i sin i
    // Light paths reverse: refracting the reversed ray back gives the reversed incident ray.
    const std::optional<Vec3d> back = rt::refract_direction(-*refracted, -normal, 1.0 / eta);
    REQUIRE(back.has_value());
    CHECK(glm::length(*back + incident) < 1e-12);
  }
}

TEST_CASE("Beer-Lambert: the attenuation colour after the attenuation distance, multiplicative in distance", "[dielectric]") {
  const Vec3d color(0.5, 0.8, 1.0);
  CHECK(rt::beer_lambert_transmittance(color, 2.0, 2.0) == color);
  const Vec3d half = rt::beer_lambert_transmittance(color, 2.0, 1.0);
  CHECK(half.x == Approx(std::sqrt(0.5)).epsilon(1e-14));
  CHECK(half.z == 1.0);
  const Vec3d three = rt::beer_lambert_transmittance(color, 2.0, 3.0);
  const Vec3d one_then_two = rt::beer_lambert_transmittance(color, 2.0, 1.0) * rt::beer_lambert_transmittance(color, 2.0, 2.0);
  CHECK(three.x == Approx(one_then_two.x).epsilon(1e-14));
  CHECK(three.y == Approx(one_then_two.y).epsilon(1e-14));
  CHECK(rt::beer_lambert_transmittance(color, INFINITY, 100.0) == Vec3d(1.0));
  CHECK(rt::beer_lambert_transmittance(Vec3d(0.0), 1.0, 0.5) == Vec3d(0.0));
}

TEST_CASE("thin sheet: the series of inner bounces sums to 2R / (1 + R), from either face", "[dielectric]") {
  for (const double eta : {1.2, 1.5, 2.5}) {
    for (const double cos_i : {1.0, 0.7, 0.3, 0.02}) {
      const double r = rt::fresnel_dielectric(cos_i, eta);
      // Light entering the sheet bounces between its faces; each exit through the front face adds
      // T * R^(2k+1) * T. Summed term by term, not by the geometric-series formula.
      double series = r, inside = (1.0 - r) * r;  // after entering (T) and one inner reflection (R)
      for (int k = 0; k < 200; ++k) {
        series += inside * (1.0 - r);
        inside *= r * r;
      }
      const double thin = rt::fresnel_thin_dielectric(cos_i, eta);
      CHECK(thin == Approx(series).epsilon(1e-12));
      CHECK(thin == Approx(2.0 * r / (1.0 + r)).epsilon(1e-12));
      CHECK(thin >= r);
      CHECK(thin < 1.0);
    }
  }
  CHECK(rt::fresnel_thin_dielectric(1.0, 1.0) == 0.0);  // no interface, nothing reflected
  CHECK(rt::fresnel_thin_dielectric(0.0, 1.5) == 1.0);  // grazing
}
