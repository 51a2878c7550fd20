#pragma once
// Area lights: the emissive triangles of a scene (materials with Material::emits_light), grouped
// into one emitter per material, and the light samples drawn on them at a shading point.
// World space, double precision. The radiometry and the estimator are in docs/area-lights.md.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "rt/flatten/flatten.h"
#include "rt/render/ray_offset.h"
#include "rt/render/sampling.h"
#include "rt/render/texture.h"
#include "rt/scene/framing.h"
#include "rt/scene/scene.h"

namespace rt {

namespace light_sample_lanes {
struct Input;
struct Chunk;
}  // namespace light_sample_lanes

// How a light sample picks its point on the chosen triangle. area: uniformly by area. solid_angle:
// uniformly in the solid angle the triangle subtends (Arvo 1995), which removes the 1/r^2 and
// cos(theta') of the emitter from the estimator. automatic: solid angle where it pays, i.e. where
// the triangle subtends between kMinSolidAngleSampling and kMaxSolidAngleSampling, else area.
enum class LightSampling { automatic, area, solid_angle };
std::string_view to_string(LightSampling sampling);
// Parses "auto", "area" or "solid-angle"; throws InputError otherwise.
LightSampling parse_light_sampling(std::string_view text);

// The solid angles (steradians) between which LightSampling::automatic samples by solid angle:
// below, area sampling is already nearly uniform in solid angle and cheaper; above (almost a
// hemisphere), the spherical triangle's construction loses accuracy (pbrt-v4's thresholds).
inline constexpr double kMinSolidAngleSampling = 3e-4;
inline constexpr double kMaxSolidAngleSampling = 6.22;

// One emissive triangle in world space (double, from the float32 flattened vertices).
struct EmitterTriangle {
  Vec3d p0, p1, p2;
  Vec3d normal;              // unit, towards the front: (p1 - p0) x (p2 - p0)
  double area = 0.0;         // scene units^2
  std::uint32_t primitive = 0;  // index in FlatScene::triangles
  TriangleFrame frame;       // make_triangle_frame: for the light samples' surface points
};

// The triangles of one emissive material, chosen among by power: triangle i with probability
// cdf[i] - cdf[i - 1], proportional to its area, times (texture_weighted) an estimate of its
// emission texture's mean luminance. The texture itself modulates each sample, so the estimate only
// steers samples and the estimator stays unbiased.
struct Emitter {
  std::uint32_t material = 0;  // index into Scene::materials
  std::vector<EmitterTriangle> triangles;
  std::vector<double> cdf;     // cumulative, cdf.back() == 1
  double area = 0.0;           // scene units^2
  // Radiant flux leaving the front sides, pi * area * emission (linear RGB, in radiance units
  // times scene units^2), before any texture.
  Vec3d power{0.0};
  Bounds3d bounds;             // of the vertices
  bool texture_weighted = false;  // the cdf includes the emission texture (collect_area_lights)
  // All triangles lie in one plane and face the same way: a point on or behind it receives nothing.
  bool planar = false;
  Vec3d plane_normal{0.0};     // unit, the front side's
  double plane_offset = 0.0;   // plane: dot(plane_normal, x) == plane_offset
};

// Every emitter of a scene, in material order.
struct AreaLights {
  std::vector<Emitter> emitters;
  std::size_t triangle_count = 0;  // emissive triangles over all emitters
  bool empty() const { return emitters.empty(); }
};

// The scene's emitters: every flattened triangle whose material emits light with a non-black
// emission. With `textures`, a textured emitter's triangles are weighted by their area times the
// mean luminance of its emission texture at four points of the triangle, plus 1% of the largest
// such mean (so that every triangle keeps a chance: a glow map is mostly black, and its bright
// details get the samples). Throws InputError naming scene.source when a sphere has an emitting
// material (area lights are triangles) or when the emitter list would not fit in memory (checked
// before allocating).
AreaLights collect_area_lights(const Scene& scene, const FlatScene& flat, const TextureSampler* textures = nullptr);

// Whether point `point` (world space) is strictly in front of a planar emitter; true for
// non-planar ones. The same test decides the "behind the emitter" rule and the estimator, so
// pruning by it cannot change a pixel.
bool in_front_of_emitter(const Emitter& emitter, const Vec3d& point);

// Whether the whole emitter lies on or below the plane through `point` with normal `normal`
// (unit, world space): no sample of it can have n.l > 0 there. Decided on the emitter's bounds.
bool emitter_below_horizon(const Emitter& emitter, const Vec3d& point, const Vec3d& normal);

// A point sampled on an emitter as seen from a shading point, with what the estimator needs.
struct LightSample {
  bool valid = false;        // false: no direction (the point lies on the triangle's plane or an edge)
  Vec3d direction{0.0};      // unit, world space, from the shading point towards the sample
  double distance = 0.0;     // world units, from the shading point to the sample
  // Emitted radiance at the sample divided by the solid-angle density of the sample direction
  // (linear RGB, radiance x steradians): zero when the sample sees the triangle's back. Without the
  // emission texture: when the emitter has one, `texcoord` says where to sample it, and the caller
  // multiplies it in once the sample's term is known not to vanish (a lookup saved where n.l <= 0).
  Vec3d radiance_over_pdf{0.0};
  std::optional<TexCoords> texcoord;
  SurfacePoint light_point;  // the sample on the emitter, for the shadow ray's far end
};

// Draws the light samples of one emitter seen from one shading point. Sample u (in [0, 1)^2, one
// point of cmj_sample) picks the triangle with u.y through the power cdf, and u.y rescaled to that
// triangle's interval picks the point together with u.x, by area or by solid angle as `sampling`
// says. What depends only on (point, triangle), the spherical triangle and the choice of strategy,
// is set up once for each of the first kCachedTriangles triangles and reused by all the samples
// of the hit. With `textures` and an emission texture, samples carry their texcoord (nullptr:
// the texture is ignored). `spherical`, where not null, holds SphericalTriangle(point, p0, p1, p2)
// of the first min(kCachedTriangles, size) triangles, set up by the caller (for many points at
// once: SphericalTriangle::set_up_many), so that none is set up here. Deterministic.
class EmitterSampler {
 public:
  EmitterSampler(const Emitter& emitter, const FlatScene& flat, const Scene& scene, const TextureSampler* textures,
                 const Vec3d& point, LightSampling sampling, const SphericalTriangle* spherical = nullptr);
  LightSample sample(Vec2d u);
  // sample(u[k]) into out[k] for every k (out.size() >= u.size()), bit for bit where valid (of an
  // invalid sample only `valid` is set), with the warp's arithmetic done several samples at a time
  // in SIMD lanes: draw's lanes, copied out.
  void sample_many(std::span<const Vec2d> u, std::span<LightSample> out);
  // The samples of the first min(u.size(), kLanes) points of u, left in lanes
  // (light_sample_lanes.h; the renderer's private header): what sample gives, without the texture.
  void draw(std::span<const Vec2d> u, light_sample_lanes::Chunk& chunk);
  // Whether the emitter's emission has a texture: a drawn sample's radiance is then multiplied
  // by emission_texel(chunk, k) (where valid and front-facing) before use.
  bool has_emission_texture() const { return emission_texture_; }
  Vec3d emission_texel(const light_sample_lanes::Chunk& chunk, int k) const;

