// Whole OBJ/MTL scenes (load_obj_scene), the default framing and headlight, and the camera, light
// and background flags of the `rt` executable.

#include "catch.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <random>
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

  // A map_Kd that cannot be read is reported and dropped; the camera is made up and reported. The
  // matte material's Ke makes it an area light, so no headlight is added.
  REQUIRE(report.warnings.size() == 1);
  CHECK_THAT(report.warnings[0], Catch::Matchers::ContainsSubstring("material 'mirror': map_Kd") && Catch::Matchers::ContainsSubstring("cannot be read"));
  CHECK(mirror.diffuse_texture.empty());
  CHECK(matte.emits_light);
  CHECK_FALSE(mirror.emits_light);
  CHECK(report.camera_framed);
  CHECK_FALSE(report.default_lights_added);
  CHECK(report.view == rt::Vec3d(0, 0, -1));
  CHECK(scene.lights.empty());
  CHECK(scene.camera.target == rt::Vec3d(0.5, 0.5, 0.0));
  CHECK(scene.camera.eye.z > 0.0);
}

TEST_CASE("OBJ scene: a missing MTL file is a warning and the default material is used", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "quad.obj", kQuadObj);  // quad.mtl is not written
  rt::LoadReport report;
  const rt::Scene scene = rt::load_obj_scene(dir / "quad.obj", &report);
  REQUIRE(report.warnings.size() == 1);
  CHECK_THAT(report.warnings[0], Catch::Matchers::ContainsSubstring("quad.obj") && Catch::Matchers::ContainsSubstring("'quad.mtl' not found"));
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
  CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("warning:") && Catch::Matchers::ContainsSubstring("quad.mtl"));
  CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("headlight"));
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
  const std::vector<Case> cases = {
      {"vertex index beyond the vertices", tri + "f 1 2 3\n# comment\nf 1 2 4\n", "bad.obj:6:", "vertex index 4 out of range"},
      {"index 0", tri + "f 0 1 2\n", "bad.obj:4:", "indices start at 1"},
      {"non-numeric index", tri + "f 1 2 x\n", "bad.obj:4:", "not a number"},
      {"relative index before the first vertex", tri + "f -1 -2 -4\n", "bad.obj:4:", "relative index"},
      {"normal index beyond the normals", tri + "vn 0 0 1\nf 1//1 2//1 3//2\n", "bad.obj:5:", "normal index 2 out of range"},
      {"index error after a polygon", tri + "v 1 1 0\nf 1 2 4 3\nf 1 2\nf 1 2 9\n", "bad.obj:7:", "vertex index 9"},
      {"normal index before the first normal", tri + "vn 0 0 1\nf 1//-1 2//-3 3//-1\n", "bad.obj:5:",
       "normal index out of range: a relative index points before the first normal"},
      // tinyobjloader's own messages, kept word for word.
      {"line with index 0", tri + "l 1 0\nf 1 2 3\n", "bad.obj:4:",
       "Failed parse `l' line(e.g. zero value for vertex index. line 4.)"},
      {"points with a non-number", tri + "p x\nf 1 2 3\n", "bad.obj:4:",
       "Failed parse `p' line(e.g. zero value for vertex index. line 4.)"},
      {"skin weight with a negative joint", tri + "vw 1 -2 0.5\nf 1 2 3\n", "bad.obj:4:",
       "Failed parse `vw' line. joint_id is negative. line 4.)"},
  };
  for (const Case& c : cases) {
    DYNAMIC_SECTION(c.name) {
      rt_test::TempDir dir;
      write_file(dir.path() / "bad.obj", c.content);
      try {
        rt::load_obj_scene(dir / "bad.obj");
        FAIL("no error");
      } catch (const rt::InputError& error) {
        CHECK_THAT(error.what(), Catch::Matchers::ContainsSubstring(c.where) && Catch::Matchers::ContainsSubstring(c.reason));
      }
      const rt_test::RtRun run = run_rt_in(dir, "render bad.obj");
      INFO("stderr: " << run.err);
      CHECK(run.status == 1);
      CHECK(std::count(run.err.begin(), run.err.end(), '\n') == 1);
      CHECK_THAT(run.err, Catch::Matchers::StartsWith("rt: error: ") && Catch::Matchers::ContainsSubstring(c.where));
      CHECK(dir.entries() == std::vector<std::string>{"bad.obj"});  // nothing written
    }
  }
  SECTION("missing file") {
    rt_test::TempDir dir;
    CHECK_THROWS_WITH(rt::load_obj_scene(dir / "none.obj"), Catch::Matchers::ContainsSubstring("none.obj") && Catch::Matchers::ContainsSubstring("no such file"));
    const rt_test::RtRun run = run_rt_in(dir, "render none.obj");
    CHECK(run.status == 1);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("none.obj: no such file"));
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

