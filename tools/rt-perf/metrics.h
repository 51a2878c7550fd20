#pragma once
// Error of an image against a ground truth, as OpenImageIO's ImageBufAlgo::compare measures it.

#include "rt/core/image.h"

namespace rt::perf {

// Both images are clamped to [0, 1] (the displayable range the 8-bit output keeps) before
// comparing, per channel of linear RGB. rmse over all channels; psnr = 20 log10(1 / rmse) dB
// (+inf for identical images); max_abs the largest channel difference; pct_over_1_255 the
// percentage of pixels with some channel off by more than 1/255.
struct ImageError {
  double rmse = 0.0;
  double psnr = 0.0;
  double max_abs = 0.0;
  double pct_over_1_255 = 0.0;
};

// Throws std::invalid_argument when the sizes differ.
ImageError compare_images(const Image& image, const Image& truth);

}  // namespace rt::perf
