// Whole OBJ/MTL scenes (load_obj_scene), the default framing and headlight, and the camera, light
// and background flags of the `rt` executable.

#include <catch2/catch.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_obj.h"
#include "rt/io/load_scene.h"
#include "rt/render/texture.h"
#include "rt/scene/framing.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

using rt_test::read_file;
using rt_test::run_rt_in;
using rt_test::write_file;

std::string quoted(const std::string& s) { return "'" + s + "'"; }

// A unit quad in the z = 0 plane facing +z, split into two faces with different materials:
// `matte` (illum 2) and `mirror` (illum 3).
const char* const kQuadObj = R"(# two materials on one quad
mtllib quad.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
o quad
usemtl matte
f 1 2 3
usemtl mirror
f 1 3 4
)";

const char* const kQuadMtl = R"(newmtl matte
Ka 0.1 0.2 0.3
Kd 0.4 0.5 0.6
Ks 0.7 0.8 0.9
Ke 0.01 0.02 0.03
Ns 42
illum 2

newmtl mirror
Kd 0 0 0
Ks 0.9 0.9 0.9
Ns 100
illum 3
map_Kd mirror.png
)";

// A square pyramid without normals: apex over the centre of a quad base.
const char* const kPyramidObj = R"(v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
v 0 1 0
f 1 2 3 4
f 4 3 5
f 3 2 5
f 2 1 5
f 1 4 5
)";

std::size_t model_count(const rt::Scene& scene) { return scene.nodes[scene.root].models.size(); }

const rt::Material& material_of(const rt::Scene& scene, std::size_t model) {
  return scene.materials[scene.nodes[scene.root].models[model].material];
}

// Fraction of pixels that differ from `background` in any channel.
double covered_fraction(const rt::Image& image, rt::Color background) {
  std::size_t covered = 0;
  for (const rt::Color& c : image.pixels) covered += c != background;
  return double(covered) / double(image.pixels.size());
}

bool all_finite(const rt::Image& image) {
  for (const rt::Color& c : image.pixels)
    if (!std::isfinite(c.r) || !std::isfinite(c.g) || !std::isfinite(c.b)) return false;
  return true;
}

}  // namespace

TEST_CASE("OBJ scene: one model per material, MTL mapped, quads triangulated", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "quad.obj", kQuadObj);
  write_file(dir.path() / "quad.mtl", kQuadMtl);
  rt::LoadReport report;
  const rt::Scene scene = rt::load_scene(dir / "quad.obj", {}, &report);

  REQUIRE(model_count(scene) == 2);
  const rt::Material& matte = material_of(scene, 0);
  const rt::Material& mirror = material_of(scene, 1);
  CHECK(matte.name == "matte");
  CHECK(matte.ambient == rt::Color(0.1f, 0.2f, 0.3f));
  CHECK(matte.diffuse == rt::Color(0.4f, 0.5f, 0.6f));
  CHECK(matte.specular == rt::Color(0.7f, 0.8f, 0.9f));
  CHECK(matte.emission == rt::Color(0.01f, 0.02f, 0.03f));
  CHECK(matte.shininess == 42.0f);
  REQUIRE(matte.reflective.has_value());
  CHECK(*matte.reflective == rt::Color(0.0f));  // illum 2: highlight from Ks, no mirror
  CHECK(mirror.name == "mirror");
  REQUIRE(mirror.reflective.has_value());
  CHECK(*mirror.reflective == rt::Color(0.9f));  // illum 3: Ks weights the mirror reflection
  for (std::size_t m = 0; m < 2; ++m) {
    const rt::TriangleMesh& mesh = *scene.nodes[scene.root].models[m].mesh;
    CHECK(mesh.triangles.size() == 1);
    CHECK(mesh.positions.size() == 3);  // renumbered densely per group
    for (const rt::Vec3f& n : mesh.normals) CHECK(n == rt::Vec3f(0, 0, 1));
  }

  // A map_Kd that cannot be read is reported and dropped; the camera and a headlight are made up
  // and reported.
  REQUIRE(report.warnings.size() == 1);
  CHECK_THAT(report.warnings[0], Catch::Contains("material 'mirror': map_Kd") && Catch::Contains("cannot be read"));
  CHECK(mirror.diffuse_texture.empty());
  CHECK(report.camera_framed);
  CHECK(report.headlight_added);
  CHECK(report.view == rt::Vec3d(0, 0, -1));
  REQUIRE(scene.lights.size() == 1);
  CHECK(scene.lights[0].position == rt::Vec4d(scene.camera.eye, 1.0));
  CHECK(scene.camera.target == rt::Vec3d(0.5, 0.5, 0.0));
  CHECK(scene.camera.eye.z > 0.0);
}

