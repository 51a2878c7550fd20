#include "rt/accel/embree_accel.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <string>

#include <fmt/format.h>
#if RT_EMBREE_MAJOR >= 4
#include <embree4/rtcore.h>
#else
#include <embree3/rtcore.h>
#endif

#include "rt/accel/reference_accel.h"
#include "triangle_clusters.h"
#include "rt/core/error.h"
#include "rt/core/memory.h"

namespace rt {

namespace {

const char* error_name(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE: return "no error";
    case RTC_ERROR_UNKNOWN: return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
    default: break;  // Embree 4.3 added a GPU-only code
  }
  return "unrecognised error";
}

// Fills Embree's ray layout. mask must be all ones because Debian builds Embree with ray masks
// enabled (a zero mask would silently hit nothing); flags = 0 and time = 0 as no motion blur.
void fill_ray(const Ray& ray, RTCRay& out) {
  out.org_x = ray.origin.x;
  out.org_y = ray.origin.y;
  out.org_z = ray.origin.z;
  out.tnear = ray.tnear;
  out.dir_x = ray.direction.x;
  out.dir_y = ray.direction.y;
  out.dir_z = ray.direction.z;
  out.time = 0.0f;
  out.tfar = ray.tfar;
  out.mask = 0xFFFFFFFFu;
  out.id = 0;
  out.flags = 0;
}

// Whether Embree may be given `ray`. Embree 3.13 asserts RayK::valid() (every origin and direction
// coordinate within +-FLT_LARGE = 1.844e18, tnear and tfar not NaN) and tnear >= 0 on every query,
// and Debian builds it with assertions on: such a ray would abort the process. One that fails
// (a NaN from a degenerate computation upstream) hits nothing and is blocked by nothing instead.
bool embree_accepts(const Ray& ray) {
  constexpr float kLargest = 1.844E18f;  // Embree's FLT_LARGE (common/math/constants.h)
  const auto within = [](const Vec3f& v) {
    return std::abs(v.x) <= kLargest && std::abs(v.y) <= kLargest && std::abs(v.z) <= kLargest;
  };
  return within(ray.origin) && within(ray.direction) && ray.tnear >= 0.0f && !std::isnan(ray.tfar);
}

// Lane `lane` of a 16-ray packet, as fill_ray fills a single ray.
void fill_packet_lane(const Ray& ray, unsigned lane, RTCRay16& out) {
  out.org_x[lane] = ray.origin.x;
  out.org_y[lane] = ray.origin.y;
  out.org_z[lane] = ray.origin.z;
  out.tnear[lane] = ray.tnear;
  out.dir_x[lane] = ray.direction.x;
  out.dir_y[lane] = ray.direction.y;
  out.dir_z[lane] = ray.direction.z;
  out.time[lane] = 0.0f;
  out.tfar[lane] = ray.tfar;
  out.mask[lane] = 0xFFFFFFFFu;
  out.id[lane] = lane;
  out.flags[lane] = 0;
}

// Lane `lane` of a 16-ray packet as a lane the query must skip: besides its 0 in the valid mask,
// an empty segment (tnear 1 > tfar 0) of a ray Embree accepts. On a CPU without 16-wide kernels
// (AVX2, no AVX-512) Embree 3.13 splits a 16-ray packet by its stream code, which ignores the
// mask and traces every lane with tnear <= tfar, asserting each one valid.
void fill_packet_lane_off(unsigned lane, RTCRay16& out) {
  fill_packet_lane(Ray{Vec3f(0.0f), Vec3f(0.0f, 0.0f, 1.0f), 1.0f, 0.0f}, lane, out);
}

RTCBuildQuality to_embree(EmbreeQuality quality) {
  switch (quality) {
    case EmbreeQuality::low: return RTC_BUILD_QUALITY_LOW;
    case EmbreeQuality::medium: return RTC_BUILD_QUALITY_MEDIUM;
    case EmbreeQuality::high: return RTC_BUILD_QUALITY_HIGH;
  }
  return RTC_BUILD_QUALITY_MEDIUM;
}

// The closest hit so far of one ray, ordered by (t, primitive index) like the reference.
struct BestHit {
  double t;       // t of the hit accepted so far (the ray's tfar until one is)
  unsigned prim;  // its FlatScene primitive number; RTC_INVALID_GEOMETRY_ID before any hit
  double b1, b2;  // its barycentrics

