#include "rt/render/region.h"

#include <fmt/format.h>

namespace rt {

PixelRegion tile_region(int k, int n, int width, int height) {
  const auto row = [&](int i) { return int(std::int64_t(i) * height / n); };  // 64-bit: 65536^2 overflows int
  return {0, row(k - 1), width, row(k)};
}

std::string to_string(const PixelRegion& region) {
  return fmt::format("{} {} {} {}", region.x0, region.y0, region.x1, region.y1);
}

}  // namespace rt
