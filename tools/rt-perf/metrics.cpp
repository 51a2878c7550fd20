#include "metrics.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <fmt/format.h>

namespace rt::perf {

namespace {

OIIO::ImageBuf clamped_buffer(const Image& image) {
  OIIO::ImageBuf buffer(OIIO::ImageSpec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT));
  std::vector<float> values(image.pixels.size() * 3);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    values[3 * i + 0] = std::clamp(image.pixels[i].r, 0.0f, 1.0f);
    values[3 * i + 1] = std::clamp(image.pixels[i].g, 0.0f, 1.0f);
    values[3 * i + 2] = std::clamp(image.pixels[i].b, 0.0f, 1.0f);
  }
  buffer.set_pixels(OIIO::ROI::All(), OIIO::TypeDesc::FLOAT, values.data());
  return buffer;
}

}  // namespace

ImageError compare_images(const Image& image, const Image& truth) {
  if (image.width != truth.width || image.height != truth.height)
    throw std::invalid_argument(fmt::format("cannot compare a {}x{} image with a {}x{} ground truth", image.width,
                                            image.height, truth.width, truth.height));
  // failthresh 1/255: nfail counts the pixels with some channel off by more than one 8-bit step.
  const auto results = OIIO::ImageBufAlgo::compare(clamped_buffer(image), clamped_buffer(truth), 1.0f / 255.0f,
                                                   1.0f / 255.0f);
  ImageError error;
  error.rmse = results.rms_error;
  error.psnr = results.rms_error > 0.0 ? results.PSNR : std::numeric_limits<double>::infinity();
  error.max_abs = results.maxerror;
  const double pixels = double(image.width) * double(image.height);
  error.pct_over_1_255 = pixels > 0.0 ? 100.0 * double(results.nfail) / pixels : 0.0;
  return error;
}

}  // namespace rt::perf
