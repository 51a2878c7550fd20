#pragma once
// A float RGB image in memory: linear colour, row 0 at the top, pixels stored row-major.

#include <cstddef>
#include <new>
#include <vector>

#include "rt/core/math.h"

namespace rt {

// Allocates on 64-byte (cache line) boundaries: an image's rows can then be written a whole line
// at a time (render_image streams each finished tile into the image).
template <class T>
struct CacheLineAllocator {
  using value_type = T;
  static constexpr std::align_val_t kAlignment{64};
  CacheLineAllocator() = default;
  template <class U>
  CacheLineAllocator(const CacheLineAllocator<U>&) {}
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlignment)); }
  void deallocate(T* p, std::size_t) { ::operator delete(p, kAlignment); }
  template <class U>
  bool operator==(const CacheLineAllocator<U>&) const { return true; }
};

struct Image {
  int width = 0;
  int height = 0;
  std::vector<Color, CacheLineAllocator<Color>> pixels;  // width * height entries, index y * width + x

  Image() = default;
  Image(int w, int h) : width(w), height(h), pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h)) {}

  Color& at(int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x]; }
  const Color& at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
};

}  // namespace rt
