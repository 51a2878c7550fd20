// rt-perf export-mitsuba: the PLY files, scene.json as rt render would load the scene, bad arguments.

#include "catch.h"

#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "export.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// A cube around the origin (outward normals) and a sphere of radius 2 at (3, 0, 0), under a point
// light with inverse-square falloff.
const char* const kScene = R"({
  "image": { "width": 40, "height": 30 },
  "camera": { "eye": [0, 0, 6], "target": [0, 0, 0], "fovy": 50 },
  "materials": { "grey": { "diffuse": 0.5 }, "red": { "ambient": 0.1, "diffuse": [0.7, 0.1, 0.1] } },
  "lights": [ { "type": "point", "position": [1, 4, 3], "color": 2, "attenuation": [0, 0, 1] } ],
  "nodes": [ { "models": [ { "geometry": { "type": "cube" }, "material": "grey" } ] },
             { "translate": [3, 0, 0], "models": [ { "geometry": { "type": "sphere", "radius": 2 }, "material": "red" } ] } ]
})";

}  // namespace

TEST_CASE("export: a material's PLY holds its triangles, vertices renumbered in order of first use", "[perf]") {
  rt::FlatScene flat;
  flat.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {5, 5, 5}};
  flat.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {1, 0, 0}};
  flat.triangles = {{1, 3, 2}, {4, 4, 4}, {0, 1, 2}};  // the middle one belongs to material 1
  flat.material_ids = {0, 1, 0};
  rt_test::TempDir dir;
  CHECK(rt::perf::write_material_ply(flat, 0, dir / "m.ply", "two\nlines") == 2);
  const std::string bytes = read_bytes(dir / "m.ply");
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment two lines\nelement vertex 4\n"
      "property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
  REQUIRE(bytes.substr(0, header.size()) == header);
  REQUIRE(bytes.size() == header.size() + 4 * 6 * sizeof(float) + 2 * (1 + 3 * sizeof(std::int32_t)));
  const char* data = bytes.data() + header.size();
  float vertex[6];
  std::memcpy(vertex, data + 1 * sizeof vertex, sizeof vertex);  // local vertex 1 is global vertex 3
  CHECK(vertex[0] == 1.0f);
  CHECK(vertex[1] == 1.0f);
  CHECK(vertex[5] == 1.0f);
  const char* faces = data + 4 * sizeof vertex;
  std::int32_t first[3], second[3];
  CHECK(faces[0] == 3);
  std::memcpy(first, faces + 1, sizeof first);
  CHECK(faces[13] == 3);
  std::memcpy(second, faces + 14, sizeof second);
  CHECK((first[0] == 0 && first[1] == 1 && first[2] == 2));   // global 1 3 2, winding kept
  CHECK((second[0] == 3 && second[1] == 0 && second[2] == 2));  // global 0 1 2
}

TEST_CASE("rt-perf export-mitsuba writes scene.json and one PLY per material, as rt render loads the scene",
          "[perf]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir.path() / "scene.json", kScene);
  const rt_test::RtRun run =
      rt_test::run_in(dir, RT_PERF_EXECUTABLE, "export-mitsuba scene.json --out out --width 20 --fovy 40");
  INFO("stderr: " << run.err);
  REQUIRE(run.status == 0);
  const nlohmann::json scene = read_json(dir / "out/scene.json");
  CHECK(scene.at("image") == nlohmann::json({{"width", 20}, {"height", 15}}));  // 40x30's aspect ratio kept
  CHECK(scene.at("camera").at("fovy") == 40.0);
  CHECK(scene.at("camera").at("eye") == nlohmann::json({0.0, 0.0, 6.0}));
  CHECK(scene.at("headlight") == false);
  REQUIRE(scene.at("lights").size() == 1);
  CHECK(scene.at("lights")[0].at("position") == nlohmann::json({1.0, 4.0, 3.0, 1.0}));
  CHECK(scene.at("lights")[0].at("attenuation") == nlohmann::json({0.0, 0.0, 1.0}));
  REQUIRE(scene.at("materials").size() == 2);
  const nlohmann::json& grey = scene.at("materials")[0];
  CHECK(grey.at("name") == "grey");
  CHECK(grey.at("triangles") == 12);
  CHECK(grey.at("mesh") == "mesh-0.ply");
  CHECK(grey.at("reflective").is_null());
  CHECK(grey.at("diffuse_texture").is_null());
  const nlohmann::json& red = scene.at("materials")[1];
  CHECK(red.at("ambient") == nlohmann::json({0.10000000149011612, 0.10000000149011612, 0.10000000149011612}));
  CHECK(red.at("triangles") == 0);
  CHECK(red.at("spheres") == 1);
  CHECK(red.at("mesh").is_null());
  CHECK(scene.at("spheres") == nlohmann::json::parse(R"([{"material": 1, "to_world":
      [[2.0, 0.0, 0.0, 3.0], [0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 2.0, 0.0], [0.0, 0.0, 0.0, 1.0]]}])"));
  CHECK(scene.at("camera_rays") == 300);
  CHECK(scene.at("camera_back_face_hits") == 0);
  CHECK(fs::exists(dir / "out/mesh-0.ply"));
  CHECK_FALSE(fs::exists(dir / "out/mesh-1.ply"));

  // From inside the cube every camera ray meets a face from behind; a tessellated sphere has a mesh.
  const rt_test::RtRun inside = rt_test::run_in(
      dir, RT_PERF_EXECUTABLE, "export-mitsuba scene.json --out in --eye 0 0 0.1 --sphere-tessellation 8");
  INFO("stderr: " << inside.err);
  REQUIRE(inside.status == 0);
  const nlohmann::json in = read_json(dir / "in/scene.json");
  CHECK(in.at("camera_back_face_hits") == in.at("camera_rays"));
  CHECK(in.at("spheres").empty());
  CHECK(in.at("materials")[1].at("mesh") == "mesh-1.ply");
}

TEST_CASE("rt-perf export-mitsuba: an OBJ gets rt render's default lights, bad input fails in one line", "[perf]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir.path() / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const rt_test::RtRun obj = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "export-mitsuba tri.obj --out o");
  REQUIRE(obj.status == 0);
  const nlohmann::json scene = read_json(dir / "o/scene.json");
  CHECK(scene.at("headlight") == true);
  REQUIRE(scene.at("lights").size() == 2);  // the default key light and headlight
  CHECK(scene.at("lights")[1].at("attenuation") == nlohmann::json({1.0, 0.0, 0.0}));
  CHECK(scene.at("notices").size() == 1);

  const rt_test::RtRun missing = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "export-mitsuba none.json --out o");
  CHECK(missing.status == 1);
  CHECK(missing.err == "rt-perf: error: none.json: no such file\n");
  CHECK(rt_test::run_in(dir, RT_PERF_EXECUTABLE, "export-mitsuba tri.obj").status == 2);  // --out is required
  const rt_test::RtRun camera = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "export-mitsuba tri.obj --out o --up 0 0 0");
  CHECK(camera.status == 2);
  CHECK_THAT(camera.err, Catch::Matchers::StartsWith("rt-perf: error: --up"));
  rt_test::write_file(dir.path() / "file", "");
  const rt_test::RtRun out = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "export-mitsuba tri.obj --out file");
  CHECK(out.status == 1);
  CHECK_THAT(out.err, Catch::Matchers::ContainsSubstring("--out file: cannot create the directory"));
}
