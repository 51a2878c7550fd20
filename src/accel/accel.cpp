#include "rt/accel/accel.h"

#include <string>

#include "rt/accel/embree_accel.h"
#include "rt/accel/reference_accel.h"
#include "rt/core/error.h"

namespace rt {

void Accel::intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits) const {
  for (std::size_t i = 0; i < rays.size(); ++i) hits[i] = intersect(rays[i]);
}

void Accel::occluded_coherent(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const {
  for (std::size_t i = 0; i < rays.size(); ++i) blocked[i] = occluded(rays[i]) ? 1 : 0;
}

std::unique_ptr<Accel> build_accel(AccelKind kind, const FlatScene& scene, const AccelOptions& options) {
  switch (kind) {
    case AccelKind::embree: return std::make_unique<EmbreeAccel>(scene, options);
    case AccelKind::reference: return std::make_unique<ReferenceAccel>(scene, ReferenceTest::watertight, options.surface_test);
    case AccelKind::reference_barycentric:
      return std::make_unique<ReferenceAccel>(scene, ReferenceTest::barycentric, options.surface_test);
  }
  throw RuntimeError("unknown accelerator kind");
}

std::string_view to_string(AccelKind kind) {
  switch (kind) {
    case AccelKind::embree: return "embree";
    case AccelKind::reference: return "reference";
    case AccelKind::reference_barycentric: return "reference-barycentric";
  }
  return "?";
}

AccelKind parse_accel_kind(std::string_view name) {
  for (AccelKind kind : {AccelKind::embree, AccelKind::reference, AccelKind::reference_barycentric})
    if (name == to_string(kind)) return kind;
  throw InputError("unknown accelerator '" + std::string(name) +
                   "' (expected embree, reference or reference-barycentric)");
}

std::string_view to_string(EmbreeQuality quality) {
  switch (quality) {
    case EmbreeQuality::low: return "low";
    case EmbreeQuality::medium: return "medium";
    case EmbreeQuality::high: return "high";
  }
  return "?";
}

EmbreeQuality parse_embree_quality(std::string_view name) {
  for (EmbreeQuality quality : {EmbreeQuality::low, EmbreeQuality::medium, EmbreeQuality::high})
    if (name == to_string(quality)) return quality;
  throw InputError("unknown Embree build quality '" + std::string(name) + "' (expected low, medium or high)");
}

std::string_view to_string(EmbreeKernel kernel) {
  switch (kernel) {
    case EmbreeKernel::native: return "native";
    case EmbreeKernel::watertight: return "watertight";
    case EmbreeKernel::exact: return "exact";
  }
  return "?";
}

EmbreeKernel parse_embree_kernel(std::string_view name) {
  for (EmbreeKernel kernel : {EmbreeKernel::native, EmbreeKernel::watertight, EmbreeKernel::exact})
    if (name == to_string(kernel)) return kernel;
  throw InputError("unknown Embree kernel '" + std::string(name) + "' (expected native, watertight or exact)");
}

}  // namespace rt
