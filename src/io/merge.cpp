#include "rt/io/merge.h"

#include <algorithm>
#include <filesystem>
#include <optional>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/io/image_io.h"
#include "rt/scene/scene.h"

namespace rt {

namespace {

namespace fs = std::filesystem;

struct RegionFile {
  std::string path;
  PixelRegion region;
  ImageHeader header;
};

std::string attribute(const ImageHeader& header, std::string_view name) {
  for (const auto& [key, value] : header.attributes)
    if (key == name) return value;
  return "";
}

// Tile numbers K of "tile K/N" parts, and N (0 when no part is a tile).
std::pair<std::set<int>, int> tile_numbers(const std::vector<RegionFile>& files) {
  std::set<int> present;
  int count = 0;
  for (const RegionFile& file : files) {
    int k = 0, n = 0;
    if (std::sscanf(attribute(file.header, kPartAttribute).c_str(), "tile %d/%d", &k, &n) == 2) {
      present.insert(k);
      count = n;
    }
  }
  return {present, count};
}

}  // namespace

Image merge_regions(const std::vector<std::string>& paths, DisplayTransform* display) {
  if (paths.empty()) throw InputError("rt merge: no region files given");
  std::vector<RegionFile> files;
  Image full;
  for (const std::string& path : paths) {
    RegionFile file{path, {}, {}};
    Image part = read_image(path, &file.header);
    if (attribute(file.header, kSceneAttribute).empty())
      throw InputError(path, "", "not a region file (no rt:scene attribute): write regions with rt render --crop or --tile and an .exr output");
    file.region = file.header.data_window.value_or(full_region(part.width, part.height));
    if (!files.empty()) {
      const RegionFile& first = files.front();
      for (const char* name : {kSceneAttribute, kSettingsAttribute, kVersionAttribute, kDisplayAttribute}) {
        const std::string mine = attribute(file.header, name), theirs = attribute(first.header, name);
        if (mine != theirs)
          throw InputError(path, "", fmt::format("{} is '{}' but '{}' in {}: the regions come from different renders",
                                                 name, mine, theirs, first.path));
      }
      if (file.header.full_width != first.header.full_width || file.header.full_height != first.header.full_height)
        throw InputError(path, "", fmt::format("belongs to a {}x{} image, {} to a {}x{} one", file.header.full_width,
                                               file.header.full_height, first.path, first.header.full_width,
                                               first.header.full_height));
    } else {
      const int width = file.header.full_width, height = file.header.full_height;
      if (width < 1 || height < 1 || width > kMaxImageSide || height > kMaxImageSide)
        throw InputError(path, "", fmt::format("its display window is {}x{}; rt writes 1 to {} pixels a side", width,
                                               height, kMaxImageSide));
      if (const auto shortfall = memory_shortfall(full_region(width, height).pixel_count() * (2 * sizeof(Color) + 3)))
        throw InputError(path, "", fmt::format("the merged {}x{} image {}", width, height, *shortfall));
      full = Image(width, height);
    }
    if (!file.region.inside(full.width, full.height))
      throw InputError(path, "", fmt::format("its pixels {} (x0 y0 x1 y1) lie outside the {}x{} image",
                                             to_string(file.region), full.width, full.height));
    for (const RegionFile& other : files) {
      std::error_code error;
      if (fs::equivalent(path, other.path, error)) throw InputError(path, "", "given twice");
      const PixelRegion overlap{std::max(file.region.x0, other.region.x0), std::max(file.region.y0, other.region.y0),
                                std::min(file.region.x1, other.region.x1), std::min(file.region.y1, other.region.y1)};
      if (!overlap.empty())
        throw InputError(path, "", fmt::format("overlaps {} in pixels {} (x0 y0 x1 y1)", other.path, to_string(overlap)));
    }
    for (int y = 0; y < part.height; ++y)
      std::copy_n(&part.at(0, y), part.width, &full.at(file.region.x0, file.region.y0 + y));
    files.push_back(std::move(file));
  }

  // No overlaps: the parts cover the image exactly once when their areas add up to it.
  std::uint64_t covered = 0;
  for (const RegionFile& file : files) covered += file.region.pixel_count();
  if (display) {
    const std::string recorded = attribute(files.front().header, kDisplayAttribute);
    *display = recorded.empty() ? DisplayTransform{} : parse_display_transform(recorded);
  }
  if (covered == full_region(full.width, full.height).pixel_count()) return full;
  std::string missing;
  if (const auto [present, n] = tile_numbers(files); n > 0) {
    std::vector<int> absent;
    for (int k = 1; k <= n; ++k)
      if (!present.contains(k)) absent.push_back(k);
    missing = fmt::format(" (missing tile{} {} of {})", absent.size() == 1 ? "" : "s", fmt::join(absent, ", "), n);
  }
  for (int y = 0; y < full.height; ++y) {  // the first uncovered pixel: the first gap in a row's spans
    std::vector<std::pair<int, int>> spans;
    for (const RegionFile& file : files)
      if (y >= file.region.y0 && y < file.region.y1) spans.emplace_back(file.region.x0, file.region.x1);
    std::sort(spans.begin(), spans.end());
    int x = 0;
    for (const auto& [x0, x1] : spans) {
      if (x0 > x) break;
      x = std::max(x, x1);
    }
    if (x < full.width)
      throw InputError(fmt::format("rt merge: the {} region file(s) leave {} of the {}x{} image's pixels uncovered, "
                                   "the first at ({}, {}){}", files.size(),
                                   full_region(full.width, full.height).pixel_count() - covered, full.width,
                                   full.height, x, y, missing));
  }
  return full;  // not reached: the areas fall short only if some pixel is uncovered
}

}  // namespace rt
