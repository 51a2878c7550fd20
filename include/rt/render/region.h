#pragma once
// Rectangles of pixels for rendering part of an image (--crop, --tile) and for stitching the parts
// back together (rt merge). Coordinates are full-image pixels, x right and y down from the
// top-left corner, half-open: [x0, x1) x [y0, y1).

#include <cstdint>
#include <string>

namespace rt {

struct PixelRegion {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;

  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  std::uint64_t pixel_count() const { return std::uint64_t(width()) * std::uint64_t(height()); }
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
  // True when the region is non-empty and lies inside a width x height image.
  bool inside(int width, int height) const { return !empty() && x0 >= 0 && y0 >= 0 && x1 <= width && y1 <= height; }
  bool operator==(const PixelRegion&) const = default;
};

// The whole width x height image.
inline PixelRegion full_region(int width, int height) { return {0, 0, width, height}; }

// Tile k (1-based) of n: the image cut into n bands of whole rows, tile k holding rows
// [floor((k - 1) height / n), floor(k height / n)). Bands differ in height by at most one row, and
// the n tiles cover the image exactly once. Requires 1 <= k <= n <= height.
PixelRegion tile_region(int k, int n, int width, int height);

// "x0 y0 x1 y1", as --crop takes it.
std::string to_string(const PixelRegion& region);

}  // namespace rt