  // Accepts a candidate that is strictly closer, or equally close with a lower index: the closest
  // hit then does not depend on BVH layout or traversal order.
  bool offer(double candidate_t, unsigned candidate_prim, double candidate_b1, double candidate_b2) {
    if (!(candidate_t < t || (candidate_t == t && candidate_prim < prim))) return false;
    t = candidate_t;
    prim = candidate_prim;
    b1 = candidate_b1;
    b2 = candidate_b2;
    return true;
  }
};

constexpr unsigned kPacketSize = 16;

// Embree 4.0 renamed the query context (RTCIntersectContext became RTCRayQueryContext) and moved
// the query's flags and context filter out of it into RTCIntersectArguments and
// RTCOccludedArguments, which rtcIntersect*/rtcOccluded* take last instead of the context first.
// Query hides that difference; it is the only part of this file that depends on the version.
#if RTC_VERSION_MAJOR >= 4
using QueryContext = RTCRayQueryContext;
constexpr RTCSceneFlags kSceneFilterFlag = RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS;
#else
using QueryContext = RTCIntersectContext;
constexpr RTCSceneFlags kSceneFilterFlag = RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION;
#endif

// One query: its context (whose address reaches the callbacks), the context filter that orders
// closest hits (null: none, as for occlusion) and whether the rays are coherent (packets).
class Query {
 public:
  Query(QueryContext& context, RTCFilterFunctionN filter, bool coherent) : context_(&context) {
#if RTC_VERSION_MAJOR >= 4
    rtcInitRayQueryContext(&context);
    filter_ = filter;
    // Embree 4 calls an argument filter only for geometries that ask for it, or for all with
    // INVOKE_ARGUMENT_FILTER; Embree 3 called the context filter for all.
    flags_ = static_cast<RTCRayQueryFlags>(
        (coherent ? RTC_RAY_QUERY_FLAG_COHERENT : RTC_RAY_QUERY_FLAG_INCOHERENT) |
        (filter ? RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER : RTC_RAY_QUERY_FLAG_NONE));
#else
    rtcInitIntersectContext(&context);
    context.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    context.filter = filter;
#endif
  }

#if RTC_VERSION_MAJOR >= 4
  void intersect(RTCScene scene, RTCRayHit& ray) {
    RTCIntersectArguments arguments = intersect_arguments();
    rtcIntersect1(scene, &ray, &arguments);
  }
  void intersect(const int* valid, RTCScene scene, RTCRayHit16& rays) {
    RTCIntersectArguments arguments = intersect_arguments();
    rtcIntersect16(valid, scene, &rays, &arguments);
  }
  void occluded(RTCScene scene, RTCRay& ray) {
    RTCOccludedArguments arguments = occluded_arguments();
    rtcOccluded1(scene, &ray, &arguments);
  }
  void occluded(const int* valid, RTCScene scene, RTCRay16& rays) {
    RTCOccludedArguments arguments = occluded_arguments();
    rtcOccluded16(valid, scene, &rays, &arguments);
  }

 private:
  // Only the arguments of the call made are filled (a query is one call).
  RTCIntersectArguments intersect_arguments() const {
    RTCIntersectArguments arguments;
    rtcInitIntersectArguments(&arguments);
    arguments.flags = flags_;
    arguments.context = context_;
    arguments.filter = filter_;
    return arguments;
  }
  RTCOccludedArguments occluded_arguments() const {
    RTCOccludedArguments arguments;
    rtcInitOccludedArguments(&arguments);
    arguments.flags = flags_;
    arguments.context = context_;
    arguments.filter = filter_;
    return arguments;
  }

  RTCFilterFunctionN filter_;
  RTCRayQueryFlags flags_;
#else
  void intersect(RTCScene scene, RTCRayHit& ray) { rtcIntersect1(scene, context_, &ray); }
  void intersect(const int* valid, RTCScene scene, RTCRayHit16& rays) { rtcIntersect16(valid, scene, context_, &rays); }
  void occluded(RTCScene scene, RTCRay& ray) { rtcOccluded1(scene, context_, &ray); }
  void occluded(const int* valid, RTCScene scene, RTCRay16& rays) { rtcOccluded16(valid, scene, context_, &rays); }

 private:
#endif
  QueryContext* context_;
};

// Embree passes our context's address to filters and user-geometry callbacks, so the fields after
// it travel along (the pattern of Embree's own tutorials). Each ray's id indexes its BestHit: 0 for
// a single ray, the lane for a packet. Occlusion queries pass a plain context.
struct HitContext {
  QueryContext embree;
  BestHit* best;  // one per ray of the query
  const ShearedRay* sheared;  // one per ray, for the watertight kernel (null with the others)

  BestHit& of(const RTCRayN* ray, unsigned n, unsigned i) const {
    return best[RTCRayN_id(const_cast<RTCRayN*>(ray), n, i)];
  }
};

// Embree culls boxes and (native) candidates beyond the ray's tfar; after accepting a hit at t the
// callbacks set tfar 2^-20 relative (~16 ulps) beyond it, so an equally close candidate elsewhere
// still reaches them: Embree's own depth test T <= |den| * tfar on unnormalised values can fail by
// rounding for a candidate whose t equals tfar exactly. BestHit::offer decides by exact
// comparison instead, and intersect() reports BestHit::t.
float widened(double t) {
  const auto f = static_cast<float>(t);
  return f + std::abs(f) * 0x1p-20f;
}

// What a geometry's callbacks read (its Embree user pointer): the world-space scene, the box
// padding of user geometries, and, for the triangle geometries of a scene with a surface test,
// which FlatScene triangle each primitive is and the test.
struct UserGeometryData {
  const FlatScene* flat = nullptr;
  float box_padding = 0.0f;  // world-space units, added on every side of each primitive's box
  const std::uint32_t* triangles = nullptr;  // FlatScene index of each primitive; null: the same index
  const SurfaceTest* test = nullptr;         // set on the geometry of the tested triangles only
  const TriangleCluster* clusters = nullptr;  // the watertight kernel's primitives, when it runs
  IntersectCluster intersect_cluster = nullptr;  // and its build for this CPU
};

// An occlusion query's context: Embree's, and each ray's set-up for the watertight kernel, by id.
struct ShadowContext {
  QueryContext embree;
  const ShearedRay* sheared;
};

// FlatScene triangle of primitive `prim` of the geometry whose data is `data`.
unsigned flat_triangle(const UserGeometryData* data, unsigned prim) {
  return data && data->triangles ? data->triangles[prim] : prim;
}

// Context intersection filter of the native triangle kernel: Embree offers candidates one after
// another, having set the ray's tfar to the candidate's t. kMapped: the scene's triangles are
// split into an untested and a tested geometry (UserGeometryData::triangles numbers them).
template <bool kMapped>
void order_hits(const RTCFilterFunctionNArguments* args) {
  auto* context = reinterpret_cast<HitContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    float& tfar = RTCRayN_tfar(args->ray, args->N, i);
    unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    if constexpr (kMapped) prim = flat_triangle(static_cast<const UserGeometryData*>(args->geometryUserPtr), prim);
    if (context->of(args->ray, args->N, i).offer(tfar, prim, RTCHitN_u(args->hit, args->N, i),
                                                 RTCHitN_v(args->hit, args->N, i)))
      tfar = widened(tfar);
    else
      args->valid[i] = 0;
  }
}