TEST_CASE("the default lights: a key light from above and behind the eye and a headlight, following the camera",
          "[obj][lights]") {
  rt::Camera camera;
  camera.eye = rt::Vec3d(3, 1, 4);
  camera.target = rt::Vec3d(0, 0.5, 0);
  camera.up = rt::Vec3d(0, 1, 0);
  const std::vector<rt::Light> lights = rt::make_default_lights(camera);
  REQUIRE(lights.size() == 2);
  const rt::Vec3d back = glm::normalize(camera.eye - camera.target);
  const rt::Vec3d right = glm::normalize(glm::cross(camera.up, back));
  const rt::Vec3d up = glm::cross(back, right);
  REQUIRE(lights[0].is_directional());
  const rt::Vec3d to_key = glm::normalize(rt::Vec3d(lights[0].position));
  CHECK(glm::dot(to_key, up) > 0.6);     // well above the eye
  CHECK(glm::dot(to_key, back) > 0.3);   // and behind it: camera-facing surfaces see it
  CHECK(glm::dot(to_key, right) > 0.2);  // a little to the right, so shading is not symmetric
  CHECK(lights[0].color == rt::Color(0.8f));
  CHECK(lights[1].position == rt::Vec4d(camera.eye, 1.0));
  CHECK(lights[1].color == rt::Color(0.4f));
  // A camera-facing surface gets about what a white headlight gave it: 0.8 cos + 0.4.
  CHECK(0.8 * glm::dot(to_key, back) + 0.4 == Approx(0.82).margin(0.03));
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
  CHECK_THAT(lit_run.err, !Catch::Matchers::ContainsSubstring("headlight"));
  CHECK(nlohmann::json::parse(read_file(dir.path() / "lit.json")).at("lights") == 1);
  const rt::Image lit = rt::read_image(dir / "lit.exr");
  CHECK(lit.pixels != framed.pixels);
  std::size_t not_red = 0;
  for (const rt::Color& c : lit.pixels) not_red += c.g != 0.0f || c.b != 0.0f;  // a red light, a black background
  CHECK(not_red == 0);
  const rt_test::RtRun info =
      run_rt_in(dir, "info pyramid.obj --point-light 0 5 0 1 0 0 --directional-light 1 1 1 .5 .5 .5");
  CHECK(info.status == 0);
  CHECK_THAT(info.out, Catch::Matchers::ContainsSubstring("lights      2") && Catch::Matchers::ContainsSubstring("point at (0, 5, 0), colour (1, 0, 0)") &&
                           Catch::Matchers::ContainsSubstring("directional towards (1, 1, 1)"));

  // --background colours the misses.
  REQUIRE(run_rt_in(dir, base + "--background 0.25 0.5 0.75 -o bg.exr").status == 0);
  CHECK(rt::read_image(dir / "bg.exr").at(0, 0) == rt::Color(0.25f, 0.5f, 0.75f));

  // Camera flags override the camera of a JSON scene too.
  const std::string scene = quoted(std::string(RT_SOURCE_DIR) + "/scenes/default.json");
  const rt_test::RtRun json_info = run_rt_in(dir, "info " + scene + " --fovy 30 --eye 1 2 3");
  CHECK(json_info.status == 0);
  CHECK_THAT(json_info.out, Catch::Matchers::ContainsSubstring("eye (1, 2, 3)") && Catch::Matchers::ContainsSubstring("fovy 30 deg"));
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
        CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring(c.message));
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
  CHECK(sampler.diffuse(0, {rt::Vec2f(0.5f, 0.25f)}) == rt::Color(1, 0, 0));
  CHECK(sampler.diffuse(0, {rt::Vec2f(0.5f, 0.75f)}) == rt::Color(0, 1, 0));
}

