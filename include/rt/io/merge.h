#pragma once
// Stitching region files (rt render --crop/--tile) back into the whole image: rt merge.

#include <string>
#include <vector>

#include "rt/core/display.h"
#include "rt/core/image.h"

namespace rt {

// Region file attributes: which scene (scene_fingerprint), which pixel-deciding options, which rt
// and which part. rt merge requires the first three to agree across the files it stitches.
inline constexpr const char* kSceneAttribute = "rt:scene";
inline constexpr const char* kSettingsAttribute = "rt:settings";
inline constexpr const char* kVersionAttribute = "rt:version";
inline constexpr const char* kPartAttribute = "rt:part";  // "tile K/N" or "crop X0 Y0 X1 Y1"

// The whole image assembled from region files: each file's pixels go where its data window says.
// Throws InputError naming the file when one is not a region file, was rendered from another
// scene, with other settings, by another rt or at another image size than the first, lies outside
// the image or overlaps another (naming both); or naming the first pixel no file covers (and, for
// --tile parts, the missing tile numbers).
// `display`, when given, receives the display transform the regions record (rt:display; linear
// when absent), for the merged image's 8-bit encoding.
Image merge_regions(const std::vector<std::string>& paths, DisplayTransform* display = nullptr);

}  // namespace rt