Vec3d ray_direction(const RTCRayN* ray, unsigned n, unsigned i) {
  auto* r = const_cast<RTCRayN*>(ray);
  return {RTCRayN_dir_x(r, n, i), RTCRayN_dir_y(r, n, i), RTCRayN_dir_z(r, n, i)};
}

// Whether the SurfaceTest in `data` lets a candidate on FlatScene triangle `prim` count (occlusion:
// block the ray).
template <bool kOcclusion>
bool surface_counts(const UserGeometryData* data, unsigned prim, float b1, float b2, const Vec3d& direction) {
  return kOcclusion ? data->test->blocks(prim, b1, b2, direction) : data->test->hit_counts(prim, b1, b2, direction);
}

// Geometry filters of the native tested triangles (Embree's documented way to cut out surfaces,
// run before the context filter): a candidate where the surface is not there for the ray is
// rejected and traversal goes on behind it.
template <bool kOcclusion>
void surface_filter(const RTCFilterFunctionNArguments* args) {
  const auto* data = static_cast<const UserGeometryData*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const unsigned prim = flat_triangle(data, RTCHitN_primID(args->hit, args->N, i));
    const float b1 = RTCHitN_u(args->hit, args->N, i), b2 = RTCHitN_v(args->hit, args->N, i);
    if (!surface_counts<kOcclusion>(data, prim, b1, b2, ray_direction(args->ray, args->N, i))) args->valid[i] = 0;
  }
}

// ---------------------------------------------------------------------------------------------
// User geometries: spheres always, and triangles with the watertight kernel. Their callbacks run
// the reference's double-precision tests on the FlatScene data.

// Geometry IDs. Tested triangles get a geometry of their own only when the scene has some.
constexpr unsigned kTriangleGeometry = 0, kSphereGeometry = 1, kTestedGeometry = 2;

// Embree traverses user geometry with its fast, non-conservative box test (Embree 3.13 compiles
// BVH4VirtualIntersector1 with robust = false whatever the scene flags say), so a ray through a
// triangle's vertex or edge can be culled at a box face it only touches: unpadded, 4,381 of the
// watertightness test's 210,000 rays escaped. The slab distances that test computes,
// fl(lower * rdir - fl(org * rdir)) with an approximate reciprocal rdir, are off by at most a few
// float32 ulps of |lower| + |org| in world units; boxes padded by 2^-18 times the scene's largest
// coordinate magnitude M absorb that error (with a margin of 4 and more) for every ray whose origin
// lies within 7 M of the world origin: all secondary rays, and camera rays unless the eye is far
// outside the scene. The padding only makes boxes overlap slightly more.
double max_abs_component(const Vec3d& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

float user_box_padding(const FlatScene& flat) {
  double largest = 1.0;
  for (const Vec3f& p : flat.positions) largest = std::max(largest, max_abs_component(Vec3d(p)));
  for (const FlatSphere& sphere : flat.spheres) {
    Vec3d lower, upper;
    sphere_bounds(sphere, lower, upper);
    largest = std::max({largest, max_abs_component(lower), max_abs_component(upper)});
  }
  return static_cast<float>(largest * 0x1p-18);
}

void set_bounds(const RTCBoundsFunctionArguments* args, const Vec3f& lower, const Vec3f& upper) {
  const float pad = static_cast<const UserGeometryData*>(args->geometryUserPtr)->box_padding;
  *args->bounds_o = RTCBounds{lower.x - pad, lower.y - pad, lower.z - pad, 0.0f,
                              upper.x + pad, upper.y + pad, upper.z + pad, 0.0f};
}

void triangle_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* data = static_cast<const UserGeometryData*>(args->geometryUserPtr);
  const FlatScene& flat = *data->flat;
  const Vec3u tri = flat.triangles[flat_triangle(data, args->primID)];
  const Vec3f a = flat.positions[tri.x], b = flat.positions[tri.y], c = flat.positions[tri.z];
  set_bounds(args, glm::min(a, glm::min(b, c)), glm::max(a, glm::max(b, c)));
}