namespace {

// Two materials for kFeatureObj.
const char* const kFeatureMtl = "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n";

// Most of what the OBJ parser handles, in few lines: groups, objects and usemtl switching (the
// material carries over into the next group), relative and absolute indices of every form, a quad
// and a pentagon, colours after a position, a 1-component vt, comments (also after numbers), tabs,
// statements that are ignored ("g" without a name among them), a face of two vertices (dropped)
// and an unknown material.
const char* const kFeatureObj = R"(# features
mtllib feature.mtl
v 0 0 0
v 1 0 0 0.5 0.5 0.5
v	1	1	0
v 0 1 0 # a comment after the numbers
vt 0 0
vt 1
vt 1 1
vt 0 1
vn 0 0 1
g front
usemtl red
f 1/1/1 2/2/1 3/3/1 4/4/1
usemtl blue
f -4/-4/-1 -2/-2/-1 -1/-1/-1
v 0 0 1
v 1 0 1
v 1 1 1
o back
f -3 -2 -1
usemtl nothere
f 5 6 7
s 1
l 1 2
p 3
f 1 2
bogus statement
g
g last
usemtl red
f 1//1 2//1 6//1 7//1 3//1
f -7/1 -6/2 -5/3
)";

std::vector<std::string> model_material_names(const rt::Scene& scene) {
  std::vector<std::string> names;
  for (const rt::Model& model : scene.nodes[scene.root].models) names.push_back(scene.materials[model.material].name);
  return names;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool same_mesh(const rt::TriangleMesh& a, const rt::TriangleMesh& b) {
  return same_bits(a.positions, b.positions) && same_bits(a.normals, b.normals) &&
         same_bits(a.texcoords, b.texcoords) && same_bits(a.triangles, b.triangles);
}

// The models of two loads: the same meshes bit for bit, the same materials, the same warnings.
void check_same_scene(const rt::Scene& a, const rt::LoadReport& report_a, const rt::Scene& b,
                      const rt::LoadReport& report_b) {
  const auto& models_a = a.nodes[a.root].models;
  const auto& models_b = b.nodes[b.root].models;
  REQUIRE(models_a.size() == models_b.size());
  for (std::size_t m = 0; m < models_a.size(); ++m) {
    INFO("model " << m);
    CHECK(models_a[m].material == models_b[m].material);
    CHECK(same_mesh(*models_a[m].mesh, *models_b[m].mesh));
  }
  CHECK(model_material_names(a) == model_material_names(b));
  CHECK(report_a.warnings == report_b.warnings);
}

// The message of the InputError that loading `path` throws (empty if none).
std::string load_error(const std::string& path, const rt::ObjLoadOptions& options = {}) {
  try {
    rt::load_obj_scene(path, nullptr, options);
  } catch (const rt::InputError& error) {
    return error.what();
  }
  return "";
}

std::string replace_all(std::string text, const std::string& from, const std::string& to) {
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

}  // namespace

TEST_CASE("OBJ parser: what the features file gives", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "feature.mtl", kFeatureMtl);
  write_file(dir.path() / "feature.obj", kFeatureObj);
  rt::LoadReport report;
  const rt::Scene scene = rt::load_obj_scene(dir / "feature.obj", &report);
  // Shapes: "front" (red quad, blue triangle), "back" (a blue triangle, the material still in
  // force, then one of the unknown material: the default), "last" (red pentagon and triangle).
  // Faces of fewer than three vertices, l and p are dropped.
  CHECK(model_material_names(scene) == std::vector<std::string>{"red", "blue", "blue", "(default)", "red"});
  const auto& models = scene.nodes[scene.root].models;
  REQUIRE(models.size() == 5);
  const rt::TriangleMesh& quad = *models[0].mesh;
  CHECK(quad.triangles.size() == 2);
  REQUIRE(quad.texcoords.size() == 4);
  CHECK(quad.texcoords[1] == rt::Vec2f(1, 1));     // "vt 1": v = 0, stored as 1 - v
  CHECK(quad.positions[1] == rt::Vec3f(1, 0, 0));  // the colour after x y z is not a coordinate
  CHECK(quad.normals[0] == rt::Vec3f(0, 0, 1));
  const rt::TriangleMesh& relative = *models[1].mesh;  // f -4/-4/-1 -2/-2/-1 -1/-1/-1
  CHECK(relative.positions == std::vector<rt::Vec3f>{{0, 0, 0}, {1, 1, 0}, {0, 1, 0}});
  CHECK(relative.texcoords == std::vector<rt::Vec2f>{{0, 1}, {1, 0}, {0, 0}});
  const std::vector<rt::Vec3f> back{{0, 0, 1}, {1, 0, 1}, {1, 1, 1}};
  CHECK(models[2].mesh->positions == back);  // f -3 -2 -1 after three more v
  CHECK(models[3].mesh->positions == back);  // f 5 6 7
  const rt::TriangleMesh& last = *models[4].mesh;
  CHECK(last.triangles.size() == 3 + 1);  // the pentagon as a fan, then f -7/1 -6/2 -5/3 (v 1 2 3)
  CHECK(last.texcoords.empty());          // the pentagon has no vt
  CHECK(last.normals.size() == last.positions.size());
  REQUIRE(report.warnings.size() == 1);
  CHECK_THAT(report.warnings[0], Catch::Matchers::ContainsSubstring("1 material(s) not defined") && Catch::Matchers::ContainsSubstring("'nothere'"));
}

