#pragma once
// libFuzzer harness shared by the loader targets: the input becomes a scene file in a private
// temporary directory and goes through load + validate + flatten, and, when small, Embree build
// and a 16x12 render. Errors the loaders report (rt::InputError, rt::RuntimeError) are the
// expected outcome for malformed input; anything else escaping is a finding: an uncaught
// exception aborts, and the sanitizers report memory and undefined-behaviour bugs.

#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "rt/accel/accel.h"
#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_scene.h"
#include "rt/render/render.h"
#include "rt/render/surface_test.h"

namespace rt_fuzz {

// Memory the checks in rt/core/memory.h may hand out: below libFuzzer's default RSS limit
// (2 GiB), so a huge request is refused by the renderer, as in real use, not reported as an OOM.
inline constexpr std::uint64_t kMemoryLimit = std::uint64_t(1) << 30;
// Inputs whose flattened scene is larger than this are loaded and flattened but not rendered.
inline constexpr std::size_t kMaxRenderedPrimitives = 20000;

inline const std::filesystem::path& work_directory() {
  static const std::filesystem::path dir = [] {
    std::string pattern = (std::filesystem::temp_directory_path() / "rt_fuzz_XXXXXX").string();
    if (!mkdtemp(pattern.data())) std::abort();
    rt::set_memory_limit(kMemoryLimit);
    return std::filesystem::path(pattern);
  }();
  return dir;
}

inline void write(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// Loads, validates, flattens and (when small) renders `file`; loader errors are swallowed.
inline void exercise(const std::filesystem::path& file) {
  try {
    rt::Scene scene = rt::load_scene(file.string());
    rt::validate_scene(scene);
    const rt::FlatScene flat = rt::flatten_scene(scene);
    if (flat.triangle_count() + flat.spheres.size() > kMaxRenderedPrimitives) return;
    scene.settings.width = 16;
    scene.settings.height = 12;
    scene.settings.max_depth = std::min(scene.settings.max_depth, 3);
    const rt::SceneSurfaceTest surface_test(scene, flat);  // alpha and culling filters, as rt render builds them
    const std::unique_ptr<rt::Accel> accel =
        rt::build_accel(rt::AccelKind::embree, flat, rt::with_surface_test({}, surface_test));
    rt::RenderOptions options;
    options.threads = 1;
    rt::render_image(scene, flat, *accel, options);
  } catch (const rt::InputError&) {
  } catch (const rt::RuntimeError&) {
  }
}

// The whole input as a scene file named scene<extension>.
inline int fuzz_scene_file(const std::uint8_t* data, std::size_t size, const char* extension) {
  const std::filesystem::path file = work_directory() / (std::string("scene") + extension);
  write(file, std::string_view(reinterpret_cast<const char*>(data), size));
  exercise(file);
  return 0;
}

}  // namespace rt_fuzz