void sphere_bounds(const RTCBoundsFunctionArguments* args) {
  const FlatScene& flat = *static_cast<const UserGeometryData*>(args->geometryUserPtr)->flat;
  Vec3d lower, upper;
  sphere_bounds(flat.spheres[args->primID], lower, upper);
  // Rounded outwards to float32; the padding covers the rounding of the box itself.
  Vec3f lo, hi;
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::nextafter(static_cast<float>(lower[i]), -kInfinity);
    hi[i] = std::nextafter(static_cast<float>(upper[i]), kInfinity);
  }
  set_bounds(args, lo, hi);
}

// The double-precision test of one user primitive (index within its geometry).
bool test_primitive(unsigned geometry, const FlatScene& flat, unsigned prim, const Vec3d& origin,
                    const Vec3d& direction, double tnear, double tfar, TriangleHitD& hit) {
  if (geometry == kSphereGeometry) {
    hit = {};
    return intersect_sphere(origin, direction, tnear, tfar, flat.spheres[prim], hit.t);
  }
  const Vec3u tri = flat.triangles[prim];
  return intersect_triangle_watertight(origin, direction, tnear, tfar, Vec3d(flat.positions[tri.x]),
                                       Vec3d(flat.positions[tri.y]), Vec3d(flat.positions[tri.z]), hit);
}

Vec3d ray_origin(RTCRayN* ray, unsigned n, unsigned i) {
  return {RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i), RTCRayN_org_z(ray, n, i)};
}

template <unsigned kGeometry>
void user_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* data = static_cast<const UserGeometryData*>(args->geometryUserPtr);
  const FlatScene& flat = *data->flat;
  auto* context = reinterpret_cast<HitContext*>(args->context);
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  RTCHitN* hit_out = RTCRayHitN_HitN(args->rayhit, args->N);
  // Spheres are numbered after all triangles.
  const unsigned prim = kGeometry == kSphereGeometry ? static_cast<unsigned>(flat.triangles.size()) + args->primID
                                                     : flat_triangle(data, args->primID);
  const unsigned tested = kGeometry == kSphereGeometry ? args->primID : prim;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    TriangleHitD hit;
    BestHit& best = context->of(ray, args->N, i);
    if (!test_primitive(kGeometry, flat, tested, ray_origin(ray, args->N, i), ray_direction(ray, args->N, i),
                        RTCRayN_tnear(ray, args->N, i), best.t, hit) ||
        (data->test && !surface_counts<false>(data, prim, static_cast<float>(hit.b1), static_cast<float>(hit.b2),
                                              ray_direction(ray, args->N, i))) ||
        !best.offer(hit.t, prim, hit.b1, hit.b2))
      continue;
    RTCRayN_tfar(ray, args->N, i) = widened(hit.t);
    RTCHitN_geomID(hit_out, args->N, i) = args->geomID;
    RTCHitN_primID(hit_out, args->N, i) = args->primID;
    RTCHitN_instID(hit_out, args->N, i, 0) = args->context->instID[0];
    RTCHitN_u(hit_out, args->N, i) = static_cast<float>(hit.b1);
    RTCHitN_v(hit_out, args->N, i) = static_cast<float>(hit.b2);
  }
}

template <unsigned kGeometry>
void user_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const UserGeometryData*>(args->geometryUserPtr);
  const FlatScene& flat = *data->flat;
  const unsigned prim = kGeometry == kSphereGeometry ? args->primID : flat_triangle(data, args->primID);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    float& tfar = RTCRayN_tfar(args->ray, args->N, i);
    TriangleHitD hit;
    if (test_primitive(kGeometry, flat, prim, ray_origin(args->ray, args->N, i),
                       ray_direction(args->ray, args->N, i), RTCRayN_tnear(args->ray, args->N, i), tfar, hit) &&
        (!data->test || surface_counts<true>(data, prim, static_cast<float>(hit.b1), static_cast<float>(hit.b2),
                                             ray_direction(args->ray, args->N, i))))
      tfar = -kInfinity;
  }
}

// ---------------------------------------------------------------------------------------------
// The watertight kernel: clusters of up to eight triangles (the leaves of an Embree SAH build over
// the triangles), each one user primitive tested by intersect_cluster.

void cluster_bounds(const RTCBoundsFunctionArguments* args) {
  const TriangleCluster& cluster = static_cast<const UserGeometryData*>(args->geometryUserPtr)->clusters[args->primID];
  set_bounds(args, cluster.lower, cluster.upper);
}

void cluster_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* data = static_cast<const UserGeometryData*>(args->geometryUserPtr);
  const TriangleCluster& cluster = data->clusters[args->primID];
  auto* context = reinterpret_cast<HitContext*>(args->context);
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  RTCHitN* hit_out = RTCRayHitN_HitN(args->rayhit, args->N);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    float& tfar = RTCRayN_tfar(ray, args->N, i);
    ClusterHits hits;
    unsigned found = data->intersect_cluster(context->sheared[RTCRayN_id(ray, args->N, i)], cluster,
                                       RTCRayN_tnear(ray, args->N, i), tfar, hits);
    if (found == 0) continue;
    BestHit& best = context->of(ray, args->N, i);
    bool improved = false;
    for (; found != 0; found &= found - 1) {
      const unsigned l = unsigned(__builtin_ctz(found));
      const unsigned prim = cluster.triangle[l];
      if (data->test && !surface_counts<false>(data, prim, hits.b1[l], hits.b2[l], ray_direction(ray, args->N, i)))
        continue;
      improved |= best.offer(hits.t[l], prim, hits.b1[l], hits.b2[l]);
    }
    if (!improved) continue;
    tfar = widened(best.t);
    RTCHitN_geomID(hit_out, args->N, i) = args->geomID;
    RTCHitN_primID(hit_out, args->N, i) = args->primID;
    RTCHitN_instID(hit_out, args->N, i, 0) = args->context->instID[0];
    RTCHitN_u(hit_out, args->N, i) = static_cast<float>(best.b1);
    RTCHitN_v(hit_out, args->N, i) = static_cast<float>(best.b2);
  }
}