TEST_CASE("OBJ parser: chunk boundaries at every line give the same scene as one chunk", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "feature.mtl", kFeatureMtl);
  // CRLF, no final newline, and a byte order mark must not change anything either.
  const std::string lf = kFeatureObj;
  const std::vector<std::pair<std::string, std::string>> variants = {
      {"LF", lf},
      {"CRLF", replace_all(lf, "\n", "\r\n")},
      {"no final newline", lf.substr(0, lf.size() - 1)},
      {"byte order mark", "\xEF\xBB\xBF" + lf},
      {"CRLF, no final newline, byte order mark",
       "\xEF\xBB\xBF" + replace_all(lf.substr(0, lf.size() - 1), "\n", "\r\n")},
  };
  rt::LoadReport reference_report;
  write_file(dir.path() / "feature.obj", lf);
  const rt::Scene reference = rt::load_obj_scene(dir / "feature.obj", &reference_report, {1 << 30});
  REQUIRE(model_count(reference) == 5);
  for (const auto& [name, text] : variants) {
    DYNAMIC_SECTION(name) {
      write_file(dir.path() / "feature.obj", text);
      // chunk_bytes 1 puts a boundary after every line; every other size shifts them around.
      for (std::size_t chunk_bytes = 1; chunk_bytes <= text.size(); ++chunk_bytes) {
        INFO("chunk_bytes " << chunk_bytes);
        rt::LoadReport report;
        const rt::Scene scene = rt::load_obj_scene(dir / "feature.obj", &report, {chunk_bytes});
        check_same_scene(scene, report, reference, reference_report);
      }
    }
  }
}

