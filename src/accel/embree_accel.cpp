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

// Context of the tie-resolving query. Embree passes our RTCIntersectContext pointer to the
// filter, so extra fields after it travel along (the pattern of Embree's own tutorials).
struct TieContext {
  RTCIntersectContext embree;
  float t;               // the closest hit's t, as Embree computed it
  unsigned lowest_prim;  // lowest primitive index seen with exactly that t, and its barycentrics
  float u, v;
};

// Collects every candidate whose computed t equals the closest hit's, and rejects all of them so
// that traversal goes on through the whole (tiny) interval. Embree has set the ray's tfar to the
// candidate's t before calling the filter.
void collect_ties(const RTCFilterFunctionNArguments* args) {
  auto* context = reinterpret_cast<TieContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    if (RTCRayN_tfar(args->ray, args->N, i) == context->t) {
      const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
      if (prim < context->lowest_prim) {
        context->lowest_prim = prim;
        context->u = RTCHitN_u(args->hit, args->N, i);
        context->v = RTCHitN_v(args->hit, args->N, i);
      }
    }
    args->valid[i] = 0;
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
  // Context filters are enabled for the tie-resolving query only; ordinary queries pass none.
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
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rayhit;
  fill_ray(ray, rayhit.ray);
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rayhit);
  if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return Hit{};
  Hit hit{rayhit.ray.tfar, rayhit.hit.u, rayhit.hit.v, rayhit.hit.primID};

  // Tie resolution. Embree accepts a candidate when its scaled t lies in [tnear, tfar]; the
  // interval is widened by a few ulps so that rounding in that test cannot drop a triangle whose
  // t (computed the same way as before) equals hit.t exactly. The filter decides by exact equality.
  TieContext ties;
  rtcInitIntersectContext(&ties.embree);
  ties.embree.filter = &collect_ties;
  ties.t = hit.t;
  ties.lowest_prim = hit.triangle;
  RTCRayHit probe;
  fill_ray(ray, probe.ray);
  probe.ray.tnear = std::nextafter(std::nextafter(hit.t, 0.0f), 0.0f);
  probe.ray.tfar = std::nextafter(std::nextafter(hit.t, kInfinity), kInfinity);
  probe.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  probe.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &ties.embree, &probe);
  if (ties.lowest_prim != hit.triangle) hit = Hit{hit.t, ties.u, ties.v, ties.lowest_prim};
  return hit;
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
