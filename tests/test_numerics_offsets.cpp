// Numerical robustness, part 2: where secondary rays start.
//
//  * Reintersection (pbrt-v3's "Triangle, Reintersect" test): a ray leaving a triangle through
//    offset_ray_origin must never find that triangle again, at any scale (coordinates 1e-8..1e8).
//  * Image level: a ground plane lit at a grazing 2 degrees must render as one flat colour (no
//    shadow acne) at the origin and far from it, and a box on the plane must still shadow the
//    plane right at its base (no light leaking under it).
//
// Each test prints one Markdown table row per case and configuration; the robust paths (reference,
// Embree robust and Embree with the watertight kernel, with the robust offset) are asserted, the
// others (Embree with robust mode off, the fixed offset fixed:1e-4) are printed for comparison. Regenerate the tables with
//   build/release/tests/rt_tests "[numerics]~[slow]"    (default suite)
//   build/release/tests/rt_tests "[numerics][slow]"     (long runs)

#include "catch.h"

#include <cmath>
#include <cstdint>
#include <iomanip>
#include <iostream>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "numerics_util.h"
#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/render/ray_offset.h"
#include "rt/render/render.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace {

using namespace rt_numerics;

// ---------------------------------------------------------------------------------------------
// Reintersection.

// pbrt-v3's coordinate distribution: magnitude 10^U(-8, 8), here with a random sign.
double log_uniform_coordinate(std::mt19937& rng) {
  std::uniform_real_distribution<double> exponent(-8.0, 8.0), unit(0.0, 1.0);
  const double magnitude = std::pow(10.0, exponent(rng));
  return unit(rng) < 0.5 ? -magnitude : magnitude;
}
Vec3f log_uniform_point(std::mt19937& rng) {
  const double x = log_uniform_coordinate(rng), y = log_uniform_coordinate(rng), z = log_uniform_coordinate(rng);
  return Vec3f(Vec3d(x, y, z));
}

// Triangles whose smallest altitude is below this fraction of their longest edge are skipped as
// near-degenerate (the float32 normal of a sliver is itself mostly rounding error). 1e-3 keeps
// triangles with angles down to ~0.06 degrees.
constexpr double kMinAltitudeOverEdge = 1e-3;

// Magnitude buckets of a triangle (its largest |coordinate|), to show where fixed offsets fail.
int magnitude_bucket(const std::array<Vec3f, 3>& tri) {
  double m = 0.0;
  for (const Vec3f& p : tri) m = std::max({m, std::abs(double(p.x)), std::abs(double(p.y)), std::abs(double(p.z))});
  return m <= 1.0 ? 0 : (m <= 1e4 ? 1 : 2);
}
const char* const kBucketNames[3] = {"<= 1", "1..1e4", "> 1e4"};

struct SpawnCounts {
  std::size_t triangles = 0, primary_misses = 0, skipped_targets = 0;
  std::size_t rays = 0;             // spawned rays whose answer is known: the triangle is not hit
  std::size_t origin_wrong_side = 0;  // of those, origin rounded onto or through the plane
  std::size_t intersect_hits = 0, occluded_hits = 0;  // self-hits among `rays`
  std::size_t excluded = 0, excluded_hits = 0;  // segments that end across the plane (see below)
  std::array<std::size_t, 3> bucket_rays{}, bucket_self_hits{};
  std::vector<std::string> examples;
  SpawnCounts& operator+=(const SpawnCounts& o) {
    triangles += o.triangles;
    primary_misses += o.primary_misses;
    skipped_targets += o.skipped_targets;
    rays += o.rays;
    origin_wrong_side += o.origin_wrong_side;
    intersect_hits += o.intersect_hits;
    occluded_hits += o.occluded_hits;
    excluded += o.excluded;
    excluded_hits += o.excluded_hits;
    for (int b = 0; b < 3; ++b) {
      bucket_rays[b] += o.bucket_rays[b];
      bucket_self_hits[b] += o.bucket_self_hits[b];
    }
    for (const std::string& e : o.examples)
      if (examples.size() < 30) examples.push_back(e);
    return *this;
  }
  std::size_t self_hits() const { return bucket_self_hits[0] + bucket_self_hits[1] + bucket_self_hits[2]; }
};