TEST_CASE("OBJ parser: relative indices reach back across many chunks", "[obj]") {
  // A strip of 50 quads over 51 columns of two vertices and a normal each, every face naming its
  // corners and its column's normal relative to the end of the vertices: with a chunk per line,
  // every face refers to vertices of earlier chunks.
  rt_test::TempDir dir;
  std::string text;
  for (int i = 0; i <= 50; ++i) text += fmt::format("v {0} 0 0\nv {0} 1 0\nvn 0 {0} 1\n", i);
  for (int i = 0; i < 50; ++i) {
    const int back = 100 - 2 * i;  // -back is the bottom vertex of column i + 1
    text += fmt::format("f -{0}//-{4} -{1}//-{4} -{2}//-{4} -{3}//-{4}\n", back + 2, back, back - 1, back + 1, 51 - i);
  }
  write_file(dir.path() / "strip.obj", text);
  const rt::Scene one = rt::load_obj_scene(dir / "strip.obj", nullptr, {1 << 30});
  const rt::Scene many = rt::load_obj_scene(dir / "strip.obj", nullptr, {1});
  REQUIRE(model_count(one) == 1);
  REQUIRE(model_count(many) == 1);
  const rt::TriangleMesh& mesh = *many.nodes[many.root].models[0].mesh;
  CHECK(same_mesh(mesh, *one.nodes[one.root].models[0].mesh));
  REQUIRE(mesh.triangles.size() == 100);
  CHECK(mesh.positions.size() == 200);  // each quad's corners carry its own normal
  for (std::size_t t = 0; t < 100; ++t) {
    const float column = float(t / 2);
    const rt::Vec3f normal(glm::normalize(rt::Vec3d(0.0, column, 1.0)));
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = mesh.triangles[t][k];
      INFO("triangle " << t << " corner " << k);
      CHECK((mesh.positions[v].x == column || mesh.positions[v].x == column + 1));
      CHECK(mesh.normals[v] == normal);
    }
  }
  // A relative index before the first vertex, in a late chunk, names its line.
  write_file(dir.path() / "strip.obj", text + "f -1 -2 -103\n");
  CHECK_THAT(load_error(dir / "strip.obj", {1}),
             Catch::Matchers::ContainsSubstring("strip.obj:204: vertex index out of range: a relative index points before the first "
                             "vertex"));
}

TEST_CASE("OBJ parser: errors in late chunks name their line and the number check comes first", "[obj]") {
  rt_test::TempDir dir;
  std::string head;
  for (int i = 0; i < 300; ++i) head += fmt::format("v {} {} 0\n", i % 17, i % 5);  // lines 1-300
  for (int i = 1; i + 2 <= 300; ++i) head += fmt::format("f {} {} {}\n", i, i + 1, i + 2);  // lines 301-598
  const std::string path = dir / "late.obj";
  struct Case {
    const char* name;
    std::string text;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"index out of range", head + "f 1 2 301\n",
       "late.obj:599: vertex index 301 out of range (300 vertices defined)"},
      {"index 0", head + "f 1 0 2\n", "late.obj:599: bad face: a vertex index is 0"},
      {"not a number", head + "vn 0 1 abc\n", "late.obj:599: 'vn': 'abc' is not a number"},
      {"not finite", head + "vt 0 inf\n", "late.obj:599: 'vt': 'inf' is not finite"},
      {"binary", head + "v 0 0 \x01\n", "late.obj:599: binary data (byte 0x01): not a text file"},
      // The number check read the whole file before tinyobj parsed it: a bad number late wins over
      // a bad face early, and over a face index out of range.
      {"number check first", "v 0 0 0\nf 0 1 2\n" + head + "v nan 0 0\n", "late.obj:601: 'v': 'nan' is not finite"},
      {"bad face before range errors", "f 999 999 999\n" + head + "f 0 1 2\n", "late.obj:600: bad face"},
      // Lines count as the old loader counted them: CRLF is one break; for a parse error tinyobj
      // also counted a lone CR.
      {"CRLF", replace_all(head, "\n", "\r\n") + "f 1 2 301\r\n", "late.obj:599: vertex index 301 out of range"},
      {"lone CR before a bad face", head + "# a\rb\nf 1 0 2\n", "late.obj:601: bad face"},
      {"lone CR before a bad number", head + "# a\rb\nv 1 0 x\n", "late.obj:600: 'v': 'x' is not a number"},
  };
  for (const Case& c : cases) {
    DYNAMIC_SECTION(c.name) {
      write_file(path, c.text);
      for (std::size_t chunk_bytes : {std::size_t(1), std::size_t(100), std::size_t(4096), std::size_t(1) << 30}) {
        INFO("chunk_bytes " << chunk_bytes);
        CHECK_THAT(load_error(path, {chunk_bytes}), Catch::Matchers::ContainsSubstring(c.message));
      }
    }
  }
}

