#pragma once
// Image files, format chosen by the file extension: PNG and PPM written by rt itself, every other
// format (and all reading) through OpenImageIO, which is loaded only then.

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rt/core/display.h"
#include "rt/core/image.h"
#include "rt/render/region.h"

namespace rt {

// The image as interleaved 8-bit RGB, rows top to bottom, through `display` (encode_8bit; the
// default is quantize_8bit).
std::vector<std::uint8_t> to_rgb8(const Image& image, const DisplayTransform& display = {});

// True for extensions written as linear float (.exr, .hdr); everything else is 8-bit.
bool writes_float(const std::string& path);

// Throws InputError unless rt or OpenImageIO can write the format named by `path`'s extension
// (compared ignoring case); the message lists the extensions that can be written.
void check_image_format(const std::string& path);

// A note for the user when `path`'s format does not keep 8-bit pixels exactly (GIF's palette,
// JPEG's and WebP's lossy compression), else empty.
std::string lossy_format_note(const std::string& path);

// Throws InputError unless rt or OpenImageIO can write the format named by `path`'s extension and the
// directory `path` names exists and is writable. Lets callers refuse a bad output before rendering.
void check_output_path(const std::string& path);

// Where an image's pixels lie in a larger image, and text attributes stored with them: what
// OpenEXR keeps as the data window, the display window and string header attributes. Region files
// (rt render --crop/--tile) carry them for rt merge.
struct ImageHeader {
  std::optional<PixelRegion> data_window;  // full-image pixels the image holds; unset: all of it
  int full_width = 0, full_height = 0;     // the display window (with data_window)
  std::vector<std::pair<std::string, std::string>> attributes;  // names start with "rt:"
};

// The attribute of float files that names the display transform of their 8-bit renditions
// (to_string(DisplayTransform)); rt merge applies it.
inline constexpr const char* kDisplayAttribute = "rt:display";

// Writes `image` to `path` (png, jpg, exr, hdr, tif, bmp, ppm and any other format OIIO writes).
// The file is written next to the destination under a temporary name and renamed into place,
// so a failed write never leaves a partial file and never touches an existing one. EXR keeps
// `header` (other formats may drop it). Throws InputError for an unknown extension, RuntimeError
// for I/O failures.
// 8-bit formats are encoded through `display`; float formats stay linear and record it as the
// "rt:display" attribute (EXR).
void write_image(const Image& image, const std::string& path, const ImageHeader& header = {},
                 const DisplayTransform& display = {});

// Writes interleaved 8-bit RGB (rows top to bottom, width * height * 3 bytes) in any 8-bit format
// write_image writes, through the same encoders: write_rgb8(w, h, to_rgb8(image), path) writes the
// file write_image(image, path) does. Throws InputError for .exr/.hdr or an unknown extension.
void write_rgb8(int width, int height, const std::vector<std::uint8_t>& rgb8, const std::string& path);

// Reads any OIIO-readable image as float RGB (extra channels dropped, grey expanded, colour not
// multiplied by alpha); 8-bit data is mapped to c / 255 without colour conversion. When `header` is given it receives the data
// window (set only if the file has one that differs from its display window), the display window
// and the "rt:" string attributes. Throws InputError when unreadable.
Image read_image(const std::string& path, ImageHeader* header = nullptr);

}  // namespace rt