// The configurations: intersector x ray offset policy. The robust-offset rows of the reference and
// of Embree robust are asserted.
struct SpawnConfig {
  Path path;
  const char* offset;
  bool asserted;
};
const SpawnConfig kSpawnConfigs[] = {
    {Path::reference, "robust", true},           {Path::embree_robust, "robust", true},
    {Path::embree_default, "robust", false},     {Path::reference, "fixed:1e-4", false},
    {Path::embree_robust, "fixed:1e-4", false},  {Path::embree_default, "fixed:1e-4", false},
    {Path::embree_exact, "robust", true},
};
constexpr std::size_t kConfigCount = std::size(kSpawnConfigs);

struct AllSpawnCounts {
  std::array<SpawnCounts, kConfigCount> per_config;
  std::size_t skipped_triangles = 0;
  AllSpawnCounts& operator+=(const AllSpawnCounts& o) {
    for (std::size_t c = 0; c < kConfigCount; ++c) per_config[c] += o.per_config[c];
    skipped_triangles += o.skipped_triangles;
    return *this;
  }
};

std::string str(const Vec3f& v) {
  std::ostringstream out;
  out.precision(9);
  out << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return out.str();
}

// `triangle_count` random triangles (seed `seed`); from each, `rays_per_triangle` spawned rays per
// configuration, half in uniform random directions (both hemispheres), half towards random points
// with the same log-uniform distribution (direction = target - origin, tfar from shadow_ray_tfar).
//
// The ideal spawned ray starts on the triangle's plane and leaves it, so it never meets the
// triangle again: any hit is a self-hit. One class of target rays is set apart ("excluded",
// counted and printed): targets that lie on the triangle's plane at float32 precision, i.e. within
//   kOnPlaneSafety * u * (|target - origin| + sqrt(3) |target|_inf)
// of it. The float32 direction target - origin alone is rounded by up to u |target - origin|,
// which moves the far end of the segment off the ideal one by that much: such a segment may really
// cross the plane, and does so at a grazing angle where the along-ray margin of shadow_ray_tfar
// cannot help. Those rays are the "light sitting on the surface" case, tested on its own below
// ("shadow rays towards a point light lying on a floor").
AllSpawnCounts reintersect(std::size_t triangle_count, std::size_t rays_per_triangle, std::uint32_t seed) {
  std::mt19937 rng(seed);
  AllSpawnCounts all;
  std::size_t kept = 0;
  while (kept < triangle_count) {
    const std::array<Vec3f, 3> tri{log_uniform_point(rng), log_uniform_point(rng), log_uniform_point(rng)};
    const Vec3d p0(tri[0]), p1(tri[1]), p2(tri[2]);
    const double area2 = glm::length(glm::cross(p1 - p0, p2 - p0));
    const double longest = std::max({glm::length(p1 - p0), glm::length(p2 - p0), glm::length(p2 - p1)});
    // Smallest altitude = area2 / longest edge.
    if (!(area2 > 0.0) || area2 / longest < kMinAltitudeOverEdge * longest) {
      ++all.skipped_triangles;
      continue;
    }
    ++kept;
    const int bucket = magnitude_bucket(tri);
    const rt::FlatScene flat = flat_soup({tri});
    const Vec3d normal = glm::normalize(glm::cross(p1 - p0, p2 - p0));

    // Shared random input for all configurations: the primary ray and the spawned directions and
    // targets.
    const auto [b1, b2] = random_barycentrics(rng);
    const Vec3d aim = (1.0 - b1 - b2) * p0 + b1 * p1 + b2 * p2;
    rt::Ray primary;
    primary.origin = log_uniform_point(rng);
    primary.direction = Vec3f(aim - Vec3d(primary.origin));
    std::vector<Vec3f> directions(rays_per_triangle / 2);
    for (Vec3f& d : directions) d = Vec3f(random_unit_vector(rng));
    std::vector<Vec3d> targets(rays_per_triangle - directions.size());
    for (Vec3d& t : targets) t = Vec3d(log_uniform_point(rng));

    std::unique_ptr<rt::Accel> accels[int(Path::embree_exact) + 1];  // indexed by Path
    for (std::size_t c = 0; c < kConfigCount; ++c) {
      const SpawnConfig& config = kSpawnConfigs[c];
      SpawnCounts& counts = all.per_config[c];
      auto& accel = accels[int(config.path)];
      if (!accel) accel = build(config.path, flat);
      ++counts.triangles;
      const rt::Hit hit = accel->intersect(primary);
      if (!hit.found()) {
        ++counts.primary_misses;
        continue;
      }
      const rt::SurfacePoint surface = rt::make_surface_point(p0, p1, p2, hit.u, hit.v);
      const rt::RayOffset policy = rt::parse_ray_offset(config.offset);

      // `side`: the direction the ideal ray leaves the plane to (its dot product with the normal).
      // `excluded`: a target on the plane at float32 precision (see reintersect's comment).
      auto spawn = [&](const rt::Ray& ray, double side, bool excluded) {
        const Vec3d o(ray.origin);
        const double start = glm::dot(normal, o - p0);
        const bool origin_ok = start * side > 0.0 && std::abs(start) > 1e-12 * glm::length(o - p0);
        const bool intersected = accel->intersect(ray).found();
        const bool occluded = accel->occluded(ray);
        if (excluded) {
          ++counts.excluded;
          counts.excluded_hits += intersected || occluded;
          return;
        }
        ++counts.rays;
        ++counts.bucket_rays[bucket];
        counts.origin_wrong_side += !origin_ok;
        counts.intersect_hits += intersected;
        counts.occluded_hits += occluded;
        if (intersected || occluded) {
          ++counts.bucket_self_hits[bucket];
          if (counts.examples.size() < 3)
            counts.examples.push_back("triangle " + str(tri[0]) + " " + str(tri[1]) + " " + str(tri[2]) + " uv (" +
                                      std::to_string(hit.u) + ", " + std::to_string(hit.v) + "), ray o=" +
                                      str(ray.origin) + " d=" + str(ray.direction) +
                                      " tfar=" + std::to_string(ray.tfar));
        }
      };
      for (const Vec3f& d : directions) {
        rt::Ray ray;
        ray.origin = rt::offset_ray_origin(policy, surface, Vec3d(d));  // the side of the float direction
        ray.direction = d;
        spawn(ray, glm::dot(surface.geometric_normal, Vec3d(d)), false);
      }
      for (const Vec3d& target : targets) {
        rt::Ray ray;
        ray.origin = rt::offset_ray_origin(policy, surface, target - surface.point);
        ray.direction = Vec3f(target - Vec3d(ray.origin));
        const double length = glm::length(Vec3d(ray.direction));
        // shadow_ray_tfar is in world units; t counts multiples of the direction.
        const double tfar = rt::shadow_ray_tfar(policy, Vec3d(ray.origin), target) / length;
        if (!(length > 0.0) || !(tfar > 0.0)) {  // target within the margin of the surface point
          ++counts.skipped_targets;
          continue;
        }
        ray.tfar = static_cast<float>(tfar);
        const double band = kFloatRoundoff * glm::length(target - Vec3d(ray.origin));
        const bool on_plane = std::abs(glm::dot(normal, target - p0)) <= band;
        spawn(ray, glm::dot(surface.geometric_normal, target - surface.point), on_plane);
      }
    }
  }
  return all;
}

