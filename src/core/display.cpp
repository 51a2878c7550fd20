#include "rt/core/display.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "rt/core/error.h"

namespace rt {

namespace {

// IEC 61966-2-1 encoding of a linear value in [0, 1].
double srgb_encode(double c) { return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055; }

// Narkowicz, "ACES Filmic Tone Mapping Curve" (2015): a rational fit of the ACES RRT + ODT,
// applied per channel to exposure-scaled linear values.
double aces_narkowicz(double x) {
  constexpr double a = 2.51, b = 0.03, c = 2.43, d = 0.59, e = 0.14;
  return std::clamp(x * (a * x + b) / (x * (c * x + d) + e), 0.0, 1.0);
}

// Khronos PBR Neutral tone mapper (Khronos Group, 2024, the reference GLSL): colours whose largest
// channel stays below 0.76 pass unchanged (after a small toe), brighter ones are compressed
// towards white and desaturated.
Vec3d pbr_neutral(Vec3d color) {
  constexpr double start_compression = 0.8 - 0.04, desaturation = 0.15;
  const double x = std::min({color.r, color.g, color.b});
  const double offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
  color -= offset;
  const double peak = std::max({color.r, color.g, color.b});
  if (peak < start_compression) return color;
  const double d = 1.0 - start_compression;
  const double new_peak = 1.0 - d * d / (peak + d - start_compression);
  color *= new_peak / peak;
  const double g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
  return glm::mix(color, Vec3d(new_peak), g);
}

std::uint8_t byte_of(double v, DisplayEncoding encoding) {
  // NaN fails the comparison and maps to 0.
  const double clamped = v > 0.0 ? std::min(v, 1.0) : 0.0;
  if (encoding == DisplayEncoding::srgb) return static_cast<std::uint8_t>(std::lround(255.0 * srgb_encode(clamped)));
  return static_cast<std::uint8_t>(std::floor(255.0 * clamped));
}

}  // namespace

std::uint8_t quantize_8bit(float c) {
  // NaN fails both comparisons and maps to 0.
  const float clamped = c > 0.0f ? std::min(c, 1.0f) : 0.0f;
  return static_cast<std::uint8_t>(std::floor(255.0f * clamped));
}

void encode_8bit(const Color& c, const DisplayTransform& display, std::uint8_t out[3]) {
  if (display == DisplayTransform{}) {
    for (int k = 0; k < 3; ++k) out[k] = quantize_8bit(c[k]);
    return;
  }
  Vec3d v = Vec3d(c) * std::exp2(display.exposure_ev);
  for (int k = 0; k < 3; ++k)
    if (!(v[k] >= 0.0)) v[k] = 0.0;  // NaN and negative values: black
  if (display.tonemap == ToneMap::aces)
    for (int k = 0; k < 3; ++k) v[k] = aces_narkowicz(v[k]);
  else if (display.tonemap == ToneMap::pbr_neutral && std::isfinite(v.r + v.g + v.b))
    v = pbr_neutral(v);
  for (int k = 0; k < 3; ++k) out[k] = byte_of(v[k], display.encoding);
}

std::string_view to_string(DisplayEncoding encoding) { return encoding == DisplayEncoding::srgb ? "srgb" : "linear"; }

DisplayEncoding parse_display_encoding(std::string_view name) {
  if (name == "linear") return DisplayEncoding::linear;
  if (name == "srgb") return DisplayEncoding::srgb;
  throw InputError(fmt::format("unknown display encoding '{}' (expected linear or srgb)", name));
}

std::string_view to_string(ToneMap tonemap) {
  switch (tonemap) {
    case ToneMap::aces: return "aces";
    case ToneMap::pbr_neutral: return "pbr-neutral";
    case ToneMap::none: break;
  }
  return "none";
}

ToneMap parse_tonemap(std::string_view name) {
  for (ToneMap t : {ToneMap::none, ToneMap::aces, ToneMap::pbr_neutral})
    if (name == to_string(t)) return t;
  throw InputError(fmt::format("unknown tone map '{}' (expected none, aces or pbr-neutral)", name));
}

std::string to_string(const DisplayTransform& display) {
  std::string text(to_string(display.encoding));
  if (display.exposure_ev != 0.0) text += fmt::format(", exposure {:+g} EV", display.exposure_ev);
  if (display.tonemap != ToneMap::none) text += fmt::format(", tone map {}", to_string(display.tonemap));
  return text;
}

DisplayTransform parse_display_transform(std::string_view text) {
  DisplayTransform display;
  std::size_t start = 0;
  for (int part = 0; start <= text.size(); ++part) {
    const std::size_t end = std::min(text.find(", ", start), text.size());
    const std::string_view item = text.substr(start, end - start);
    if (part == 0) {
      display.encoding = parse_display_encoding(item);
    } else if (item.starts_with("exposure ") && item.ends_with(" EV")) {
      const std::string number(item.substr(9, item.size() - 12));
      char* end_of_number = nullptr;
      display.exposure_ev = std::strtod(number.c_str(), &end_of_number);
      if (number.empty() || end_of_number != number.c_str() + number.size() || !std::isfinite(display.exposure_ev))
        throw InputError(fmt::format("bad exposure in display transform '{}'", text));
    } else if (item.starts_with("tone map ")) {
      display.tonemap = parse_tonemap(item.substr(9));
    } else {
      throw InputError(fmt::format("unknown part '{}' of display transform '{}'", item, text));
    }
    start = end + 2;
  }
  return display;
}

}  // namespace rt
