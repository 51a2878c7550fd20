#include "rt/accel/embree_accel.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <string>

#include <embree3/rtcore.h>
#include <fmt/format.h>

#include "rt/accel/reference_accel.h"
#include "rt/core/error.h"

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

RTCBuildQuality to_embree(EmbreeQuality quality) {
  switch (quality) {
    case EmbreeQuality::low: return RTC_BUILD_QUALITY_LOW;
    case EmbreeQuality::medium: return RTC_BUILD_QUALITY_MEDIUM;
    case EmbreeQuality::high: return RTC_BUILD_QUALITY_HIGH;
  }
  return RTC_BUILD_QUALITY_MEDIUM;
}

// Intersection context that orders hits by (t, primitive index). Embree passes our
// RTCIntersectContext pointer to the filter, so fields after it travel along (the pattern of
// Embree's own tutorials).
struct OrderedHitContext {
  RTCIntersectContext embree;
  float best_t;         // t of the hit accepted so far (the ray's tfar until one is)
  unsigned best_prim;   // its primitive index; RTC_INVALID_GEOMETRY_ID before any hit
};

// Embree offers candidates to the filter one after another, having set the ray's tfar to the
// candidate's t. Accepting only strictly closer hits, or equally close ones with a lower index,
// makes the closest hit independent of BVH layout and traversal order. One catch: Embree's depth
// test for later candidates is T <= |den| * tfar on unnormalised values, which rounding can fail
// for a candidate whose t = T / |den| equals tfar exactly. So on acceptance tfar is widened by
// 2^-20 relative (~16 ulps, far more than that rounding); the filter, not the depth test, then
// decides between candidates by exact comparison of t, and intersect() reports best_t.
void order_hits(const RTCFilterFunctionNArguments* args) {
  auto* context = reinterpret_cast<OrderedHitContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    float& tfar = RTCRayN_tfar(args->ray, args->N, i);
    const float t = tfar;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    if (t < context->best_t || (t == context->best_t && prim < context->best_prim)) {
      context->best_t = t;
      context->best_prim = prim;
      tfar = t + std::abs(t) * 0x1p-20f;
    } else {
      args->valid[i] = 0;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The watertight kernel: every triangle is a primitive of one Embree user geometry whose
// callbacks run intersect_triangle_watertight in double, on the same float32 vertices.

// What the user-geometry callbacks read: the world-space float32 buffers and the box padding.
struct WatertightTriangles {
  const FlatScene* flat = nullptr;
  float box_padding = 0.0f;  // world-space units, added on every side of each triangle's box
};

// Embree traverses user geometry with its fast, non-conservative box test (Embree 3.13 compiles
// BVH4VirtualIntersector1 with robust = false whatever the scene flags say), so a ray through a
// triangle's vertex or edge can be culled at a box face it only touches. The slab distances that
// test computes, fl(lower * rdir - fl(org * rdir)) with an approximate reciprocal rdir, are off by
// at most a few float32 ulps of |lower| + |org| in world units; boxes padded by 2^-18 times the
// scene's largest coordinate magnitude M absorb that error (with a margin of 4 and more) for every
// ray whose origin lies within 7 M of the world origin: all secondary rays, and camera rays unless
// the eye is far outside the scene. The padding only makes boxes overlap slightly more.
float watertight_box_padding(const FlatScene& flat) {
  float largest = 0.0f;
  for (const Vec3f& p : flat.positions)
    largest = std::max({largest, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  return std::max(largest, 1.0f) * 0x1p-18f;
}

void watertight_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* triangles = static_cast<const WatertightTriangles*>(args->geometryUserPtr);
  const FlatScene& flat = *triangles->flat;
  const Vec3u tri = flat.triangles[args->primID];
  const Vec3f a = flat.positions[tri.x], b = flat.positions[tri.y], c = flat.positions[tri.z];
  const Vec3f lower = glm::min(a, glm::min(b, c)) - triangles->box_padding;
  const Vec3f upper = glm::max(a, glm::max(b, c)) + triangles->box_padding;
  *args->bounds_o = RTCBounds{lower.x, lower.y, lower.z, 0.0f, upper.x, upper.y, upper.z, 0.0f};
}

// The closest hit found so far, in double, ordered by (t, primitive index) like the reference.
struct WatertightHitContext {
  RTCIntersectContext embree;
  double best_t;       // the ray's tfar until a hit is accepted
  unsigned best_prim;  // RTC_INVALID_GEOMETRY_ID before any hit
  double best_b1, best_b2;
};

bool intersect_flat_triangle(const FlatScene& flat, unsigned prim, const Vec3d& origin, const Vec3d& direction,
                             double tnear, double tfar, TriangleHitD& hit) {
  const Vec3u tri = flat.triangles[prim];
  return intersect_triangle_watertight(origin, direction, tnear, tfar, Vec3d(flat.positions[tri.x]),
                                       Vec3d(flat.positions[tri.y]), Vec3d(flat.positions[tri.z]), hit);
}

void watertight_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* triangles = static_cast<const WatertightTriangles*>(args->geometryUserPtr);
  auto* context = reinterpret_cast<WatertightHitContext*>(args->context);
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  RTCHitN* hit_out = RTCRayHitN_HitN(args->rayhit, args->N);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const Vec3d origin(RTCRayN_org_x(ray, args->N, i), RTCRayN_org_y(ray, args->N, i), RTCRayN_org_z(ray, args->N, i));
    const Vec3d direction(RTCRayN_dir_x(ray, args->N, i), RTCRayN_dir_y(ray, args->N, i),
                          RTCRayN_dir_z(ray, args->N, i));
    TriangleHitD hit;
    if (!intersect_flat_triangle(*triangles->flat, args->primID, origin, direction, RTCRayN_tnear(ray, args->N, i),
                                 context->best_t, hit))
      continue;
    if (!(hit.t < context->best_t || args->primID < context->best_prim)) continue;
    context->best_t = hit.t;
    context->best_prim = args->primID;
    context->best_b1 = hit.b1;
    context->best_b2 = hit.b2;
    // Embree only needs tfar to cull boxes entirely beyond the hit; widened as in order_hits so
    // an equally close candidate in another leaf still reaches this callback.
    const auto t = static_cast<float>(hit.t);
    RTCRayN_tfar(ray, args->N, i) = t + std::abs(t) * 0x1p-20f;
    RTCHitN_geomID(hit_out, args->N, i) = args->geomID;
    RTCHitN_primID(hit_out, args->N, i) = args->primID;
    RTCHitN_instID(hit_out, args->N, i, 0) = args->context->instID[0];
    RTCHitN_u(hit_out, args->N, i) = static_cast<float>(hit.b1);
    RTCHitN_v(hit_out, args->N, i) = static_cast<float>(hit.b2);
  }
}

void watertight_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* triangles = static_cast<const WatertightTriangles*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    float& tfar = RTCRayN_tfar(args->ray, args->N, i);
    const Vec3d origin(RTCRayN_org_x(args->ray, args->N, i), RTCRayN_org_y(args->ray, args->N, i),
                       RTCRayN_org_z(args->ray, args->N, i));
    const Vec3d direction(RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i),
                          RTCRayN_dir_z(args->ray, args->N, i));
    TriangleHitD hit;
    if (intersect_flat_triangle(*triangles->flat, args->primID, origin, direction,
                                RTCRayN_tnear(args->ray, args->N, i), tfar, hit))
      tfar = -kInfinity;
  }
}

}  // namespace

