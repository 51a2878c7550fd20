// libFuzzer target: the .test loader (see fuzz_scene.h).
#include "fuzz_scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return rt_fuzz::fuzz_scene_file(data, size, ".test");
}