TEST_CASE("OBJ parser: an MTL error comes at its mtllib line, before later bad faces, after earlier ones", "[obj]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "bad.mtl", "newmtl x\nKd 0 nan 0\n");
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  write_file(dir.path() / "mtl_first.obj", tri + "mtllib bad.mtl\nf 1 2 0\n");
  write_file(dir.path() / "face_first.obj", tri + "f 1 2 0\nmtllib bad.mtl\n");
  for (std::size_t chunk_bytes : {std::size_t(1), std::size_t(1) << 30}) {
    INFO("chunk_bytes " << chunk_bytes);
    CHECK_THAT(load_error(dir / "mtl_first.obj", {chunk_bytes}),
               Catch::Matchers::ContainsSubstring("bad.mtl:2: 'Kd': 'nan' is not finite"));
    CHECK_THAT(load_error(dir / "face_first.obj", {chunk_bytes}), Catch::Matchers::ContainsSubstring("face_first.obj:4: bad face"));
  }
}

TEST_CASE("OBJ parser: numbers are rounded once, to float32", "[obj]") {
  // 1 + 2^-24 + 2^-60: rounded to double first it would land on 1 + 2^-24, halfway between two
  // floats, and then round to 1. Read straight into float it is above the halfway point.
  rt_test::TempDir dir;
  write_file(dir.path() / "n.obj", "v 1.000000059604644776257 0.1 -2.5e-3\nv 1e-50 -7.5e+2 +4\nv 0 1 0\nf 1 2 3\n");
  const rt::TriangleMesh mesh = rt::load_obj_mesh(dir / "n.obj");
  REQUIRE(mesh.positions.size() == 3);
  CHECK(mesh.positions[0].x == std::nextafter(1.0f, 2.0f));
  CHECK(mesh.positions[0].y == 0.1f);
  CHECK(mesh.positions[0].z == -2.5e-3f);
  CHECK(mesh.positions[1] == rt::Vec3f(0.0f, -750.0f, 4.0f));  // 1e-50 underflows to 0
  // Beyond float's range a coordinate is infinite, and beyond the world's limit.
  write_file(dir.path() / "n.obj", "v 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n");
  CHECK_THAT(load_error(dir / "n.obj"), Catch::Matchers::ContainsSubstring("vertex 3 has a coordinate inf, beyond +-1e+17"));
}

TEST_CASE("OBJ parser: a face of 300 vertices is a fan of 298 triangles", "[obj]") {
  // tinyobjloader kept a face's vertex count in a byte; the parser here has no such limit.
  rt_test::TempDir dir;
  std::string text;
  for (int i = 0; i < 300; ++i) text += fmt::format("v {} {} 0\n", std::cos(i * 0.02), std::sin(i * 0.02));
  text += "f";
  for (int i = 1; i <= 300; ++i) text += fmt::format(" {}", i);
  text += "\n";
  write_file(dir.path() / "fan.obj", text);
  const rt::TriangleMesh mesh = rt::load_obj_mesh(dir / "fan.obj");
  REQUIRE(mesh.triangles.size() == 298);
  CHECK(mesh.positions.size() == 300);
  for (std::size_t k = 0; k < 298; ++k) CHECK(mesh.triangles[k] == rt::Vec3u(0, k + 1, k + 2));
}

TEST_CASE("OBJ parser: every OBJ of the shared corpus parses the same in chunks as in one", "[obj]") {
  const fs::path root = fs::path(RT_SHARED_DATA_DIR) / "data" / "models" / "obj";
  std::error_code error;
  if (!fs::is_directory(root, error)) {
    WARN("shared models not found at " << root.string() << " (RT_SHARED_DATA_DIR): skipping");
    return;
  }
  std::size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    if (entry.path().extension() != ".obj") continue;
    ++files;
    INFO(entry.path().string());
    rt::LoadReport one_report, chunked_report;
    const rt::Scene one = rt::load_obj_scene(entry.path().string(), &one_report, {std::size_t(1) << 40});
    const rt::Scene chunked = rt::load_obj_scene(entry.path().string(), &chunked_report, {4096});
    check_same_scene(chunked, chunked_report, one, one_report);
  }
  CHECK(files >= 8);
}