struct EmbreeAccel::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  EmbreeKernel kernel = EmbreeKernel::native;
  WatertightTriangles watertight;
  std::mutex error_mutex;
  std::string first_error;  // recorded by the callback; never thrown across Embree's frames

  static void on_error(void* user, RTCError code, const char* message) {
    auto* self = static_cast<Impl*>(user);
    std::lock_guard lock(self->error_mutex);
    if (self->first_error.empty())
      self->first_error = fmt::format("Embree: {} ({})", message ? message : "", error_name(code));
  }

  void throw_if_failed(const char* step) {
    std::lock_guard lock(error_mutex);
    if (!first_error.empty()) throw RuntimeError(fmt::format("{} failed: {}", step, first_error));
  }

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

EmbreeAccel::EmbreeAccel(const FlatScene& flat, const AccelOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (!impl_->device)
    throw RuntimeError(fmt::format("creating the Embree device failed: {}", error_name(rtcGetDeviceError(nullptr))));
  rtcSetDeviceErrorFunction(impl_->device, &Impl::on_error, impl_.get());

  impl_->scene = rtcNewScene(impl_->device);
  // The context filter orders closest hits; occlusion queries pass none.
  rtcSetSceneFlags(impl_->scene, static_cast<RTCSceneFlags>(
                                     RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION |
                                     (options.embree_robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE)));
  rtcSetSceneBuildQuality(impl_->scene, to_embree(options.embree_quality));
  impl_->kernel = options.embree_kernel;
  if (flat.triangle_count() > 0) {
    RTCGeometry geometry = nullptr;
    if (options.embree_kernel == EmbreeKernel::native) {
      geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
      // Shared buffers: Embree reads FlatScene's vectors in place. FlatScene guarantees one spare
      // Vec3f of capacity past the last vertex for Embree's 16-byte vertex loads.
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, flat.positions.data(), 0,
                                 sizeof(Vec3f), flat.positions.size());
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, flat.triangles.data(), 0,
                                 sizeof(Vec3u), flat.triangles.size());
    } else {
      impl_->watertight = {&flat, watertight_box_padding(flat)};
      geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(flat.triangle_count()));
      rtcSetGeometryUserData(geometry, &impl_->watertight);
      rtcSetGeometryBoundsFunction(geometry, &watertight_bounds, nullptr);
      rtcSetGeometryIntersectFunction(geometry, &watertight_intersect);
      rtcSetGeometryOccludedFunction(geometry, &watertight_occluded);
    }
    rtcSetGeometryBuildQuality(geometry, to_embree(options.embree_quality));
    rtcCommitGeometry(geometry);
    rtcAttachGeometryByID(impl_->scene, geometry, 0);
    rtcReleaseGeometry(geometry);
  }
  rtcCommitScene(impl_->scene);
  impl_->throw_if_failed("building the Embree scene");
}