void cluster_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const UserGeometryData*>(args->geometryUserPtr);
  const TriangleCluster& cluster = data->clusters[args->primID];
  const ShearedRay* sheared = reinterpret_cast<const ShadowContext*>(args->context)->sheared;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    float& tfar = RTCRayN_tfar(args->ray, args->N, i);
    ClusterHits hits;
    unsigned found = data->intersect_cluster(sheared[RTCRayN_id(args->ray, args->N, i)], cluster,
                                       RTCRayN_tnear(args->ray, args->N, i), tfar, hits);
    for (; found != 0; found &= found - 1) {
      const unsigned l = unsigned(__builtin_ctz(found));
      if (!data->test || surface_counts<true>(data, cluster.triangle[l], hits.b1[l], hits.b2[l],
                                                  ray_direction(args->ray, args->N, i))) {
        tfar = -kInfinity;
        break;
      }
    }
  }
}

// Collects the leaves of an rtcBuildBVH run as clusters; the inner nodes are not needed.
struct ClusterBuild {
  const FlatScene* flat;
  std::mutex mutex;
  std::vector<TriangleCluster> clusters;
};

char unused_node;

void* create_cluster_node(RTCThreadLocalAllocator, unsigned, void*) { return &unused_node; }
void set_cluster_node_children(void*, void**, unsigned, void*) {}
void set_cluster_node_bounds(void*, const RTCBounds**, unsigned, void*) {}

void* create_cluster_leaf(RTCThreadLocalAllocator, const RTCBuildPrimitive* primitives, size_t count, void* user) {
  auto* build = static_cast<ClusterBuild*>(user);
  for (size_t first = 0; first < count; first += kClusterWidth) {
    const auto n = static_cast<unsigned>(std::min<size_t>(kClusterWidth, count - first));
    std::uint32_t triangles[kClusterWidth];
    for (unsigned i = 0; i < n; ++i) triangles[i] = primitives[first + i].primID;
    const TriangleCluster cluster = make_cluster(*build->flat, triangles, n);
    std::lock_guard lock(build->mutex);
    build->clusters.push_back(cluster);
  }
  return &unused_node;
}

// The clusters of `triangles` (FlatScene numbers; `index` null: 0, 1, ...), degenerate triangles
// left out: the leaves of a binned SAH build whose leaf cost is that of one cluster test, whatever
// the leaf holds up to eight triangles (sahBlockSize 8).
std::vector<TriangleCluster> build_clusters(RTCDevice device, const FlatScene& flat, std::size_t count,
                                            const std::uint32_t* index) {
  std::vector<RTCBuildPrimitive> primitives;
  primitives.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto t = static_cast<std::uint32_t>(index ? index[i] : i);
    if (is_degenerate(flat, t)) continue;
    const Vec3u tri = flat.triangles[t];
    const Vec3f a = flat.positions[tri.x], b = flat.positions[tri.y], c = flat.positions[tri.z];
    const Vec3f lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
    primitives.push_back(RTCBuildPrimitive{lo.x, lo.y, lo.z, 0, hi.x, hi.y, hi.z, t});
  }
  ClusterBuild build{&flat, {}, {}};
  if (primitives.empty()) return {};
  build.clusters.reserve(primitives.size() / 4);
  RTCBVH bvh = rtcNewBVH(device);
  RTCBuildArguments arguments = rtcDefaultBuildArguments();
  arguments.byteSize = sizeof(arguments);
  arguments.buildQuality = RTC_BUILD_QUALITY_MEDIUM;
  arguments.maxBranchingFactor = 2;
  arguments.minLeafSize = 1;
  arguments.maxLeafSize = kClusterWidth;
  arguments.sahBlockSize = kClusterWidth;
  arguments.traversalCost = 1.0f;
  arguments.intersectionCost = 1.0f;
  arguments.bvh = bvh;
  arguments.primitives = primitives.data();
  arguments.primitiveCount = primitives.size();
  arguments.primitiveArrayCapacity = primitives.capacity();
  arguments.createNode = &create_cluster_node;
  arguments.setNodeChildren = &set_cluster_node_children;
  arguments.setNodeBounds = &set_cluster_node_bounds;
  arguments.createLeaf = &create_cluster_leaf;
  arguments.userPtr = &build;
  rtcBuildBVH(&arguments);
  rtcReleaseBVH(bvh);
  return std::move(build.clusters);
}

}  // namespace

std::string_view embree_version() { return RTC_VERSION_STRING; }