void print_spawn_table(const AllSpawnCounts& all, const char* run) {
  std::cout << "\n### Reintersection (" << run << "): rays spawned from random triangles, coordinates 10^U(-8,8)\n\n"
            << "Triangles skipped as near-degenerate (altitude < " << kMinAltitudeOverEdge
            << " x longest edge): " << all.skipped_triangles << "\n\n"
            << "| intersector | ray offset | triangles | primary misses | spawned rays | origin on/through plane "
               "| self-hits (intersect) | self-hits (occluded) | self-hits / rays, max coord <= 1 | 1..1e4 | > 1e4 "
               "| excluded (target on the plane at float32 precision) | hits among excluded |\n"
            << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t c = 0; c < kConfigCount; ++c) {
    const SpawnCounts& k = all.per_config[c];
    std::cout << "| " << name(kSpawnConfigs[c].path) << " | " << kSpawnConfigs[c].offset << " | " << k.triangles
              << " | " << k.primary_misses << " | " << k.rays << " | " << k.origin_wrong_side << " | "
              << k.intersect_hits << " | " << k.occluded_hits;
    for (int b = 0; b < 3; ++b) std::cout << " | " << k.bucket_self_hits[b] << " / " << k.bucket_rays[b];
    std::cout << " | " << k.excluded << " | " << k.excluded_hits << " |\n";
  }
  std::cout << std::endl;
  for (std::size_t c = 0; c < kConfigCount; ++c)
    for (const std::string& e : all.per_config[c].examples)
      std::cout << "  self-hit, " << name(kSpawnConfigs[c].path) << " + " << kSpawnConfigs[c].offset << ": " << e
                << "\n";
}