TEST_CASE("OBJ scene: a missing MTL file is a warning and the default material is used", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "quad.obj", kQuadObj);  // quad.mtl is not written
  rt::LoadReport report;
  const rt::Scene scene = rt::load_obj_scene(dir / "quad.obj", &report);
  REQUIRE(report.warnings.size() == 1);
  CHECK_THAT(report.warnings[0], Catch::Contains("quad.obj") && Catch::Contains("'quad.mtl' not found"));
  REQUIRE(model_count(scene) == 1);  // both faces fall back to the one default material
  CHECK(scene.nodes[scene.root].models[0].mesh->triangles.size() == 2);
  const rt::Material expected = rt::default_obj_material();
  const rt::Material& used = material_of(scene, 0);
  CHECK(used.name == expected.name);
  CHECK(used.diffuse == expected.diffuse);
  CHECK(used.reflective == expected.reflective);

  // The CLI prints the warning and still renders.
  const rt_test::RtRun run = run_rt_in(dir, "render --width 16 --height 12 -o out.png quad.obj");
  INFO("stderr: " << run.err);
  CHECK(run.status == 0);
  CHECK_THAT(run.err, Catch::Contains("warning:") && Catch::Contains("quad.mtl"));
  CHECK_THAT(run.err, Catch::Contains("headlight"));
  CHECK(fs::exists(dir.path() / "out.png"));
  const rt_test::RtRun quiet = run_rt_in(dir, "render --quiet --width 16 --height 12 -o out.png quad.obj");
  CHECK(quiet.status == 0);
  CHECK(quiet.err.empty());
}

TEST_CASE("OBJ scene: without vn, smooth angle-weighted normals, with vn, the file's", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "pyramid.obj", kPyramidObj);
  const rt::Scene scene = rt::load_obj_scene(dir / "pyramid.obj");
  REQUIRE(model_count(scene) == 1);
  const rt::TriangleMesh& mesh = *scene.nodes[scene.root].models[0].mesh;
  CHECK(mesh.triangles.size() == 6);
  rt::TriangleMesh expected = mesh;
  rt::compute_vertex_normals(expected);
  REQUIRE(mesh.normals.size() == mesh.positions.size());
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    CHECK(mesh.normals[i] == expected.normals[i]);
    if (mesh.positions[i] == rt::Vec3f(0, 1, 0)) CHECK(mesh.normals[i] == rt::Vec3f(0, 1, 0));  // symmetric apex
  }

  write_file(dir.path() / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 0 0\nvn 0 0 2\nf 1//1 2//2 3//2\n");
  const rt::Scene with_normals = rt::load_obj_scene(dir / "tri.obj");
  const rt::TriangleMesh& tri = *with_normals.nodes[with_normals.root].models[0].mesh;
  REQUIRE(tri.normals.size() == 3);
  CHECK(tri.normals[0] == rt::Vec3f(1, 0, 0));
  CHECK(tri.normals[1] == rt::Vec3f(0, 0, 1));  // normalised
}

