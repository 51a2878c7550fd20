#pragma once
// Hits of plain materials shaded many at a time: shade_surface's arithmetic laid out over arrays
// of hits (structure of arrays, world space, double), one stage for all lanes after another, with
// the same operations in the same order, so that every colour and every count is bit for bit
// what shade_camera_hit and find_color give (tests/test_batch_shade.cpp renders scenes both ways).
// The reflection rays of a block are traced depth by depth (a wavefront) and their hits shaded the
// same way; only the order in which the queries are made changes.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "rt/render/area_lights.h"
#include "rt/render/sampling.h"
#include "rt/render/shade.h"

namespace rt {

namespace batch_lanes {  // what the lane arithmetic (batch_lanes.h) reads of the scene

// RayOffset, as the lanes read it.
struct OriginPolicy {
  bool fixed = false;    // RayOffset::Mode::fixed
  double epsilon = 0.0;  // its distance, world units
};

// What Kernels::light reads of one light (world space, double), set once per render.
struct LightLanes {
  bool directional = false, spot = false;
  double position[3], to_light[3], color[3], attenuation[3], spot_direction[3];
  double spot_cos_outer = 0.0, cone_width = 0.0;
  double extent = 0.0;  // the largest coordinate magnitude of the position (robust_shadow_tfar)
};

struct Kernels;

}  // namespace batch_lanes

// kLanes doubles, one per hit of a batch.
template <int kLanes>
struct alignas(64) LaneArray {
  double v[kLanes];
};

template <int kLanes>
struct Vec3Lanes {
  LaneArray<kLanes> x, y, z;
};

// kLanes float32 points (ray origins).
template <int kLanes>
struct Vec3fLanes {
  alignas(64) float x[kLanes], y[kLanes], z[kLanes];
};

// Shades the hits of render_image's blocks. A hit is batched when it lies on a triangle and its
// material is plain (no texture, surface map, glass, blend alpha or light emission), traced
// without a --debug-pixel trace; other hits take shade_camera_hit or shade_hit, as before. Point
// lights are computed in lanes; area lights' terms per hit by shade.cpp's code, from the lanes'
// surface.
class BatchShader {
 public:
  static constexpr int kLanes = 16;  // a camera packet of render_image (4 x 4 pixels)
  // The largest area light whose views the lanes set up (EmitterSampler's cache holds as many).
  static constexpr std::size_t kViewedTriangles = EmitterSampler::kCachedTriangles;

  // The shading arithmetic of up to kLanes hits; one per render thread, reused.
  struct Lanes {
    int count = 0;
    bool reflections = false;  // some lane may trace a reflection ray: reflected, reflection_origin are set
    bool highlights = false;   // some lane evaluates the highlight (highlight[i] != 0)
    std::array<std::uint32_t, kLanes> material{};
    Vec3Lanes<kLanes> point, geometric_normal, normal, direction;  // normal: shading, unit; direction: unit
    LaneArray<kLanes> error_bound;  // SurfacePoint::error_bound
    Vec3Lanes<kLanes> ambient, diffuse, specular;  // the material's colours at each lane
    LaneArray<kLanes> shininess;
    alignas(32) std::int64_t highlight[kLanes];  // PlainMaterial::highlight: all ones or 0
    Vec3Lanes<kLanes> reflected;       // the mirror direction (reflect_direction), unit
    Vec3fLanes<kLanes> reflection_origin;  // offset_ray_origin along it
    struct Light {  // one light's unshadowed term, direction and shadow ray at each lane
      Vec3Lanes<kLanes> term, to_light;
      alignas(32) std::int64_t zero_term[kLanes];  // all ones where term == Vec3d(0.0), else 0
      LaneArray<kLanes> geometric_cosine;    // geometric normal . to_light (the convex rule)
      alignas(32) std::int64_t on_point[kLanes];  // nonzero: the light is at the point (no direction)
      Vec3fLanes<kLanes> shadow_origin;      // offset_ray_origin along to_light
      LaneArray<kLanes> shadow_distance;     // shadow_ray_tfar (or +inf), before rounding to float32
    };
    std::vector<Light> lights;  // parallel to Scene::lights
    // The small area lights' spherical triangles (EmitterSampler's `spherical`), set up for all
    // lanes together so that several points share the SIMD lanes: [v] for emitter
    // small_emitters_[v], lane i's triangles at spherical[first[i]...] where first[i] >= 0 (the
    // lanes that draw samples of it).
    struct EmitterViews {
      std::array<SphericalTriangle, kViewedTriangles * kLanes> spherical;
      std::array<std::int16_t, kLanes> first{};
    };
    std::vector<EmitterViews> emitter_views;
  };

  // A reflection ray of depth >= 1 and what becomes of it.
  // Its fields are set one by one where it is made (shade_lane), not zeroed first: every reflection
  // ray makes one.
  struct Secondary {
    Secondary() {}  // user-provided, so that emplace_back() does not zero it first (a memset per ray)
    Ray ray;
    Hit hit;
    Vec3d throughput;    // the product of the reflection weights up to this ray, its own included
    Vec3d weight;        // its reflection weight: the parent adds weight * colour
    std::uint64_t path_seed;  // its pixel's (pixel_path_seed), for area-light samples
    std::int32_t parent;  // the pixel in PendingShading (depth 1), else the index in the previous wave
    std::int32_t child;   // its own reflection ray in the next wave, or -1
    bool batched;         // shaded here (local holds its lights' sum); else color came from shade_hit
    Vec3d local;          // emission plus its unshadowed-and-unblocked light terms
    Color color;          // find_color of the ray
  };

