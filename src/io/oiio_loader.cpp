// Finds and loads rt-oiio.so (see oiio_module.h).

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>

#include <fmt/format.h>

#include "io/oiio_module.h"
#include "rt/core/error.h"

namespace rt {

namespace fs = std::filesystem;

namespace {

constexpr const char* kModuleFile = "rt-oiio.so";

// Where to look, in order: $RT_OIIO_MODULE (a file), lib/ beside the executable's directory (the
// layout of the build tree, whose executables live one directory below it), and the build tree
// the library was compiled in.
std::vector<fs::path> module_candidates() {
  std::vector<fs::path> candidates;
  if (const char* path = std::getenv("RT_OIIO_MODULE"); path && *path) return {path};
  std::error_code error;
  const fs::path executable = fs::read_symlink("/proc/self/exe", error);
  if (!error) candidates.push_back(executable.parent_path().parent_path() / "lib" / kModuleFile);
  candidates.push_back(fs::path(RT_OIIO_MODULE_DIR) / kModuleFile);
  return candidates;
}

const OiioModule* load_module() {
  std::string tried;
  for (const fs::path& candidate : module_candidates()) {
    std::error_code error;
    if (!fs::exists(candidate, error)) {
      tried += fmt::format("{}{} (absent)", tried.empty() ? "" : ", ", candidate.string());
      continue;
    }
    void* handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
    const char* reason = handle ? nullptr : dlerror();
    if (handle) {
      using Entry = const OiioModule* (*)();
      if (auto entry = reinterpret_cast<Entry>(dlsym(handle, "rt_oiio_module"))) return entry();
      reason = "no rt_oiio_module symbol";
    }
    tried += fmt::format("{}{} ({})", tried.empty() ? "" : ", ", candidate.string(), reason ? reason : "?");
  }
  throw RuntimeError(fmt::format("cannot load the OpenImageIO module {}, needed to read or write this image "
                                 "format; tried {}. Set RT_OIIO_MODULE to its path.",
                                 kModuleFile, tried));
}

}  // namespace

const OiioModule& oiio_module() {
  static std::once_flag once;
  static const OiioModule* module = nullptr;
  std::call_once(once, [] { module = load_module(); });  // a throw leaves the flag unset: tried again
  return *module;
}

}  // namespace rt
