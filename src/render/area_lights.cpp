#include "rt/render/area_lights.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/render/sampling.h"
#include "lane_math.h"
#include "light_sample_lanes.h"

namespace rt {

namespace {

// Planarity tolerances (relative): normals within ~1e-6 rad of the first triangle's, vertices
// within 1e-9 of the emitter's extent off its plane. A point the plane test puts behind a slightly
// tilted triangle then receives at most ~1e-6 of a grazing contribution less; float32 vertices of a
// flat quad are usually exactly coplanar.
constexpr double kPlanarNormalCosine = 1.0 - 1e-12;
constexpr double kPlanarDistance = 1e-9;

// The emitter's plane, when every triangle lies in it and faces the same way.
void find_plane(Emitter& emitter) {
  const Vec3d n = emitter.triangles.front().normal;
  const double offset = glm::dot(n, emitter.triangles.front().p0);
  const double tolerance = kPlanarDistance * std::max(glm::length(emitter.bounds.hi - emitter.bounds.lo), 1e-300);
  for (const EmitterTriangle& t : emitter.triangles) {
    if (glm::dot(t.normal, n) < kPlanarNormalCosine) return;
    for (const Vec3d& p : {t.p0, t.p1, t.p2})
      if (std::abs(glm::dot(n, p) - offset) > tolerance) return;
  }
  emitter.planar = true;
  emitter.plane_normal = n;
  emitter.plane_offset = offset;
}

// Share of the largest triangle's texture estimate added to every triangle's (see collect_area_lights).
constexpr double kTextureWeightFloor = 0.01;

// Per triangle of a textured emitter: the mean luminance of its emission texture (linear) at the
// centroid and at the three points halfway between it and the vertices. Empty when the emitter has
// no texture the sampler can read, or the scene no texture coordinates. Lookups in parallel, each
// triangle's its own, so the result does not depend on the thread count.
std::vector<double> estimate_texture_means(const Emitter& emitter, const FlatScene& flat, const TextureSampler* textures) {
  if (!textures || !textures->has_emission(emitter.material) || !has_texcoords(flat)) return {};
  constexpr float kCorner = 2.0f / 3.0f, kOther = 1.0f / 6.0f, kThird = 1.0f / 3.0f;
  const Vec3f points[4] = {Vec3f(kThird), Vec3f(kCorner, kOther, kOther), Vec3f(kOther, kCorner, kOther),
                           Vec3f(kOther, kOther, kCorner)};
  std::vector<double> means(emitter.triangles.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, means.size(), 256), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      double sum = 0.0;
      for (const Vec3f& b : points) {
        const TexCoords uv = texcoords_at(flat, emitter.triangles[i].primitive, b.x, b.y, b.z);
        const Vec3d texel(textures->emission(emitter.material, uv));
        sum += 0.2126 * texel.r + 0.7152 * texel.g + 0.0722 * texel.b;  // Rec. 709 luminance
      }
      means[i] = sum / 4.0;
    }
  });
  return means;
}

}  // namespace

std::string_view to_string(LightSampling sampling) {
  switch (sampling) {
    case LightSampling::automatic: return "auto";
    case LightSampling::area: return "area";
    case LightSampling::solid_angle: return "solid-angle";
  }
  return "?";
}

LightSampling parse_light_sampling(std::string_view text) {
  for (LightSampling s : {LightSampling::automatic, LightSampling::area, LightSampling::solid_angle})
    if (text == to_string(s)) return s;
  throw InputError("", "", fmt::format("unknown light sampling '{}' (expected auto, area or solid-angle)", text));
}

