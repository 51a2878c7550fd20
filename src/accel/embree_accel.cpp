#include "rt/accel/embree_accel.h"

#include <cmath>
#include <mutex>
#include <string>

#include <embree3/rtcore.h>
#include <fmt/format.h>

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

}  // namespace

struct EmbreeAccel::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
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
  if (flat.triangle_count() > 0) {
    RTCGeometry geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry, to_embree(options.embree_quality));
    // Shared buffers: Embree reads FlatScene's vectors in place. FlatScene guarantees one spare
    // Vec3f of capacity past the last vertex for Embree's 16-byte vertex loads.
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, flat.positions.data(), 0,
                               sizeof(Vec3f), flat.positions.size());
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, flat.triangles.data(), 0,
                               sizeof(Vec3u), flat.triangles.size());
    rtcCommitGeometry(geometry);
    rtcAttachGeometryByID(impl_->scene, geometry, 0);
    rtcReleaseGeometry(geometry);
  }
  rtcCommitScene(impl_->scene);
  impl_->throw_if_failed("building the Embree scene");
}

EmbreeAccel::~EmbreeAccel() = default;

Hit EmbreeAccel::intersect(const Ray& ray) const {
  OrderedHitContext context;
  rtcInitIntersectContext(&context.embree);
  context.embree.filter = &order_hits;
  context.best_t = ray.tfar;
  context.best_prim = RTC_INVALID_GEOMETRY_ID;
  RTCRayHit rayhit;
  fill_ray(ray, rayhit.ray);
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
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