// Device-wide state, reached from Embree's callbacks. Accels sharing the device use it one after
// another; each resets the error and the budget when it starts building.
struct EmbreeDevice::Impl {
  RTCDevice device = nullptr;
  std::mutex error_mutex;
  std::string first_error;  // recorded by the callback; never thrown across Embree's frames
  std::atomic<std::int64_t> memory_bytes{0};  // net bytes the device allocated
  std::atomic<std::int64_t> memory_budget{0}; // largest memory_bytes allowed (see on_memory)
  std::atomic<std::int64_t> refused_bytes{0}; // the first allocation refused, 0 if none

  // Embree may call this from several threads: positive bytes for an allocation, negative for a
  // free. Refusing (false) an allocation that would exceed the budget makes Embree cancel the build
  // with RTC_ERROR_OUT_OF_MEMORY. A refusal before the allocation (post == false) is not counted,
  // as the allocation never happens; one after it is (Embree will free the block), as its manual
  // page asks.
  static bool on_memory(void* user, ssize_t bytes, bool post) {
    auto* self = static_cast<Impl*>(user);
    const std::int64_t total = self->memory_bytes.fetch_add(bytes, std::memory_order_relaxed) + bytes;
    if (bytes <= 0 || total <= self->memory_budget.load(std::memory_order_relaxed)) return true;
    std::int64_t none = 0;
    self->refused_bytes.compare_exchange_strong(none, bytes);
    if (!post) self->memory_bytes.fetch_sub(bytes, std::memory_order_relaxed);
    return false;
  }

  static void on_error(void* user, RTCError code, const char* message) {
    auto* self = static_cast<Impl*>(user);
    std::lock_guard lock(self->error_mutex);
    if (self->first_error.empty())
      self->first_error = fmt::format("Embree: {} ({})", message ? message : "", error_name(code));
  }

  // Before a build: no recorded error, and a budget of what is available now on top of what the
  // device already holds.
  void begin_build() {
    std::lock_guard lock(error_mutex);
    first_error.clear();
    refused_bytes = 0;
    memory_budget = memory_bytes.load() + std::int64_t(std::min<std::uint64_t>(available_memory_bytes(), INT64_MAX / 2));
  }

  void throw_if_failed(const char* step, std::int64_t baseline) {
    std::lock_guard lock(error_mutex);
    if (const std::int64_t refused = refused_bytes.load(); refused > 0)
      throw RuntimeError(fmt::format("{} failed: out of memory: Embree asked for {} more with {} in use; {} were "
                                     "available when the build began",
                                     step, format_bytes(std::uint64_t(refused)),
                                     format_bytes(std::uint64_t(std::max<std::int64_t>(0, memory_bytes.load() - baseline))),
                                     format_bytes(std::uint64_t(memory_budget.load() - baseline))));
    if (!first_error.empty()) throw RuntimeError(fmt::format("{} failed: {}", step, first_error));
  }

  ~Impl() {
    if (device) rtcReleaseDevice(device);
  }
};

EmbreeDevice::EmbreeDevice() : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (!impl_->device)
    throw RuntimeError(fmt::format("creating the Embree device failed: {}", error_name(rtcGetDeviceError(nullptr))));
  rtcSetDeviceErrorFunction(impl_->device, &Impl::on_error, impl_.get());
  rtcSetDeviceMemoryMonitorFunction(impl_->device, &Impl::on_memory, impl_.get());
}

EmbreeDevice::~EmbreeDevice() = default;

struct EmbreeAccel::Impl {
  std::shared_ptr<EmbreeDevice> owner;  // keeps the device alive as long as the scene
  EmbreeDevice::Impl* device = nullptr;
  std::int64_t baseline_bytes = 0;  // the device's memory_bytes when this accel began
  RTCScene scene = nullptr;
  // Read by the callbacks of the triangle geometry (the untested triangles when some are tested),
  // the tested triangles' geometry and the spheres'.
  UserGeometryData triangle_data, tested_data, sphere_data;
  // With a surface test: the untested and the tested triangles, each with their FlatScene indices.
  std::vector<Vec3u> untested_triangles, tested_triangles;
  std::vector<std::uint32_t> untested_index, tested_index;
  const SurfaceTest* test = nullptr;   // null unless some triangle is tested
  std::vector<TriangleCluster> clusters, tested_clusters;  // the watertight kernel's
  bool shear = false;  // queries set up ShearedRays (the watertight kernel)
  RTCFilterFunctionN context_filter = &order_hits<false>;
  bool use_packets = true;     // the *_coherent queries trace packets (see intersect_coherent)

  template <unsigned kGeometry>
  RTCGeometry new_user_geometry(std::size_t count, RTCBoundsFunction bounds, UserGeometryData& data) {
    RTCGeometry geometry = rtcNewGeometry(device->device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(count));
    rtcSetGeometryUserData(geometry, &data);
    rtcSetGeometryBoundsFunction(geometry, bounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, &user_intersect<kGeometry>);
    rtcSetGeometryOccludedFunction(geometry, &user_occluded<kGeometry>);
    return geometry;
  }

  void attach(RTCGeometry geometry, unsigned id, EmbreeQuality quality) {
    rtcSetGeometryBuildQuality(geometry, to_embree(quality));
    rtcCommitGeometry(geometry);
    rtcAttachGeometryByID(scene, geometry, id);
    rtcReleaseGeometry(geometry);
  }

