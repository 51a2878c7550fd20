// libFuzzer target: the OBJ loader and its MTL reader (see fuzz_scene.h). An input holding a line
// "#MTL" is split there: what follows becomes fuzz.mtl beside the OBJ, for "mtllib fuzz.mtl".
#include "fuzz_scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t split = input.find("\n#MTL\n");
  const auto& dir = rt_fuzz::work_directory();
  rt_fuzz::write(dir / "fuzz.mtl", split == std::string_view::npos ? std::string_view() : input.substr(split + 6));
  rt_fuzz::write(dir / "scene.obj", input.substr(0, split));
  rt_fuzz::exercise(dir / "scene.obj");
  return 0;
}