void check_spawn(const AllSpawnCounts& all, std::size_t min_rays) {
  for (std::size_t c = 0; c < kConfigCount; ++c) {
    const SpawnCounts& k = all.per_config[c];
    INFO(name(kSpawnConfigs[c].path) << " + " << kSpawnConfigs[c].offset);
    if (!kSpawnConfigs[c].asserted) continue;
    CHECK(k.rays >= min_rays);
    // Targets on the plane at float32 precision are common in this distribution (~7%: small
    // coordinates cluster near the coordinate origin, through which the planes of triangles with a
    // tiny vertex pass within u |target - origin|), but they must stay a minority; `rays` counts
    // only the others, and those are what the >= 1M requirement is about.
    CHECK(k.excluded * 10 < k.rays);
    CHECK(k.skipped_targets * 1000 < k.rays);
    // The robust offset rounds the origin away from the plane, always.
    CHECK(k.origin_wrong_side == 0);
    CHECK(k.intersect_hits == 0);
    CHECK(k.occluded_hits == 0);
  }
}

}  // namespace

TEST_CASE("rays spawned with the robust offset never re-hit their triangle (1M rays)", "[numerics]") {
  // 1,120 triangles x 1,040 spawned rays per configuration, in 8 independently seeded chunks.
  const AllSpawnCounts all = parallel_chunks<AllSpawnCounts>(
      8, [](std::size_t chunk) { return reintersect(140, 1040, 7001u + static_cast<std::uint32_t>(chunk)); });
  print_spawn_table(all, "default suite");
  check_spawn(all, 1'000'000);
  // The fixed offset is scale-dependent: it must fail somewhere on triangles far from the origin
  // (1e-4 is below float32 spacing beyond ~1e3), which shows the test can see self-hits at all.
  CHECK(all.per_config[4].bucket_self_hits[2] > 0);
}

TEST_CASE("rays spawned with the robust offset never re-hit their triangle (10M rays)", "[numerics][.slow]") {
  const AllSpawnCounts all = parallel_chunks<AllSpawnCounts>(
      80, [](std::size_t chunk) { return reintersect(135, 1040, 9001u + static_cast<std::uint32_t>(chunk)); });
  print_spawn_table(all, "slow run");
  check_spawn(all, 10'000'000);
}

// A light exactly on a surface, seen at grazing angles: the float32 error of t at the far end grows
// like 1 / sin(angle), far beyond the margin of shadow_ray_tfar, so Embree's native float32 kernels
// report the floor as an occluder (printed, not asserted; docs/robustness.md). The double-precision
// watertight test resolves these angles, in the reference and inside Embree's BVH alike.
TEST_CASE("shadow rays towards a point light lying on a floor are not occluded by that floor", "[numerics]") {
  // shadow_ray_tfar promises that "a surface the light sits on is not an occluder". Here a point
  // light sits exactly on a floor: it is the shared vertex of a fan of 8 float32 triangles in a
  // tilted plane (normal (1, 3, 2) / |.|), so the light is on every one of them. Shadow rays arrive
  // from points above the floor at elevations 10^U(-3, 0.7) degrees and distances 5..45, built as
  // shade.cpp builds them: direction = float32(normalize(light - origin)), tfar =
  // shadow_ray_tfar(robust, origin, light). The ideal segment touches the floor only at its end,
  // the light, which the margin cuts off: no hit is correct. Rays whose float32 segment is not
  // strictly above every fan triangle's plane (checked in double, relative margin 1e-12) are
  // skipped: for them a hit could be right.
  std::cout << "\n### Point light at a vertex of a tilted floor: shadow rays from above at grazing elevations\n\n"
            << "| placement | intersector | rays | skipped | occluded | occluded, elevation < 0.1 deg | 0.1..1 deg | > 1 deg |\n"
            << "|---|---|---|---|---|---|---|---|\n";
  const Vec3d normal = glm::normalize(Vec3d(1, 3, 2));
  const Vec3d tangent = glm::normalize(glm::cross(normal, Vec3d(0, 0, 1))), bitangent = glm::cross(normal, tangent);
  for (const Vec3d centre : {Vec3d(0.0), Vec3d(1e3), Vec3d(1e5)}) {
    const double radius = 100.0;
    const Vec3f light(centre);
    std::vector<std::array<Vec3f, 3>> fan;
    for (int k = 0; k < 8; ++k) {
      auto rim = [&](int j) {
        const double a = 2.0 * std::numbers::pi * j / 8;
        return Vec3f(Vec3d(light) + radius * (std::cos(a) * tangent + std::sin(a) * bitangent));
      };
      fan.push_back({light, rim(k), rim(k + 1)});
    }
    const rt::FlatScene flat = flat_soup(fan);
    for (Path path : {Path::reference, Path::embree_robust, Path::embree_default, Path::embree_exact}) {
      const std::unique_ptr<rt::Accel> accel = build(path, flat);
      std::mt19937 rng(4242u);
      std::uniform_real_distribution<double> unit(0.0, 1.0), exponent(-3.0, std::log10(5.0));
      std::size_t rays = 0, skipped = 0, occluded = 0;
      std::array<std::size_t, 3> by_angle{};
      for (int i = 0; i < 20000; ++i) {
        const double degrees = std::pow(10.0, exponent(rng)), elevation = degrees * std::numbers::pi / 180.0;
        const double azimuth = 2.0 * std::numbers::pi * unit(rng), distance = 5.0 + 40.0 * unit(rng);
        const Vec3d horizontal = std::cos(azimuth) * tangent + std::sin(azimuth) * bitangent;
        const Vec3f origin(Vec3d(light) +
                           distance * (std::cos(elevation) * horizontal + std::sin(elevation) * normal));
        rt::Ray ray;
        ray.origin = origin;
        ray.direction = Vec3f(glm::normalize(Vec3d(light) - Vec3d(origin)));
        const double tfar = rt::shadow_ray_tfar(rt::RayOffset{}, Vec3d(origin), Vec3d(light));
        ray.tfar = static_cast<float>(tfar);
        bool above = tfar > 0.0;
        for (const auto& tri : fan) {
          const Vec3d p0(tri[0]), n = glm::normalize(glm::cross(Vec3d(tri[1]) - p0, Vec3d(tri[2]) - p0));
          const Vec3d o(ray.origin), end = o + double(ray.tfar) * Vec3d(ray.direction);
          above = above && glm::dot(n, o - p0) > 1e-12 * glm::length(o - p0) &&
                  glm::dot(n, end - p0) > 1e-12 * glm::length(end - p0);
        }
        if (!above) {
          ++skipped;
          continue;
        }
        ++rays;
        if (accel->occluded(ray) || accel->intersect(ray).found()) {
          ++occluded;
          ++by_angle[degrees < 0.1 ? 0 : (degrees < 1.0 ? 1 : 2)];
        }
      }
      std::cout << "| (" << centre.x << ", " << centre.y << ", " << centre.z << ") | " << name(path) << " | " << rays
                << " | " << skipped << " | " << occluded << " | " << by_angle[0] << " | " << by_angle[1] << " | "
                << by_angle[2] << " |\n";
      if (path == Path::reference || path == Path::embree_exact) {
        INFO(name(path) << " at offset " << centre.x);
        CHECK(occluded == 0);
      }
    }
  }
  std::cout << std::endl;
}