AreaLights collect_area_lights(const Scene& scene, const FlatScene& flat, const TextureSampler* textures) {
  AreaLights lights;
  // Material index -> its emitter's index in lights.emitters (material order), -1 if it emits nothing.
  std::vector<int> emitter_of(scene.materials.size(), -1);
  for (std::size_t m = 0; m < scene.materials.size(); ++m)
    if (scene.materials[m].is_emitter()) {
      emitter_of[m] = int(lights.emitters.size());
      lights.emitters.emplace_back().material = static_cast<std::uint32_t>(m);
    }
  if (lights.empty()) return lights;
  for (const FlatSphere& sphere : flat.spheres)
    if (emitter_of[sphere.material] >= 0)
      throw InputError(scene.source, "",
                       fmt::format("material '{}' emits light and is used by a sphere: area lights must be triangle "
                                   "meshes (use a mesh, or tessellate spheres with --sphere-tessellation N)",
                                   scene.materials[sphere.material].name));

  std::size_t count = 0;
  for (std::uint32_t material : flat.material_ids) count += emitter_of[material] >= 0;
  if (const auto shortfall = memory_shortfall(count * (sizeof(EmitterTriangle) + sizeof(double))))
    throw InputError(scene.source, "", fmt::format("the {} emissive triangles' area lights {}", count, *shortfall));

  for (std::size_t i = 0; i < flat.triangles.size(); ++i) {
    const int e = emitter_of[flat.material_ids[i]];
    if (e < 0) continue;
    const Vec3u tri = flat.triangles[i];
    EmitterTriangle t;
    t.p0 = Vec3d(flat.positions[tri.x]);
    t.p1 = Vec3d(flat.positions[tri.y]);
    t.p2 = Vec3d(flat.positions[tri.z]);
    const Vec3d cross = glm::cross(t.p1 - t.p0, t.p2 - t.p0);
    const double twice_area = glm::length(cross);
    if (!(twice_area > 0.0)) continue;  // flatten drops these already; float32 vertices are exact in double
    t.area = 0.5 * twice_area;
    t.primitive = static_cast<std::uint32_t>(i);
    t.frame = make_triangle_frame(t.p0, t.p1, t.p2);
    t.normal = t.frame.geometric_normal;  // cross / twice_area: the light points' normal, by construction
    Emitter& emitter = lights.emitters[std::size_t(e)];
    for (const Vec3d& p : {t.p0, t.p1, t.p2}) emitter.bounds.extend(p);
    emitter.area += t.area;
    emitter.triangles.push_back(t);
  }

  // Emitters whose triangles were all dropped (zero area) light nothing.
  std::erase_if(lights.emitters, [](const Emitter& emitter) { return emitter.triangles.empty(); });
  for (Emitter& emitter : lights.emitters) {
    const Vec3d emission(scene.materials[emitter.material].emission);
    emitter.power = std::numbers::pi * emitter.area * emission;
    // One emission per emitter, so power is proportional to area, times the texture's estimate.
    const std::vector<double> texture_means = estimate_texture_means(emitter, flat, textures);
    emitter.texture_weighted = !texture_means.empty();
    const double floor =
        emitter.texture_weighted ? kTextureWeightFloor * *std::max_element(texture_means.begin(), texture_means.end()) : 0.0;
    double running = 0.0;
    emitter.cdf.reserve(emitter.triangles.size());
    for (std::size_t i = 0; i < emitter.triangles.size(); ++i)
      emitter.cdf.push_back(running += emitter.triangles[i].area *
                                       (emitter.texture_weighted ? texture_means[i] + floor : 1.0));
    if (!(running > 0.0)) {  // an all-black texture: by area
      running = 0.0;
      for (std::size_t i = 0; i < emitter.triangles.size(); ++i) emitter.cdf[i] = running += emitter.triangles[i].area;
    }
    for (double& c : emitter.cdf) c /= running;
    emitter.cdf.back() = 1.0;
    find_plane(emitter);
    lights.triangle_count += emitter.triangles.size();
  }
  return lights;
}

bool in_front_of_emitter(const Emitter& emitter, const Vec3d& point) {
  return !emitter.planar || glm::dot(emitter.plane_normal, point) > emitter.plane_offset;
}

bool emitter_below_horizon(const Emitter& emitter, const Vec3d& point, const Vec3d& normal) {
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3d p((corner & 1) ? emitter.bounds.hi.x : emitter.bounds.lo.x,
                  (corner & 2) ? emitter.bounds.hi.y : emitter.bounds.lo.y,
                  (corner & 4) ? emitter.bounds.hi.z : emitter.bounds.lo.z);
    if (glm::dot(normal, p - point) > 0.0) return false;
  }
  return true;
}

EmitterSampler::EmitterSampler(const Emitter& emitter, const FlatScene& flat, const Scene& scene,
                               const TextureSampler* textures, const Vec3d& point, LightSampling sampling,
                               const SphericalTriangle* spherical)
    : emitter_(emitter),
      flat_(flat),
      scene_(scene),
      textures_(textures),
      emission_texture_(textures && textures->has_emission(emitter.material) && has_texcoords(flat)),
      point_(point),
      sampling_(sampling) {
  // An emitter of at most kSlots triangles (draw's slots) has every view set up before its first
  // sample anyway: here, the set-up's long chain of divisions, square roots and atan2 overlaps
  // the caller's independent work before the first draw (the origins, the sample pattern).
  if (spherical)
    view_cached_triangles(spherical);
  else if (emitter.triangles.size() <= std::size_t(light_sample_lanes::Input::kSlots))
    view_cached_triangles();
}