EmbreeAccel::~EmbreeAccel() = default;

Hit EmbreeAccel::intersect(const Ray& ray) const {
  RTCRayHit rayhit;
  fill_ray(ray, rayhit.ray);
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  if (impl_->kernel == EmbreeKernel::watertight) {
    WatertightHitContext context;
    rtcInitIntersectContext(&context.embree);
    context.best_t = ray.tfar;
    context.best_prim = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene, &context.embree, &rayhit);
    if (context.best_prim == RTC_INVALID_GEOMETRY_ID) return Hit{};
    return Hit{static_cast<float>(context.best_t), static_cast<float>(context.best_b1),
               static_cast<float>(context.best_b2), context.best_prim};
  }
  OrderedHitContext context;
  rtcInitIntersectContext(&context.embree);
  context.embree.filter = &order_hits;
  context.best_t = ray.tfar;
  context.best_prim = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context.embree, &rayhit);
  if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return Hit{};
  return Hit{context.best_t, rayhit.hit.u, rayhit.hit.v, rayhit.hit.primID};
}

bool EmbreeAccel::occluded(const Ray& ray) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay embree_ray;
  fill_ray(ray, embree_ray);
  rtcOccluded1(impl_->scene, &context, &embree_ray);
  return embree_ray.tfar == -kInfinity;  // Embree marks an occluded ray by tfar = -inf
}

}  // namespace rt
