#pragma once
// The display transform: how linear radiance becomes the 8-bit values of PNG, JPEG, PPM and the
// viewer's window (docs/display.md). Float outputs (EXR, HDR) stay linear and record it. Scenes
// carry one (RenderSettings::display); the command line overrides it.

#include <cstdint>
#include <string>
#include <string_view>

#include "rt/core/math.h"

namespace rt {

enum class DisplayEncoding {
  linear,  // byte = floor(255 c): the CSE167x course's quantisation, which its reference images use
  srgb,    // the sRGB transfer function (IEC 61966-2-1), rounded: what viewers assume an 8-bit file holds
};

enum class ToneMap {
  none,         // clamp to [0, 1]
  aces,         // Narkowicz's fit of the ACES filmic curve, per channel
  pbr_neutral,  // Khronos PBR Neutral (2024): base colours kept up to 0.76, highlights compressed
};

// Exposure, then the tone map, then the encoding, per pixel. The default is the identity of the
// course: linear, 0 EV, no tone map.
struct DisplayTransform {
  DisplayEncoding encoding = DisplayEncoding::linear;
  double exposure_ev = 0.0;  // the linear colour is scaled by 2^exposure_ev first
  ToneMap tonemap = ToneMap::none;

  bool operator==(const DisplayTransform&) const = default;
};

// 8-bit quantisation of the course scenes (the identity DisplayTransform): clamp to [0, 1], then
// byte = floor(255 c) in float, no transfer function. (The CSE167x references were made this way;
// round() would disagree on most pixels.) NaN maps to 0.
std::uint8_t quantize_8bit(float c);

// The 8-bit RGB of the linear colour `c` (linear RGB, any range; NaN maps to 0).
void encode_8bit(const Color& c, const DisplayTransform& display, std::uint8_t out[3]);

// "srgb", "linear, exposure +1 EV, tone map pbr-neutral": how the transform is named in messages
// and recorded in float files ("rt:display"); parse_display_transform reads it back.
std::string to_string(const DisplayTransform& display);
DisplayTransform parse_display_transform(std::string_view text);

// Names as on the command line ("linear", "srgb"; "none", "aces", "pbr-neutral"). The parse
// functions throw InputError on anything else.
std::string_view to_string(DisplayEncoding encoding);
DisplayEncoding parse_display_encoding(std::string_view name);
std::string_view to_string(ToneMap tonemap);
ToneMap parse_tonemap(std::string_view name);

}  // namespace rt