bool EmitterSampler::needs_spherical(const EmitterTriangle& t) const {
  if (sampling_ == LightSampling::area) return false;
  // A triangle whose back faces the point sends nothing: area sampling finds that as cheaply.
  return sampling_ != LightSampling::automatic || glm::dot(t.normal, point_ - t.p0) > 0.0;
}

void EmitterSampler::set_view(std::size_t triangle, const SphericalTriangle& spherical, View& view) const {
  view.spherical = spherical;
  view.by_solid_angle = spherical.valid() && (sampling_ == LightSampling::solid_angle ||
                                              (spherical.solid_angle() >= kMinSolidAngleSampling &&
                                               spherical.solid_angle() <= kMaxSolidAngleSampling));
  view.radiance_over_pdf = Vec3d(0.0);
  if (view.by_solid_angle) {
    // weigh's value: the triangle's probability as choose computes it.
    const std::vector<double>& cdf = emitter_.cdf;
    const double probability = cdf[triangle] - (triangle > 0 ? cdf[triangle - 1] : 0.0);
    view.radiance_over_pdf =
        Vec3d(scene_.materials[emitter_.material].emission) * (spherical.solid_angle() / probability);
  }
}

EmitterSampler::View EmitterSampler::view_of(std::size_t triangle) const {
  const EmitterTriangle& t = emitter_.triangles[triangle];
  View view;
  if (needs_spherical(t)) set_view(triangle, SphericalTriangle(point_, t.p0, t.p1, t.p2), view);
  return view;
}

void EmitterSampler::view_cached_triangles(const SphericalTriangle* seen) {
  // The spherical triangles the cached views need, set up together in lanes unless seen.
  std::array<std::array<Vec3d, 3>, kCachedTriangles> corners;
  std::array<std::size_t, kCachedTriangles> which;
  std::size_t count = 0;
  const std::size_t cached = std::min(kCachedTriangles, emitter_.triangles.size());
  for (std::size_t i = 0; i < cached; ++i) {
    const EmitterTriangle& t = emitter_.triangles[i];
    cache_[i].by_solid_angle = false;  // its spherical triangle is not read
    if (!needs_spherical(t)) continue;
    if (!seen) corners[count] = {t.p0, t.p1, t.p2};
    which[count++] = i;
  }
  if (seen) {
    for (std::size_t k = 0; k < count; ++k) set_view(which[k], seen[which[k]], cache_[which[k]]);
    cached_ = true;
    return;
  }
  constexpr SphericalTriangle::Unset unset;
  std::array<SphericalTriangle, kCachedTriangles> spherical{SphericalTriangle(unset), SphericalTriangle(unset),
                                                            SphericalTriangle(unset), SphericalTriangle(unset)};
  SphericalTriangle::set_up_many(point_, std::span(corners).first(count), spherical);
  for (std::size_t k = 0; k < count; ++k) set_view(which[k], spherical[k], cache_[which[k]]);
  cached_ = true;
}

[[gnu::always_inline]] inline EmitterSampler::Choice EmitterSampler::choose(double uy) const {
  const std::vector<double>& cdf = emitter_.cdf;
  // std::upper_bound's index: the number of entries c with !(uy < c), the cdf being sorted. A few
  // entries (a quad light has two) are counted without branches: uy is random, so a search's
  // branches are mispredicted about half the time.
  std::size_t index = 0;
  if (cdf.size() <= 16)
    for (const double c : cdf) index += uy < c ? 0 : 1;
  else
    index = std::size_t(std::upper_bound(cdf.begin(), cdf.end(), uy) - cdf.begin());
  Choice choice;
  choice.triangle = std::min(index, cdf.size() - 1);
  const double low = choice.triangle > 0 ? cdf[choice.triangle - 1] : 0.0;
  choice.probability = cdf[choice.triangle] - low;
  choice.v = std::clamp((uy - low) / choice.probability, 0.0, 1.0 - 0x1p-53);
  return choice;
}