TEST_CASE("OBJ scene: malformed files give one error naming the file and the line", "[obj]") {
  struct Case {
    const char* name;
    std::string content;
    std::string where;  // "bad.obj:LINE:"
    std::string reason;
  };
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  std::string long_face = "v 0 0 0\n";
  for (int i = 0; i < 300; ++i) long_face += fmt::format("v {} 1 0\n", i);
  long_face += "f 1 2 3\nf";
  for (int i = 1; i <= 300; ++i) long_face += fmt::format(" {}", i);
  long_face += "\n";
  const std::vector<Case> cases = {
      {"vertex index beyond the vertices", tri + "f 1 2 3\n# comment\nf 1 2 4\n", "bad.obj:6:", "vertex index 4 out of range"},
      {"index 0", tri + "f 0 1 2\n", "bad.obj:4:", "indices start at 1"},
      {"non-numeric index", tri + "f 1 2 x\n", "bad.obj:4:", "not a number"},
      {"relative index before the first vertex", tri + "f -1 -2 -4\n", "bad.obj:4:", "relative index"},
      {"normal index beyond the normals", tri + "vn 0 0 1\nf 1//1 2//1 3//2\n", "bad.obj:5:", "normal index 2 out of range"},
      {"index error after a polygon", tri + "v 1 1 0\nf 1 2 4 3\nf 1 2\nf 1 2 9\n", "bad.obj:7:", "vertex index 9"},
      {"face of 300 vertices", long_face, "bad.obj:303:", "more than 255 vertices"},
  };
  for (const Case& c : cases) {
    DYNAMIC_SECTION(c.name) {
      rt_test::TempDir dir;
      write_file(dir.path() / "bad.obj", c.content);
      try {
        rt::load_obj_scene(dir / "bad.obj");
        FAIL("no error");
      } catch (const rt::InputError& error) {
        CHECK_THAT(error.what(), Catch::Contains(c.where) && Catch::Contains(c.reason));
      }
      const rt_test::RtRun run = run_rt_in(dir, "render bad.obj");
      INFO("stderr: " << run.err);
      CHECK(run.status == 1);
      CHECK(std::count(run.err.begin(), run.err.end(), '\n') == 1);
      CHECK_THAT(run.err, Catch::StartsWith("rt: error: ") && Catch::Contains(c.where));
      CHECK(dir.entries() == std::vector<std::string>{"bad.obj"});  // nothing written
    }
  }
  SECTION("missing file") {
    rt_test::TempDir dir;
    CHECK_THROWS_WITH(rt::load_obj_scene(dir / "none.obj"), Catch::Contains("none.obj") && Catch::Contains("no such file"));
    const rt_test::RtRun run = run_rt_in(dir, "render none.obj");
    CHECK(run.status == 1);
    CHECK_THAT(run.err, Catch::Contains("none.obj: no such file"));
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("frame_bounds fits the bounding sphere in both fields of view", "[obj]") {
  rt::Bounds3d bounds;
  bounds.extend({-1, -2, -3});
  bounds.extend({3, 2, 1});
  for (double aspect : {0.5, 1.0, 2.0}) {
    const rt::Camera camera = rt::frame_bounds(bounds, aspect, {0, 0, -1}, {0, 1, 0}, 45.0);
    CHECK(camera.target == bounds.center());
    CHECK(camera.eye.x == Approx(1.0));
    CHECK(camera.eye.y == Approx(0.0));
    CHECK_FALSE(rt::find_camera_problem(camera));
    const double half_fovy = 22.5 * std::numbers::pi / 180.0;
    const double half_fovx = std::atan(std::tan(half_fovy) * aspect);
    const double distance = glm::length(camera.eye - camera.target);
    CHECK(bounds.radius() / distance == Approx(std::sin(std::min(half_fovy, half_fovx))));
  }
  // An up vector parallel to the view is replaced.
  CHECK_FALSE(rt::find_camera_problem(rt::frame_bounds(bounds, 1.0, {0, 1, 0}, {0, 1, 0})));
  // An empty box still gives a usable camera.
  CHECK_FALSE(rt::find_camera_problem(rt::frame_bounds(rt::Bounds3d{}, 1.0)));
}

TEST_CASE("OBJ scene: a box open towards -z is viewed from -z", "[obj]") {
  // Back wall at z = 1 facing -z (counter-clockwise seen from z < 1), as in the original Cornell box data.
  rt_test::TempDir dir;
  write_file(dir.path() / "wall.obj", "v 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\nf 1 2 3 4\n");
  rt::LoadReport report;
  const rt::Scene scene = rt::load_obj_scene(dir / "wall.obj", &report);
  CHECK(report.view == rt::Vec3d(0, 0, 1));
  CHECK(scene.camera.eye.z < 1.0);
}

TEST_CASE("OBJ: the mirror material traces reflection rays, illum 2 does not", "[obj][cli]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "quad.obj", kQuadObj);
  write_file(dir.path() / "quad.mtl", kQuadMtl);
  write_file(dir.path() / "matte.mtl", std::string(kQuadMtl).replace(std::string(kQuadMtl).find("illum 3"), 7, "illum 2"));
  write_file(dir.path() / "matte.obj", std::string(kQuadObj).replace(std::string(kQuadObj).find("quad.mtl"), 8, "matte.mtl"));
  for (const char* name : {"quad", "matte"}) {
    const rt_test::RtRun run = run_rt_in(dir, std::string("render --quiet --width 16 --height 12 --stats ") + name +
                                                  ".json -o " + name + ".png " + name + ".obj");
    INFO("stderr: " << run.err);
    REQUIRE(run.status == 0);
  }
  const auto reflections = [&](const char* name) {
    return nlohmann::json::parse(read_file(dir.path() / name)).at("rays").at("reflection").get<std::uint64_t>();
  };
  CHECK(reflections("quad.json") > 0);
  CHECK(reflections("matte.json") == 0);
}

TEST_CASE("rt flags: --eye/--target, --point-light, --background, --fovy", "[cli][obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "pyramid.obj", kPyramidObj);
  const std::string base = "render --quiet --width 24 --height 18 pyramid.obj ";

  REQUIRE(run_rt_in(dir, base + "-o framed.exr").status == 0);
  const rt::Image framed = rt::read_image(dir / "framed.exr");
  CHECK(covered_fraction(framed, rt::Color(0.0f)) > 0.05);

  // --eye and --target move the camera.
  const rt_test::RtRun moved_run = run_rt_in(dir, base + "--eye 0 6 0.1 --target 0 0 0 -o moved.exr");
  INFO("stderr: " << moved_run.err);
  REQUIRE(moved_run.status == 0);
  const rt::Image moved = rt::read_image(dir / "moved.exr");
  CHECK(moved.pixels != framed.pixels);
  CHECK(covered_fraction(moved, rt::Color(0.0f)) > 0.05);

  // --point-light replaces the headlight; info lists the lights given.
  const rt_test::RtRun lit_run = run_rt_in(dir, "render --width 24 --height 18 pyramid.obj --point-light 0 5 0 1 0 0 "
                                                "--stats lit.json -o lit.exr");
  INFO("stderr: " << lit_run.err);
  REQUIRE(lit_run.status == 0);
  CHECK_THAT(lit_run.err, !Catch::Contains("headlight"));
  CHECK(nlohmann::json::parse(read_file(dir.path() / "lit.json")).at("lights") == 1);
  const rt::Image lit = rt::read_image(dir / "lit.exr");
  CHECK(lit.pixels != framed.pixels);
  std::size_t not_red = 0;
  for (const rt::Color& c : lit.pixels) not_red += c.g != 0.0f || c.b != 0.0f;  // a red light, a black background
  CHECK(not_red == 0);
  const rt_test::RtRun info =
      run_rt_in(dir, "info pyramid.obj --point-light 0 5 0 1 0 0 --directional-light 1 1 1 .5 .5 .5");
  CHECK(info.status == 0);
  CHECK_THAT(info.out, Catch::Contains("lights      2") && Catch::Contains("point at (0, 5, 0), colour (1, 0, 0)") &&
                           Catch::Contains("directional towards (1, 1, 1)"));

  // --background colours the misses.
  REQUIRE(run_rt_in(dir, base + "--background 0.25 0.5 0.75 -o bg.exr").status == 0);
  CHECK(rt::read_image(dir / "bg.exr").at(0, 0) == rt::Color(0.25f, 0.5f, 0.75f));

  // Camera flags override the camera of a JSON scene too.
  const std::string scene = quoted(std::string(RT_SOURCE_DIR) + "/scenes/default.json");
  const rt_test::RtRun json_info = run_rt_in(dir, "info " + scene + " --fovy 30 --eye 1 2 3");
  CHECK(json_info.status == 0);
  CHECK_THAT(json_info.out, Catch::Contains("eye (1, 2, 3)") && Catch::Contains("fovy 30 deg"));
}

TEST_CASE("rt flags: bad values are usage errors (exit 2) and nothing is written", "[cli][obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "pyramid.obj", kPyramidObj);
  struct Case {
    const char* args;
    const char* message;
    bool info_too = false;  // also run `rt info` with it (each run costs ~0.5 s of start-up)
  };
  const std::vector<Case> cases = {
      {"--fovy 0", "--fovy", true},
      {"--fovy 180", "--fovy"},
      {"--fovy nan", "--fovy"},
      {"--eye 1 2", "--eye"},
      {"--eye 0 1e999 0", "--eye"},
      {"--target 0 0 inf", "--target"},
      {"--up 0 0 -1 --eye 0 0 5 --target 0 0 0", "--up: up vector is zero or parallel", true},
      {"--eye 0 0.5 0 --target 0 0.5 0", "--target: target is the same point as eye"},
      {"--eye 0 0.5 0", "--eye: target is the same point as eye"},  // the framed target is the box centre
      {"--point-light 0 0 0 -1 1 1", "--point-light: colour", true},
      {"--point-light 0 0 0 1 1", "--point-light"},
      {"--directional-light 0 0 0 1 1 1", "--directional-light: direction is zero"},
      {"--background 1 1", "--background"},
      {"--background 1 -1 1", "--background: colour"},
  };
  for (const Case& c : cases) {
    DYNAMIC_SECTION(c.args) {
      for (const char* command : {"render pyramid.obj -o x.png ", "info pyramid.obj "}) {
        if (!c.info_too && std::string(command).starts_with("info")) continue;
        const rt_test::RtRun run = run_rt_in(dir, command + std::string(c.args));
        INFO(command << c.args << "\nstderr: " << run.err);
        CHECK(run.status == 2);
        CHECK_THAT(run.err, Catch::Contains(c.message));
      }
      CHECK(dir.entries() == std::vector<std::string>{"pyramid.obj"});
    }
  }
}

TEST_CASE("every OBJ of the shared corpus renders", "[obj][cli]") {
  const fs::path root = fs::path(RT_SHARED_DATA_DIR) / "data" / "models" / "obj";
  std::error_code error;
  if (!fs::is_directory(root, error)) {
    WARN("shared models not found at " << root.string() << " (RT_SHARED_DATA_DIR): skipping the OBJ corpus test");
    return;
  }
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(root))
    if (entry.path().extension() == ".obj") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  REQUIRE(files.size() >= 8);  // bunny, teapot, dragon, 4 Williams Cornell boxes, Embree's Cornell box
  for (const fs::path& file : files) {
    DYNAMIC_SECTION(file.filename().string()) {
      rt_test::TempDir dir;
      const rt_test::RtRun run = run_rt_in(dir, "render --quiet --width 96 --height 72 -o out.exr " + quoted(file.string()));
      INFO("stderr: " << run.err);
      REQUIRE(run.status == 0);
      const rt::Image image = rt::read_image(dir / "out.exr");
      CHECK(image.width == 96);
      CHECK(image.height == 72);
      CHECK(all_finite(image));
      const double covered = covered_fraction(image, rt::Color(0.0f));
      INFO("covered " << covered);
      CHECK(covered > 0.05);
    }
  }
}

TEST_CASE("OBJ scene: map_Kd is sampled at the vt coordinates, v = 1 at the image's top", "[obj]") {
  rt_test::TempDir dir;
  // A 1 x 2 texture: top row red, bottom row green (8-bit sRGB 255 decodes to linear 1).
  rt::Image texture;
  texture.width = 1;
  texture.height = 2;
  texture.pixels = {rt::Color(1, 0, 0), rt::Color(0, 1, 0)};
  rt::write_image(texture, (dir.path() / "two.png").string());
  write_file(dir.path() / "t.mtl", "newmtl t\nKd 1 1 1\nmap_Kd two.png\n");
  write_file(dir.path() / "t.obj",
             "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl t\nf 1/1 2/2 3/3\n");
  rt::LoadReport report;
  const rt::Scene scene = rt::load_scene(dir / "t.obj", {}, &report);
  CHECK(report.warnings.empty());
  REQUIRE(scene.materials.size() == 1);
  CHECK_FALSE(scene.materials[0].diffuse_texture.empty());
  const rt::TriangleMesh& mesh = *scene.nodes[scene.root].models.at(0).mesh;
  REQUIRE(mesh.texcoords.size() == 3);
  CHECK(mesh.texcoords[2] == rt::Vec2f(0, 0));  // vt 0 1: the top of the image
  CHECK(mesh.texcoords[0] == rt::Vec2f(0, 1));
  const rt::TextureSampler sampler(scene);
  REQUIRE(sampler.has_diffuse(0));
  CHECK(sampler.diffuse(0, {0.5f, 0.25f}) == rt::Color(1, 0, 0));
  CHECK(sampler.diffuse(0, {0.5f, 0.75f}) == rt::Color(0, 1, 0));
}
