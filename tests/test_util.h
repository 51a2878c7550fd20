#pragma once
// Small helpers shared by the test files: hand-built scenes, a scratch directory, running `rt`.

#include <stdlib.h>  // mkdtemp
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "catch.h"
#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/render/render.h"
#include "rt/render/surface_test.h"
#include "rt/scene/scene.h"

namespace rt_test {

// A mesh of the given triangles (each three corners, counter-clockwise), every vertex carrying
// the triangle's geometric normal, so the mesh is flat-shaded and needs no normal computation.
inline rt::TriangleMesh make_flat_mesh(const std::vector<std::array<rt::Vec3f, 3>>& corners) {
  rt::TriangleMesh mesh;
  for (const auto& c : corners) {
    const auto base = static_cast<unsigned>(mesh.positions.size());
    const rt::Vec3f n = glm::normalize(glm::cross(c[1] - c[0], c[2] - c[0]));
    for (const rt::Vec3f& p : c) {
      mesh.positions.push_back(p);
      mesh.normals.push_back(n);
    }
    mesh.triangles.push_back({base, base + 1, base + 2});
  }
  return mesh;
}

// A scene whose root node (index 0, identity transform) holds one model per (mesh, material)
// pair; the materials vector is left to the caller.
inline rt::Scene make_scene(const std::vector<std::pair<rt::TriangleMesh, std::uint32_t>>& models) {
  rt::Scene scene;
  scene.source = "<test>";
  rt::Node root;
  root.name = "root";
  for (const auto& [mesh, material] : models)
    root.models.push_back({std::make_shared<const rt::TriangleMesh>(mesh), material});
  scene.nodes.push_back(std::move(root));
  return scene;
}

// Every intersector a test can build: Embree's three kernels and both references.
struct Intersector {
  const char* name;
  rt::AccelKind kind;
  rt::EmbreeKernel kernel;
  // This intersector over `flat` with `test` (may be null) as its surface test.
  std::unique_ptr<rt::Accel> build(const rt::FlatScene& flat, const rt::SurfaceTest* test) const {
    rt::AccelOptions options;
    options.embree_kernel = kernel;
    options.surface_test = test;
    return rt::build_accel(kind, flat, options);
  }
};
inline constexpr Intersector kIntersectors[] = {
    {"embree native", rt::AccelKind::embree, rt::EmbreeKernel::native},
    {"embree watertight", rt::AccelKind::embree, rt::EmbreeKernel::watertight},
    {"embree exact", rt::AccelKind::embree, rt::EmbreeKernel::exact},
    {"reference", rt::AccelKind::reference, rt::EmbreeKernel::native},
    {"reference barycentric", rt::AccelKind::reference_barycentric, rt::EmbreeKernel::native}};

// Renders `scene` on one thread with Embree and the scene's surface test (alpha, culling), as
// rt render does; the linear image.
inline rt::Image render_as_rt_does(const rt::Scene& scene) {
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const rt::SceneSurfaceTest test(scene, flat);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat, rt::with_surface_test({}, test));
  rt::RenderOptions options;
  options.threads = 1;
  return rt::render_image(scene, flat, *accel, options).image;
}

// Whole file contents as bytes ("" if it cannot be read).
inline std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

inline void write_file(const std::filesystem::path& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary);
  out << content;
}

// A fresh, empty directory under the system temporary directory, removed with its contents
// when the object goes out of scope.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "rt_tests_XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

  // Names of the directory's entries, sorted.
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(path_)) names.push_back(entry.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  std::filesystem::path path_;
};

// Exit status and output of one run of the `rt` executable.
struct RtRun {
  int status = -1;
  std::string out, err;
};

// Runs `EXECUTABLE ARGS` (ARGS already shell-quoted as needed) with `cwd` as working directory;
// stdout and stderr go to files in a separate directory, so `cwd` ends up holding exactly what the
// program wrote. run_rt_in runs the `rt` executable.
inline RtRun run_in(const TempDir& cwd, const std::string& executable, const std::string& args) {
  auto quoted = [](const std::string& s) { return "'" + s + "'"; };
  TempDir capture;
  const std::string command = "cd " + quoted(cwd.path().string()) + " && " + quoted(executable) + " " + args +
                              " >" + quoted(capture / "out") + " 2>" + quoted(capture / "err") + " </dev/null";
  const int raw = std::system(command.c_str());
  RtRun run;
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.out = read_file(capture / "out");
  run.err = read_file(capture / "err");
  return run;
}

inline RtRun run_rt_in(const TempDir& cwd, const std::string& args) { return run_in(cwd, RT_EXECUTABLE, args); }

// The material of `scene` called `name`; throws when there is none.
inline const rt::Material& material_named(const rt::Scene& scene, std::string_view name) {
  for (const rt::Material& m : scene.materials)
    if (m.name == name) return m;
  throw std::runtime_error("no material '" + std::string(name) + "'");
}

// A small valid native scene, 32x24: one red sphere under one directional light. `extra` is
// spliced in as the first top-level keys (e.g. R"("output": "x.png",)").
inline std::string small_json_scene(const std::string& extra = "") {
  return "{ " + extra + R"(
  "image": { "width": 32, "height": 24 },
  "camera": { "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 45 },
  "materials": { "red": { "diffuse": [0.8, 0.1, 0.1], "ambient": 0.1 } },
  "lights": [ { "type": "directional", "direction": [1, 1, 1] } ],
  "nodes": [ { "models": [ { "geometry": { "type": "sphere" }, "material": "red" } ] } ]
})";
}

// The shared data folder `relative` (below RT_SHARED_DATA_DIR), or nullopt with a warning that the
// corpus is skipped when it is absent.
inline std::optional<std::filesystem::path> shared_dir(const std::filesystem::path& relative) {
  const std::filesystem::path dir = std::filesystem::path(RT_SHARED_DATA_DIR) / relative;
  std::error_code error;
  if (std::filesystem::is_directory(dir, error)) return dir;
  WARN("shared data not found at " << dir.string() << " (RT_SHARED_DATA_DIR): skipping that corpus");
  return std::nullopt;
}

// The files below `dir` whose extension is one of `extensions` (".obj"), sorted.
inline std::vector<std::filesystem::path> files_with(const std::filesystem::path& dir,
                                                     const std::vector<std::string>& extensions) {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (std::find(extensions.begin(), extensions.end(), entry.path().extension().string()) != extensions.end())
      files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

// The shared glTF and OBJ models (data/models), glTF first; empty, with a warning, without them.
inline std::vector<std::filesystem::path> shared_model_files() {
  std::vector<std::filesystem::path> files;
  if (const auto gltf = shared_dir(std::filesystem::path("data") / "models" / "gltf"))
    files = files_with(*gltf, {".gltf", ".glb"});
  if (const auto obj = shared_dir(std::filesystem::path("data") / "models" / "obj"))
    for (const std::filesystem::path& file : files_with(*obj, {".obj"})) files.push_back(file);
  return files;
}

// `scene` rendered `width` pixels wide, its aspect ratio kept.
inline rt::Scene at_width(rt::Scene scene, int width) {
  scene.settings.height = std::max(1, int(std::lround(double(scene.settings.height) * width / scene.settings.width)));
  scene.settings.width = width;
  return scene;
}

}  // namespace rt_test