void EmitterSampler::choose_many(std::span<const double> uy, std::span<Choice> out) const {
  namespace lm = lane_math;
  const std::vector<double>& cdf = emitter_.cdf;
  if (cdf.size() > 16 || uy.size() % 4 != 0) {
    for (std::size_t k = 0; k < uy.size(); ++k) out[k] = choose(uy[k]);
    return;
  }
  // choose's steps four lanes at a time: the index counted as there, std::min(index, last) as
  // (last < index) ? last : index, the interval's ends selected entry by entry. The divisions of
  // a group overlap instead of each stalling the comparison of std::clamp after it.
  const lm::D4 zero{}, one = lm::broadcast(1.0), last = lm::broadcast(double(cdf.size() - 1));
  for (std::size_t g = 0; g < uy.size(); g += 4) {
    lm::D4 u;
    lm::load(u, uy.data() + g);
    lm::D4 index{};
    for (const double c : cdf) index += lm::select(u < lm::broadcast(c), zero, one);
    const lm::D4 triangle = lm::select(last < index, last, index);
    lm::D4 low{}, high = lm::broadcast(cdf[0]);
    for (std::size_t j = 1; j < cdf.size(); ++j) {
      const lm::M4 here = triangle == lm::broadcast(double(j));
      low = lm::select(here, lm::broadcast(cdf[j - 1]), low);
      high = lm::select(here, lm::broadcast(cdf[j]), high);
    }
    const lm::D4 probability = high - low;
    const lm::D4 v = lm::clamp((u - low) / probability, zero, lm::broadcast(1.0 - 0x1p-53));
    double triangles[4], probabilities[4], vs[4];
    lm::store(triangles, triangle);
    lm::store(probabilities, probability);
    lm::store(vs, v);
    for (std::size_t i = 0; i < 4; ++i) out[g + i] = {std::size_t(triangles[i]), probabilities[i], vs[i]};
  }
}

[[gnu::always_inline]] inline const EmitterSampler::View& EmitterSampler::view(std::size_t i, View* uncached) {
  if (i >= kCachedTriangles) return *uncached = view_of(i);
  if (!cached_) view_cached_triangles();
  return cache_[i];
}

[[gnu::always_inline]] inline void EmitterSampler::weigh(LightSample& sample, const EmitterTriangle& t, const Choice& choice, const View& view,
                           const Vec3d& b) const {
  const double cos_emitter = -glm::dot(t.normal, sample.direction);
  if (!(cos_emitter > 0.0)) return;  // the triangle's back faces the point: no radiance

  if (emission_texture_) sample.texcoord = texcoords_at(flat_, t.primitive, float(b.x), float(b.y), float(b.z));
  // Solid-angle density of the direction: probability / solid angle (the view's, once per
  // triangle), or by area probability / area * r^2 / cos(theta') (the change of measure
  // dA = r^2 / cos(theta') d omega).
  if (view.by_solid_angle) {
    sample.radiance_over_pdf = view.radiance_over_pdf;
    return;
  }
  const Vec3d radiance(scene_.materials[emitter_.material].emission);
  sample.radiance_over_pdf =
      radiance * (t.area * cos_emitter / (choice.probability * sample.distance * sample.distance));
}

LightSample EmitterSampler::sample(Vec2d u) {
  const Choice choice = choose(u.y);
  const EmitterTriangle& t = emitter_.triangles[choice.triangle];
  View uncached;
  const View& seen = view(choice.triangle, &uncached);

  LightSample sample;
  Vec3d b;
  if (seen.by_solid_angle) {
    const auto along = barycentrics_along(point_, seen.spherical.sample({u.x, choice.v}), t.p0, t.p1, t.p2);
    if (!along) return sample;
    b = *along;
  } else {
    b = sample_triangle_uniform({u.x, choice.v});
  }
  sample.light_point = make_surface_point(t.p0, t.p1, t.p2, t.frame, b.y, b.z);
  const Vec3d offset = sample.light_point.point - point_;
  sample.distance = glm::length(offset);
  if (!(sample.distance > 0.0)) return sample;
  sample.direction = offset / sample.distance;
  sample.valid = true;
  weigh(sample, t, choice, seen, b);
  return sample;
}

namespace {

void set_lane(light_sample_lanes::Vec3& to, int k, const Vec3d& v) {
  to.x.v[k] = v.x;
  to.y.v[k] = v.y;
  to.z.v[k] = v.z;
}

}  // namespace

