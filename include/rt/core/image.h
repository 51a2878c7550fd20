#pragma once
// A float RGB image in memory: linear colour, row 0 at the top, pixels stored row-major.

#include <cstddef>
#include <vector>

#include "rt/core/math.h"

namespace rt {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<Color> pixels;  // width * height entries, index y * width + x

  Image() = default;
  Image(int w, int h) : width(w), height(h), pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h)) {}

  Color& at(int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x]; }
  const Color& at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
};

}  // namespace rt