  static constexpr std::size_t kCachedTriangles = 4;

 private:
  struct View {  // the triangle as seen from the point
    View() = default;
    explicit View(SphericalTriangle::Unset unset) : spherical(unset) {}  // spherical read only once set
    bool by_solid_angle = false;
    SphericalTriangle spherical;
    // Where by_solid_angle: the emission over the pdf of a direction, the same for every sample
    // of the triangle (linear RGB, radiance x steradians; weigh's value).
    Vec3d radiance_over_pdf{0.0};
  };
  // Whether `triangle` is sampled by solid angle if its spherical triangle allows, and the view
  // that spherical triangle gives, written into `view` in place (a View built on the stack and
  // copied had its flag, just stored, read back by the copy's wide loads: a store-forwarding
  // stall); view_of does both for one triangle. The first kCachedTriangles triangles' views are
  // set up together, on the first sample that needs one of them.
  bool needs_spherical(const EmitterTriangle& triangle) const;
  void set_view(std::size_t triangle, const SphericalTriangle& spherical, View& view) const;
  View view_of(std::size_t triangle) const;
  // The cached views, from the caller's spherical triangles (`seen`, see the constructor) or set up here.
  void view_cached_triangles(const SphericalTriangle* seen = nullptr);
  // The triangle that u.y picks through the cdf, its probability and u.y rescaled to its interval.
  struct Choice {
    std::size_t triangle = 0;
    double probability = 0.0, v = 0.0;
  };
  Choice choose(double uy) const;
  // choose(uy[k]) into out[k], bit for bit, in SIMD lanes for short cdfs.
  void choose_many(std::span<const double> uy, std::span<Choice> out) const;
  // How triangle i is seen: from the cache for the first kCachedTriangles, else into *uncached.
  const View& view(std::size_t i, View* uncached);
  // A valid sample's radiance over pdf and texcoord, from its surface point, direction and
  // distance and its barycentrics b.
  void weigh(LightSample& sample, const EmitterTriangle& t, const Choice& choice, const View& view,
             const Vec3d& b) const;
  // Triangle `triangle`'s per-triangle inputs of the lanes, with its probability and view, as entry
  // `entry` (a slot or a lane).
  void put_triangle(light_sample_lanes::Input& in, int entry, std::size_t triangle, double probability,
                    const View& seen) const;
  // The texture coordinates of lane k of a drawn chunk.
  TexCoords texcoord_of(const light_sample_lanes::Chunk& chunk, int k) const;

  const Emitter& emitter_;
  const FlatScene& flat_;
  const Scene& scene_;
  const TextureSampler* textures_;
  bool emission_texture_;  // the emitter's emission has a texture the samples look up
  Vec3d point_;
  LightSampling sampling_;
  std::array<View, kCachedTriangles> cache_{View(SphericalTriangle::Unset{}), View(SphericalTriangle::Unset{}),
                                             View(SphericalTriangle::Unset{}), View(SphericalTriangle::Unset{})};
  bool cached_ = false;  // cache_ is set
  std::vector<View> uncached_;  // draw's views of triangles past the cache, one per lane
};

// The shadow ray from a shading point to a light sample: from `origin` (already offset off the
// shading surface) to the sample moved off its emitter towards the origin by the sample's error
// bound, stopping short as for point lights (shadow_ray_tfar). tfar <= 0: the sample is closer
// than that margin, nothing can be in between.
Ray shadow_ray_to_sample(const RayOffset& policy, const Vec3f& origin, const LightSample& sample);

}  // namespace rt