void EmitterSampler::put_triangle(light_sample_lanes::Input& in, int entry, std::size_t triangle, double probability,
                                  const View& seen) const {
  const EmitterTriangle& t = emitter_.triangles[triangle];
  set_lane(in.p0, entry, t.p0);
  set_lane(in.p1, entry, t.p1);
  set_lane(in.p2, entry, t.p2);
  in.edge_term.v[entry] = t.frame.edge_term;
  set_lane(in.normal, entry, t.normal);
  in.area.v[entry] = t.area;
  in.probability.v[entry] = probability;
  if (seen.by_solid_angle) {
    const SphericalTriangle& spherical = seen.spherical;
    in.cos_alpha.v[entry] = spherical.cos_alpha();
    in.sin_alpha.v[entry] = spherical.sin_alpha();
    in.cos_c.v[entry] = spherical.cos_c();
    set_lane(in.a, entry, spherical.a());
    set_lane(in.b, entry, spherical.b());
    set_lane(in.c_perp, entry, spherical.c_perp());
    set_lane(in.solid_radiance, entry, seen.radiance_over_pdf);
  } else {
    // The warp's inputs are read but not used: any finite values.
    in.cos_alpha.v[entry] = in.sin_alpha.v[entry] = in.cos_c.v[entry] = 0.0;
    set_lane(in.a, entry, Vec3d(1.0, 0.0, 0.0));
    set_lane(in.b, entry, Vec3d(0.0, 1.0, 0.0));
    set_lane(in.c_perp, entry, Vec3d(0.0, 0.0, 1.0));
    set_lane(in.solid_radiance, entry, Vec3d(0.0));
  }
}

void EmitterSampler::draw(std::span<const Vec2d> u, light_sample_lanes::Chunk& chunk) {
  namespace lanes = light_sample_lanes;
  static const lanes::Kernels& kernels = lanes::best_kernels();
  lanes::Input& in = chunk.in;
  for (int axis = 0; axis < 3; ++axis) in.point[axis] = point_[axis];
  const Vec3d emission(scene_.materials[emitter_.material].emission);
  for (int axis = 0; axis < 3; ++axis) in.emission[axis] = emission[axis];
  // An emitter of at most kCachedTriangles triangles has them in the slots, its views all set up;
  // a larger one has each lane's, with one view per lane for triangles past the cache.
  const bool by_slot = emitter_.triangles.size() <= std::size_t(lanes::Input::kSlots);
  static_assert(lanes::Input::kSlots <= kCachedTriangles);
  in.slots = by_slot ? static_cast<int>(emitter_.triangles.size()) : 0;
  const int count = chunk.count = static_cast<int>(std::min<std::size_t>(lanes::kLanes, u.size()));
  // Gather each lane's sample (and without slots its triangle); the lanes past `count` up to a
  // multiple of 4 repeat the last one.
  const int padded = (count + 3) / 4 * 4;
  // Where every slot is sampled by solid angle, the choices and the warp's inputs are made in
  // lanes (Kernels::choose); otherwise lane by lane, the choices in a pass of their own (a choice
  // read back right after it was written stalled store forwarding).
  const auto u_of = [&](int k) { return u[std::size_t(std::min(k, count - 1))]; };
  if (by_slot) {
    if (!cached_) view_cached_triangles();
    const std::vector<double>& cdf = emitter_.cdf;
    bool all_by_solid_angle = true;
    for (int s = 0; s < in.slots; ++s) {  // choose's probability of triangle s
      const double low = s > 0 ? cdf[std::size_t(s) - 1] : 0.0;
      const View& seen = cache_[std::size_t(s)];
      put_triangle(in, s, std::size_t(s), cdf[std::size_t(s)] - low, seen);
      in.low.v[s] = low;
      in.high.v[s] = cdf[std::size_t(s)];
      in.solid_area.v[s] = seen.spherical.solid_angle();
      in.alpha.v[s] = seen.spherical.alpha();
      all_by_solid_angle = all_by_solid_angle && seen.by_solid_angle;
    }
    if (all_by_solid_angle) {  // the choices and the warp's inputs in lanes
      for (int k = 0; k < padded; ++k) {
        in.ux.v[k] = u_of(k).x;
        in.uy.v[k] = u_of(k).y;
      }
      kernels.choose(in, padded, chunk.triangle);
      kernels.sample(in, count, chunk.out);
      return;
    }
  } else if (emitter_.triangles.size() > kCachedTriangles) {
    uncached_.resize(lanes::kLanes);
  }
  std::array<double, lanes::kLanes> uy;
  for (int k = 0; k < padded; ++k) uy[std::size_t(k)] = u_of(k).y;
  std::array<Choice, lanes::kLanes> choices;
  choose_many(std::span(uy).first(std::size_t(padded)), choices);
  for (int k = 0; k < padded; ++k) {
    const Vec2d uk = u_of(k);
    const Choice& choice = choices[std::size_t(k)];
    chunk.triangle[k] = static_cast<std::uint32_t>(choice.triangle);
    const View* seen;
    if (by_slot) {
      seen = &cache_[choice.triangle];
      in.slot.v[k] = double(choice.triangle);
    } else {
      View* spill = uncached_.empty() ? nullptr : &uncached_[std::size_t(k)];  // read past the cache only
      seen = &view(choice.triangle, spill);
      put_triangle(in, k, choice.triangle, choice.probability, *seen);
    }
    in.by_solid_angle[k] = seen->by_solid_angle ? -1 : 0;
    if (seen->by_solid_angle) {
      in.angle.v[k] = seen->spherical.warp_angle(uk.x);
      in.v.v[k] = choice.v;
      in.b1.v[k] = in.b2.v[k] = 0.0;  // read but not used
      chunk.b0[k] = 0.0;  // set from the kernel's b1, b2 by emission_texel
    } else {
      const Vec3d b = sample_triangle_uniform({uk.x, choice.v});
      chunk.b0[k] = b.x;
      in.b1.v[k] = b.y;
      in.b2.v[k] = b.z;
      in.angle.v[k] = in.v.v[k] = 0.0;  // read but not used
    }
  }
  kernels.sample(in, count, chunk.out);
}