TEST_CASE("robust offset origins lie at least the error bound off the plane, on the direction's side", "[numerics]") {
  // offset_ray_origin promises the point moved along the normal by error_bound and "rounded away
  // from the surface": after rounding to float32 every component must still be at or beyond the
  // unrounded target along the side's sign, and the origin's distance to the triangle's plane at
  // least error_bound (up to the double rounding of that check, 1e-9 relative here).
  std::mt19937 rng(5150u);
  std::size_t checked = 0, short_of_bound = 0, rounded_back = 0;
  for (int i = 0; i < 20000; ++i) {
    const std::array<Vec3f, 3> tri{log_uniform_point(rng), log_uniform_point(rng), log_uniform_point(rng)};
    const Vec3d p0(tri[0]), p1(tri[1]), p2(tri[2]);
    const Vec3d cross = glm::cross(p1 - p0, p2 - p0);
    if (!(glm::length(cross) > 0.0)) continue;
    const auto [b1, b2] = random_barycentrics(rng);
    const rt::SurfacePoint surface = rt::make_surface_point(p0, p1, p2, b1, b2);
    const Vec3d direction = random_unit_vector(rng);
    const Vec3f origin = rt::offset_ray_origin(rt::RayOffset{}, surface, direction);
    const Vec3d side = glm::dot(surface.geometric_normal, direction) >= 0.0 ? surface.geometric_normal
                                                                          : -surface.geometric_normal;
    const Vec3d target = surface.point + surface.error_bound * side;
    ++checked;
    for (int c = 0; c < 3; ++c)
      if ((double(origin[c]) - target[c]) * side[c] < 0.0) ++rounded_back;
    const double distance = glm::dot(Vec3d(origin) - surface.point, side);
    if (distance < surface.error_bound * (1.0 - 1e-9)) ++short_of_bound;
  }
  INFO(checked << " origins checked");
  CHECK(checked > 19000);
  CHECK(rounded_back == 0);
  CHECK(short_of_bound == 0);
}