  // With a surface test that tests some triangle: the untested and the tested triangles apart,
  // the geometries' data numbering them, and the context filter that maps the numbers back.
  void split_by_test(const FlatScene& flat, const SurfaceTest* surface_test) {
    if (!surface_test) return;
    for (std::uint32_t t = 0; t < flat.triangle_count(); ++t) {
      const bool tested = surface_test->tested(t);
      (tested ? tested_triangles : untested_triangles).push_back(flat.triangles[t]);
      (tested ? tested_index : untested_index).push_back(t);
    }
    if (tested_triangles.empty()) {
      untested_triangles = {};
      untested_index = {};
      return;
    }
    test = surface_test;
    triangle_data.triangles = untested_index.data();
    tested_data.triangles = tested_index.data();
    tested_data.test = surface_test;
    context_filter = &order_hits<true>;
  }

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

EmbreeAccel::EmbreeAccel(const FlatScene& flat, const AccelOptions& options) : impl_(std::make_unique<Impl>()) {
  if (flat.triangle_count() + flat.spheres.size() >= RTC_INVALID_GEOMETRY_ID)
    throw RuntimeError("scene has more primitives than Embree can number");
  impl_->owner = options.embree_device ? options.embree_device : std::make_shared<EmbreeDevice>();
  impl_->device = impl_->owner->impl_.get();
  impl_->device->begin_build();
  impl_->baseline_bytes = options.embree_device ? impl_->device->memory_bytes.load() : 0;  // own device: all of it
  RTCDevice device = impl_->device->device;

  impl_->scene = rtcNewScene(device);
  const bool compact = flat.triangle_count() >= options.embree_compact_from_triangles;
  // The context filter orders the native triangle kernel's closest hits; user geometries order
  // their own; occlusion queries pass no filter.
  rtcSetSceneFlags(impl_->scene, static_cast<RTCSceneFlags>(
                                     kSceneFilterFlag |
                                     (compact ? RTC_SCENE_FLAG_COMPACT : RTC_SCENE_FLAG_NONE) |
                                     (options.embree_robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE)));
  rtcSetSceneBuildQuality(impl_->scene, to_embree(options.embree_quality));
  const float padding = user_box_padding(flat);
  impl_->triangle_data = impl_->tested_data = impl_->sphere_data = {&flat, padding, nullptr, nullptr};
  impl_->use_packets = (options.embree_robust || options.embree_kernel != EmbreeKernel::native) && !compact;
  impl_->split_by_test(flat, options.surface_test);
  // The triangles of one geometry: all of them (none tested: FlatScene's buffers, shared), or the
  // untested or tested ones (own index buffers, FlatScene numbers in data.triangles).
  const auto add_triangles = [&](unsigned id, const std::vector<Vec3u>& triangles, UserGeometryData& data) {
    if (triangles.empty()) return;
    RTCGeometry geometry = nullptr;
    if (options.embree_kernel == EmbreeKernel::native) {
      geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      // Shared buffers: Embree reads the vectors in place. FlatScene guarantees one spare
      // Vec3f of capacity past the last vertex for Embree's 16-byte vertex loads.
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, flat.positions.data(), 0,
                                 sizeof(Vec3f), flat.positions.size());
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, triangles.data(), 0,
                                 sizeof(Vec3u), triangles.size());
      if (data.triangles) rtcSetGeometryUserData(geometry, &data);
      if (data.test) {
        rtcSetGeometryIntersectFilterFunction(geometry, &surface_filter<false>);
        rtcSetGeometryOccludedFilterFunction(geometry, &surface_filter<true>);
      }
    } else if (options.embree_kernel == EmbreeKernel::watertight) {
      std::vector<TriangleCluster>& clusters = id == kTestedGeometry ? impl_->tested_clusters : impl_->clusters;
      clusters = build_clusters(device, flat, triangles.size(), data.triangles);
      if (clusters.empty()) return;
      data.clusters = clusters.data();
      data.intersect_cluster = best_intersect_cluster();
      impl_->shear = true;
      geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(clusters.size()));
      rtcSetGeometryUserData(geometry, &data);
      rtcSetGeometryBoundsFunction(geometry, &cluster_bounds, nullptr);
      rtcSetGeometryIntersectFunction(geometry, &cluster_intersect);
      rtcSetGeometryOccludedFunction(geometry, &cluster_occluded);
    } else {
      geometry = id == kTestedGeometry ? impl_->new_user_geometry<kTestedGeometry>(triangles.size(), &triangle_bounds, data)
                                      : impl_->new_user_geometry<kTriangleGeometry>(triangles.size(), &triangle_bounds, data);
    }
    impl_->attach(geometry, id, options.embree_quality);
  };
  if (!impl_->test) {
    add_triangles(kTriangleGeometry, flat.triangles, impl_->triangle_data);
  } else {
    add_triangles(kTriangleGeometry, impl_->untested_triangles, impl_->triangle_data);
    add_triangles(kTestedGeometry, impl_->tested_triangles, impl_->tested_data);
  }
  if (!flat.spheres.empty())
    impl_->attach(impl_->new_user_geometry<kSphereGeometry>(flat.spheres.size(), &sphere_bounds, impl_->sphere_data),
                  kSphereGeometry, options.embree_quality);
  rtcCommitScene(impl_->scene);
  impl_->device->throw_if_failed("building the Embree scene", impl_->baseline_bytes);
}

EmbreeAccel::~EmbreeAccel() = default;