TexCoords EmitterSampler::texcoord_of(const light_sample_lanes::Chunk& chunk, int k) const {
  const double b1 = chunk.out.b1.v[k], b2 = chunk.out.b2.v[k];
  const double b0 = chunk.in.by_solid_angle[k] ? 1.0 - b1 - b2 : chunk.b0[k];
  return texcoords_at(flat_, emitter_.triangles[chunk.triangle[k]].primitive, float(b0), float(b1), float(b2));
}

Vec3d EmitterSampler::emission_texel(const light_sample_lanes::Chunk& chunk, int k) const {
  return Vec3d(textures_->emission(emitter_.material, texcoord_of(chunk, k)));
}

void EmitterSampler::sample_many(std::span<const Vec2d> u, std::span<LightSample> out) {
  light_sample_lanes::Chunk chunk;
  for (std::size_t first = 0; first < u.size(); first += light_sample_lanes::kLanes) {
    draw(u.subspan(first), chunk);
    const light_sample_lanes::Output& lane = chunk.out;
    for (int k = 0; k < chunk.count; ++k) {
      LightSample& sample = out[first + std::size_t(k)];
      sample.valid = lane.valid[k] != 0;
      if (!sample.valid) continue;
      const EmitterTriangle& t = emitter_.triangles[chunk.triangle[k]];
      sample.light_point.point = {lane.point.x.v[k], lane.point.y.v[k], lane.point.z.v[k]};
      sample.light_point.geometric_normal = t.frame.geometric_normal;
      sample.light_point.error_bound = lane.error_bound.v[k];
      sample.distance = lane.distance.v[k];
      sample.direction = {lane.direction.x.v[k], lane.direction.y.v[k], lane.direction.z.v[k]};
      sample.radiance_over_pdf = {lane.radiance_over_pdf.x.v[k], lane.radiance_over_pdf.y.v[k],
                                  lane.radiance_over_pdf.z.v[k]};
      sample.texcoord.reset();
      if (emission_texture_ && lane.front[k]) sample.texcoord = texcoord_of(chunk, k);
    }
  }
}

Ray shadow_ray_to_sample(const RayOffset& policy, const Vec3f& origin, const LightSample& sample) {
  const Vec3f target = offset_ray_origin(policy, sample.light_point, Vec3d(origin) - sample.light_point.point);
  const Vec3d span = Vec3d(target) - Vec3d(origin);
  const double length = glm::length(span);
  Ray ray;
  ray.origin = origin;
  ray.direction = length > 0.0 ? Vec3f(span / length) : Vec3f(sample.direction);
  // shadow_ray_tfar(policy, origin, target), whose distance is `length` (the same operations): not
  // computed twice.
  const double tfar = policy.mode == RayOffset::Mode::fixed
                          ? length - policy.epsilon
                          : ray_offset_detail::robust_shadow_tfar(
                                length, std::max({std::abs(double(target.x)), std::abs(double(target.y)),
                                                  std::abs(double(target.z))}));
  ray.tfar = length > 0.0 ? static_cast<float>(tfar) : 0.0f;
  return ray;
}

}  // namespace rt