  // Everything one render thread reuses from block to block.
  struct Workspace {
    std::array<std::int8_t, kLanes> lane_of{};  // per camera pixel of the prepared packet: its lane, or -1
    Lanes lanes;
    std::vector<std::vector<Secondary>> waves;  // [d]: the reflection rays of depth d (index 0 unused)
  };

  explicit BatchShader(const ShadingContext& context);

  // False when no hit of the scene can be batched: every pixel takes shade_camera_hit.
  bool enabled() const { return enabled_; }

  // Starts a block of camera pixels: no reflection ray waits yet.
  void start_block(Workspace& work) const;

  // Cache hints for what prepare gathers of `hits`, in two steps some work apart: the triangles'
  // vertex indices and materials, then (reading those indices) their vertices and normals.
  void prefetch_triangles(std::span<const Hit> hits) const;
  void prefetch_vertices(std::span<const Hit> hits) const;

  // Computes the shading arithmetic of the batchable camera hits among `hits` (at most kLanes; the
  // closest hits of `rays`, a packet of the block); pixels with `unbatched[k]` set are left out.
  void prepare(std::span<const Ray> rays, std::span<const Hit> hits, std::span<const bool> unbatched,
               Workspace& work) const;

  // shade_camera_hit for pixel k of the prepared packet, when work.lane_of[k] >= 0: appends its
  // pixel to `pending` and counts as shade_camera_hit does (`path_seed` as there); its reflection
  // ray waits in work.waves[1] until trace_reflections traces the block's.
  void finish_camera_hit(Workspace& work, int k, const Ray& ray, const Hit& hit, std::uint64_t path_seed,
                         RayCounts& counts, PendingShading& pending) const;

  // The colour of a camera ray that hit nothing: the background, as finish_camera_hit gives it for
  // shade_camera_hit's record of the miss.
  Color background() const { return background_; }

  // Traces the block's reflection rays depth by depth, shades their hits (shadow rays traced one by
  // one, as find_color traces them) and sets each reflecting pixel's PendingShading::reflection.
  void trace_reflections(Workspace& work, RayCounts& counts, PendingShading& pending) const;

 private:
  // A plain material's colours as shade_surface derives them (double, linear RGB).
  struct PlainMaterial {
    bool batched = false;
    bool flip_back_face = false;  // BackFace::flipped: the shading normal turns to the viewer
    bool highlight = false;       // the specular term is evaluated (MaterialPlan::specular, or unpruned)
    bool reflects = false;        // MaterialPlan::reflection
    bool reflects_light = false;  // reflects and reflective != (0, 0, 0): a reflection ray is traced
    double shininess = 0.0;
    Vec3d ambient{0.0}, diffuse{0.0}, specular{0.0}, reflective{0.0}, emission{0.0};
  };
  bool batchable(const Hit& hit) const;
  // FlatScene::material_ids[triangle], from the runs below when the scene has few of them.
  std::uint32_t material_of_triangle(std::uint32_t triangle) const;
  // The arithmetic of lanes.count hits at ray depth `depth` (rays[i], hits[i] batchable).
  void compute_lanes(Lanes& lanes, const Ray* rays, const Hit* hits, int depth) const;
  void compute_surfaces(Lanes& lanes, const Ray* rays, const Hit* hits, int depth) const;
  void compute_light(Lanes& lanes, std::size_t light) const;
  // lanes.emitter_views: for each of small_emitters_, the spherical triangles of the lanes that
  // will draw its samples (shade.cpp's add_area_light_terms: the emitter-level rules pass).
  void compute_emitter_views(Lanes& lanes) const;
  // The light terms of lane i at `depth` through `sink` (lit / query, as shade_surface's Shadows),
  // the point lights' and then the area lights' (samples drawn from `path_seed`), then its
  // reflection ray, if any, appended to `next` (parent `parent`); returns its index or -1.
  template <class Sink>
  std::int32_t shade_lane(const Lanes& lanes, int i, int depth, const Ray& ray, const Hit& hit,
                          const Vec3d& throughput, std::uint64_t path_seed, std::int32_t parent, RayCounts& counts,
                          Sink& sink, std::vector<Secondary>& next) const;
  // The area lights' terms of lane i through `sink`, as shade_surface adds them.
  template <class Sink>
  void add_area_lights(const Lanes& lanes, int i, int depth, std::uint64_t path_seed, RayCounts& counts,
                       Sink& sink) const;
  void shade_wave(Workspace& work, int depth, RayCounts& counts) const;

  const ShadingContext& context_;
  std::size_t light_count_;  // Scene::lights.size()
  const batch_lanes::Kernels& kernels_;  // the AVX2 or the baseline build
  batch_lanes::OriginPolicy origin_policy_;
  std::vector<batch_lanes::LightLanes> lights_;  // parallel to Scene::lights
  bool enabled_ = false;
  Color background_;  // Settings::background
  std::vector<PlainMaterial> materials_;
  // The runs of equal FlatScene::material_ids (flattening writes a model's triangles together):
  // run r starts at triangle run_first_[r] and has material run_material_[r]. With at most
  // kMaxRuns of them a hit's material is found in these few bytes instead of by a cache miss in
  // the per-triangle array (the 871k-triangle torus's render / re-trace: diffuse 1.26 -> 1.25,
  // Whitted 1.22 -> 1.19; the dragon's, whose arrays mostly stay in cache, unchanged); otherwise
  // both are empty.
  static constexpr std::size_t kMaxRuns = 8;
  std::vector<std::uint32_t> run_first_, run_material_;
  // The area lights whose views the lanes set up together: among the first kViewedEmitters, those
  // of at most kViewedTriangles triangles that contribute, unless every sample is drawn by area.
  static constexpr std::size_t kViewedEmitters = 4;
  std::vector<std::size_t> small_emitters_;
};

}  // namespace rt