namespace {

// compute_vertex_normals as it was before it went parallel: one serial loop.
void serial_vertex_normals(rt::TriangleMesh& mesh) {
  std::vector<rt::Vec3d> sums(mesh.positions.size(), rt::Vec3d(0.0));
  for (const rt::Vec3u& tri : mesh.triangles) {
    const rt::Vec3d p[3] = {rt::Vec3d(mesh.positions[tri[0]]), rt::Vec3d(mesh.positions[tri[1]]),
                            rt::Vec3d(mesh.positions[tri[2]])};
    const rt::Vec3d face = glm::cross(p[1] - p[0], p[2] - p[0]);
    const double length = glm::length(face);
    if (!(length > 0.0)) continue;
    for (int k = 0; k < 3; ++k) {
      const rt::Vec3d e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
      const double l1 = glm::length(e1), l2 = glm::length(e2);
      if (!(l1 > 0.0 && l2 > 0.0)) continue;
      const double angle = std::acos(std::clamp(glm::dot(e1, e2) / (l1 * l2), -1.0, 1.0));
      sums[tri[k]] += angle * (face / length);
    }
  }
  mesh.normals.resize(mesh.positions.size());
  for (std::size_t i = 0; i < sums.size(); ++i) {
    const double length = glm::length(sums[i]);
    mesh.normals[i] = length > 0.0 ? rt::Vec3f(sums[i] / length) : rt::Vec3f(0.0f, 0.0f, 1.0f);
  }
}

}  // namespace

TEST_CASE("compute_vertex_normals gives the serial loop's normals bit for bit", "[obj]") {
  // Random triangles over few vertices, each also present with the opposite winding, later and in
  // shuffled order: a vertex's contributions cancel up to rounding, so its normal is the direction
  // of the rounding residue, and any change in the order of summation shows. Degenerate triangles
  // (repeated corners, coincident positions) too; 80000 triangles make several blocks.
  std::mt19937_64 rng(20261124);
  std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
  std::uniform_int_distribution<std::uint32_t> vertex(0, 999);
  rt::TriangleMesh mesh;
  for (int i = 0; i < 1000; ++i) mesh.positions.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
  mesh.positions[7] = mesh.positions[3];  // coincident positions: zero-length edges
  for (int t = 0; t < 40000; ++t) mesh.triangles.emplace_back(vertex(rng), vertex(rng), vertex(rng));
  mesh.triangles[10] = rt::Vec3u(5, 5, 6);
  mesh.triangles[11] = rt::Vec3u(3, 7, 8);
  std::vector<rt::Vec3u> reversed;
  for (const rt::Vec3u& t : mesh.triangles) reversed.emplace_back(t.x, t.z, t.y);
  std::shuffle(reversed.begin(), reversed.end(), rng);
  mesh.triangles.insert(mesh.triangles.end(), reversed.begin(), reversed.end());
  mesh.positions.emplace_back(0.0f, 0.0f, 0.0f);  // used by no triangle: (0, 0, 1)
  rt::TriangleMesh expected = mesh;
  serial_vertex_normals(expected);
  rt::compute_vertex_normals(mesh);
  REQUIRE(mesh.normals.size() == expected.normals.size());
  CHECK(std::memcmp(mesh.normals.data(), expected.normals.data(), mesh.normals.size() * sizeof(rt::Vec3f)) == 0);
  CHECK(mesh.normals.back() == rt::Vec3f(0, 0, 1));
  // The residues are not all zero (else the check above would show nothing about the order).
  std::size_t residues = 0;
  for (std::size_t i = 0; i + 1 < mesh.normals.size(); ++i) residues += mesh.normals[i] != rt::Vec3f(0, 0, 1);
  CHECK(residues > 100);
}