const SurfaceTest* EmbreeAccel::surface_test() const { return impl_->test; }

std::size_t EmbreeAccel::memory_bytes() const {
  const std::int64_t bytes = impl_->device->memory_bytes.load(std::memory_order_relaxed) - impl_->baseline_bytes;
  const std::size_t cluster_bytes =
      (impl_->clusters.size() + impl_->tested_clusters.size()) * sizeof(TriangleCluster);
  return static_cast<std::size_t>(std::max<std::int64_t>(bytes, 0)) + cluster_bytes;
}

namespace {

BestHit no_hit_yet(const Ray& ray) { return {ray.tfar, RTC_INVALID_GEOMETRY_ID, 0.0, 0.0}; }

Hit to_hit(const BestHit& best) {
  if (best.prim == RTC_INVALID_GEOMETRY_ID) return Hit{};
  return Hit{static_cast<float>(best.t), static_cast<float>(best.b1), static_cast<float>(best.b2), best.prim};
}

}  // namespace

Hit EmbreeAccel::intersect(const Ray& ray) const {
  if (!embree_accepts(ray)) [[unlikely]]
    return Hit{};
  BestHit best = no_hit_yet(ray);
  ShearedRay sheared;
  if (impl_->shear) shear_ray(ray.origin, ray.direction, sheared);
  HitContext context{{}, &best, &sheared};
  Query query(context.embree, impl_->context_filter, false);
  RTCRayHit rayhit;
  fill_ray(ray, rayhit.ray);
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  query.intersect(impl_->scene, rayhit);
  return to_hit(best);
}

void EmbreeAccel::intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits) const {
  // Without RTC_SCENE_FLAG_ROBUST the native packet kernel and the single-ray kernel disagree on
  // rays exactly along an edge (tests/test_accel.cpp has three), and Embree switches between them
  // by how many lanes are still active, so a pixel would depend on its neighbours: single rays then.
  // With RTC_SCENE_FLAG_COMPACT (and robust) rtcOccluded16 never returned on a 2.2M-triangle UV
  // sphere (Embree 3.13.5; single rays take 0.2 s there): single rays too.
  if (!impl_->use_packets) {
    Accel::intersect_coherent(rays, hits);
    return;
  }
  for (std::size_t first = 0; first < rays.size(); first += kPacketSize) {
    const auto lanes = static_cast<unsigned>(std::min<std::size_t>(kPacketSize, rays.size() - first));
    BestHit best[kPacketSize];
    ShearedRay sheared[kPacketSize];
    HitContext context{{}, best, sheared};
    Query query(context.embree, impl_->context_filter, true);
    alignas(64) RTCRayHit16 packet;
    alignas(64) int valid[kPacketSize];
    for (unsigned i = 0; i < kPacketSize; ++i) {
      const Ray& ray = rays[first + (i < lanes ? i : 0)];
      const bool on = i < lanes && embree_accepts(ray);
      valid[i] = on ? -1 : 0;
      best[i] = no_hit_yet(ray);
      if (!on) {
        fill_packet_lane_off(i, packet.ray);
        continue;
      }
      if (impl_->shear) shear_ray(ray.origin, ray.direction, sheared[i]);
      fill_packet_lane(ray, i, packet.ray);
      packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
      packet.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;
      packet.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    query.intersect(valid, impl_->scene, packet);
    for (unsigned i = 0; i < lanes; ++i) hits[first + i] = to_hit(best[i]);
  }
}

void EmbreeAccel::occluded_coherent(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const {
  if (!impl_->use_packets) {  // as in intersect_coherent
    Accel::occluded_coherent(rays, blocked);
    return;
  }
  ShearedRay sheared[kPacketSize];
  ShadowContext context{{}, sheared};
  Query query(context.embree, nullptr, true);
  for (std::size_t first = 0; first < rays.size(); first += kPacketSize) {
    const auto lanes = static_cast<unsigned>(std::min<std::size_t>(kPacketSize, rays.size() - first));
    alignas(64) RTCRay16 packet;
    alignas(64) int valid[kPacketSize];
    for (unsigned i = 0; i < kPacketSize; ++i) {
      const Ray& ray = rays[first + (i < lanes ? i : 0)];
      const bool on = i < lanes && embree_accepts(ray);
      valid[i] = on ? -1 : 0;
      if (!on) {
        fill_packet_lane_off(i, packet);
        continue;
      }
      if (impl_->shear) shear_ray(ray.origin, ray.direction, sheared[i]);
      fill_packet_lane(ray, i, packet);
    }
    query.occluded(valid, impl_->scene, packet);
    for (unsigned i = 0; i < lanes; ++i) blocked[first + i] = packet.tfar[i] == -kInfinity ? 1 : 0;
  }
}

bool EmbreeAccel::occluded(const Ray& ray) const {
  if (!embree_accepts(ray)) [[unlikely]]
    return false;
  ShearedRay sheared;
  if (impl_->shear) shear_ray(ray.origin, ray.direction, sheared);
  ShadowContext context{{}, &sheared};
  Query query(context.embree, nullptr, false);
  RTCRay embree_ray;
  fill_ray(ray, embree_ray);
  query.occluded(impl_->scene, embree_ray);
  return embree_ray.tfar == -kInfinity;  // Embree marks an occluded ray by tfar = -inf
}

}  // namespace rt
