// libFuzzer target: the glTF loader, text (.gltf) and binary (.glb, chosen when the input starts
// with the GLB magic "glTF"), see fuzz_scene.h.
#include "fuzz_scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool binary = size >= 4 && std::string_view(reinterpret_cast<const char*>(data), 4) == "glTF";
  return rt_fuzz::fuzz_scene_file(data, size, binary ? ".glb" : ".gltf");
}
