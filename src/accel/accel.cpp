#include "rt/accel/accel.h"

#include "rt/accel/embree_accel.h"
#include "rt/accel/reference_accel.h"
#include "rt/core/error.h"

namespace rt {

std::unique_ptr<Accel> build_accel(AccelKind kind, const FlatScene& scene) {
  switch (kind) {
    case AccelKind::embree: return std::make_unique<EmbreeAccel>(scene);
    case AccelKind::reference: return std::make_unique<ReferenceAccel>(scene);
  }
  throw RuntimeError("unknown accelerator kind");
}

std::string_view to_string(AccelKind kind) { return kind == AccelKind::embree ? "embree" : "reference"; }

AccelKind parse_accel_kind(std::string_view name) {
  if (name == "embree") return AccelKind::embree;
  if (name == "reference") return AccelKind::reference;
  throw InputError("unknown accelerator '" + std::string(name) + "' (expected embree or reference)");
}

}  // namespace rt
