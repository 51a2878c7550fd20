// The CSE167x / CS184.1x ".test" loader: the scene graph each command builds, every kind of bad
// input, and the shared course corpus rendered against the official grader images.

#include "catch.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "rt/accel/accel.h"
#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/io/load_test.h"
#include "rt/render/render.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

constexpr const char* kPath = "fixture.test";

rt::Scene parse(const std::string& text) { return rt::parse_test_scene(text, kPath); }

// The what() of the InputError parsing `text` throws, or "" if it throws none.
std::string error_of(const std::string& text, const std::string& path = "bad.test") {
  try {
    rt::parse_test_scene(text, path);
  } catch (const rt::InputError& error) {
    return error.what();
  }
  return "";
}

const char* const kHeader =  // two lines; fixtures below count their lines from 3
    "size 40 30\n"
    "camera 0 0 5 0 0 0 0 1 0 45\n";

bool near(const rt::Mat4d& a, const rt::Mat4d& b, double tolerance = 1e-12) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (std::abs(a[c][r] - b[c][r]) > tolerance) return false;
  return true;
}

bool near(const rt::Vec3d& a, const rt::Vec3d& b, double tolerance = 1e-6) {
  return glm::length(a - b) <= tolerance;
}

rt::Vec3d apply(const rt::Mat4d& m, const rt::Vec3d& p) { return rt::Vec3d(m * rt::Vec4d(p, 1.0)); }

// The nodes holding geometry, in declaration order (children of the root).
std::vector<const rt::Node*> geometry_nodes(const rt::Scene& scene) {
  std::vector<const rt::Node*> nodes;
  for (std::uint32_t child : scene.nodes[scene.root].children) nodes.push_back(&scene.nodes[child]);
  return nodes;
}

}  // namespace

TEST_CASE("test scenes: defaults of the course format", "[io][cse167x]") {
  const rt::Scene scene = parse(std::string(kHeader) +
                                "point 1 2 3 1 1 1\n"
                                "directional 0 0 1 .5 .5 .5\n"
                                "maxverts 3\n"
                                "vertex 0 0 0\n"
                                "vertex 1 0 0\n"
                                "vertex 0 1 0\n"
                                "tri 0 1 2\n");
  CHECK(scene.source == kPath);
  CHECK(scene.settings.width == 40);
  CHECK(scene.settings.height == 30);
  CHECK(scene.settings.max_depth == 5);              // maxdepth default 5
  CHECK(scene.settings.background == rt::Color(0.0f));  // black
  CHECK(scene.settings.output.empty());              // no output line: "<scene stem>.png"
  CHECK(scene.camera.eye == rt::Vec3d(0, 0, 5));
  CHECK(scene.camera.target == rt::Vec3d(0, 0, 0));
  CHECK(scene.camera.up == rt::Vec3d(0, 1, 0));
  CHECK(scene.camera.fovy_degrees == 45.0);

  REQUIRE(scene.lights.size() == 2);
  CHECK(scene.lights[0].position == rt::Vec4d(1, 2, 3, 1));
  CHECK(scene.lights[0].attenuation == rt::Vec3d(1, 0, 0));  // attenuation default 1 0 0
  CHECK(scene.lights[1].is_directional());
  CHECK(scene.lights[1].position == rt::Vec4d(0, 0, 1, 0));  // direction towards the light
  CHECK(scene.lights[1].color == rt::Color(0.5f));

  REQUIRE(scene.materials.size() == 1);
  const rt::Material& m = scene.materials[0];
  CHECK(m.ambient == rt::Color(0.0f));    // never the shader's per-light ambient
  CHECK(m.emission == rt::Color(0.2f));   // ambient default .2 .2 .2, added once
  CHECK(m.diffuse == rt::Color(0.0f));
  CHECK(m.specular == rt::Color(0.0f));
  CHECK(m.shininess == 0.0f);

  const auto nodes = geometry_nodes(scene);
  REQUIRE(nodes.size() == 1);
  CHECK(near(nodes[0]->parent_from_node, rt::Mat4d(1.0)));
  REQUIRE(nodes[0]->models.size() == 1);
  const rt::TriangleMesh& mesh = *nodes[0]->models[0].mesh;
  CHECK(mesh.positions == std::vector<rt::Vec3f>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  CHECK(mesh.normals == std::vector<rt::Vec3f>(3, rt::Vec3f(0, 0, 1)));  // (v2-v1) x (v3-v1)
  CHECK(mesh.triangles == std::vector<rt::Vec3u>{{0, 1, 2}});
}

TEST_CASE("test scenes: transforms right-multiply and are captured when a tri is declared", "[io][cse167x]") {
  const rt::Scene scene = parse(std::string(kHeader) +
                                "maxverts 3\n"
                                "translate 1 2 3\n"   // before the vertices: vertices stay untransformed
                                "vertex 0 0 0\n"
                                "vertex 1 0 0\n"
                                "vertex 0 1 0\n"
                                "rotate 0 0 1 90\n"
                                "scale 2 3 4\n"
                                "tri 0 1 2\n"         // node 0: T R S
                                "pushTransform\n"
                                "translate 5 0 0\n"
                                "tri 0 1 2\n"         // node 1: T R S T5
                                "popTransform\n"
                                "tri 0 1 2\n"         // node 2: T R S again
                                "translate 0 0 1\n");  // after the last tri: changes nothing
  const auto nodes = geometry_nodes(scene);
  REQUIRE(nodes.size() == 3);
  // The last command applies first to the object (OpenGL): scale, then rotate, then translate.
  CHECK(near(apply(nodes[0]->parent_from_node, {1, 0, 0}), {1, 4, 3}));   // (2,0,0) -> (0,2,0) -> (1,4,3)
  CHECK(near(apply(nodes[0]->parent_from_node, {0, 1, 0}), {-2, 2, 3}));  // (0,3,0) -> (-3,0,0) -> (-2,2,3)
  CHECK(near(apply(nodes[0]->parent_from_node, {0, 0, 1}), {1, 2, 7}));
  // translate 5 0 0 after T R S acts in the scaled, rotated frame: x5 -> x10 -> y10.
  CHECK(near(apply(nodes[1]->parent_from_node, {0, 0, 0}), {1, 12, 3}));
  CHECK(near(nodes[2]->parent_from_node, nodes[0]->parent_from_node));
  for (const rt::Node* node : nodes) {
    REQUIRE(node->models.size() == 1);
    CHECK(node->models[0].mesh->positions == std::vector<rt::Vec3f>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  }
  // The camera is not transformed either.
  CHECK(scene.camera.eye == rt::Vec3d(0, 0, 5));
}

TEST_CASE("test scenes: consecutive tris with one transform and material share a mesh", "[io][cse167x]") {
  const rt::Scene scene = parse(std::string(kHeader) +
                                "maxverts 4\n"
                                "vertex 0 0 0\n"
                                "vertex 1 0 0\n"
                                "vertex 1 1 0\n"
                                "vertex 0 1 0\n"
                                "tri 0 1 2\n"
                                "point 0 0 9 1 1 1\n"   // not a transform or material change
                                "pushTransform\n"       // the top of the stack is unchanged
                                "tri 0 2 3\n"
                                "diffuse 1 0 0\n"
                                "tri 0 1 2\n"           // new material: new node
                                "popTransform\n"
                                "tri 0 2 3\n"           // same transform and material: same node
                                "scale 1 1 2\n"
                                "tri 0 2 3\n");         // new transform: new node
  const auto nodes = geometry_nodes(scene);
  REQUIRE(nodes.size() == 3);
  REQUIRE(nodes[0]->models.size() == 1);
  REQUIRE(nodes[1]->models.size() == 1);
  REQUIRE(nodes[2]->models.size() == 1);
  const rt::TriangleMesh& first = *nodes[0]->models[0].mesh;
  CHECK(first.triangles == std::vector<rt::Vec3u>{{0, 1, 2}, {3, 4, 5}});
  CHECK(first.positions.size() == 6);  // each tri its own three vertices: no smoothing across tris
  CHECK(nodes[1]->models[0].mesh->triangles.size() == 2);
  CHECK(nodes[2]->models[0].mesh->triangles.size() == 1);
  CHECK(nodes[0]->models[0].material != nodes[1]->models[0].material);
  CHECK(nodes[1]->models[0].material == nodes[2]->models[0].material);
  CHECK(scene.materials.size() == 2);
}

TEST_CASE("test scenes: material state is captured per primitive, ambient and emission become emission",
          "[io][cse167x]") {
  const rt::Scene scene = parse(std::string(kHeader) +
                                "maxverts 3\n"
                                "vertex 0 0 0\n"
                                "vertex 1 0 0\n"
                                "vertex 0 1 0\n"
                                "ambient 0.25 0.5 0\n"
                                "emission 0.5 0 0.125\n"
                                "diffuse 0.1 0.2 0.3\n"
                                "specular 0.4 0.5 0.6\n"
                                "shininess 30\n"
                                "tri 0 1 2\n"        // material A
                                "diffuse 1 1 1\n"
                                "sphere 0 0 0 1\n"   // material B
                                "diffuse 0.1 0.2 0.3\n"
                                "translate 1 0 0\n"
                                "tri 0 1 2\n"        // material A again: deduplicated
                                "ambient 0 0 0\n"
                                "emission 0.75 0.5 0.125\n"
                                "scale 2 2 2\n"
                                "tri 0 1 2\n"        // ambient + emission as before: still A
                                "shininess 31\n"
                                "diffuse 0.1 0.2 0.3\n");  // after the last primitive: unused
  REQUIRE(scene.materials.size() == 2);
  const auto nodes = geometry_nodes(scene);
  REQUIRE(nodes.size() == 4);
  std::vector<std::uint32_t> ids;
  for (const rt::Node* node : nodes) {
    REQUIRE(node->models.size() == 1);
    ids.push_back(node->models[0].material);
  }
  CHECK(ids == std::vector<std::uint32_t>{0, 1, 0, 0});
  const rt::Material& a = scene.materials[0];
  CHECK(a.ambient == rt::Color(0.0f));
  CHECK(a.emission == rt::Color(0.75f, 0.5f, 0.125f));
  CHECK(a.diffuse == rt::Color(0.1f, 0.2f, 0.3f));
  CHECK(a.specular == rt::Color(0.4f, 0.5f, 0.6f));
  CHECK(a.shininess == 30.0f);
  CHECK(scene.materials[1].diffuse == rt::Color(1.0f));
  CHECK(scene.materials[1].emission == rt::Color(0.75f, 0.5f, 0.125f));
}

TEST_CASE("test scenes: attenuation is state for later point lights, lights are not transformed",
          "[io][cse167x]") {
  const rt::Scene scene = parse(std::string(kHeader) +
                                "point 1 0 0 1 1 1\n"
                                "attenuation 1 0.1 0.05\n"
                                "translate 5 5 5\n"
                                "point 0 0.44 -1.5 0.8 0.8 0.8\n"
                                "directional 0 1 -1 0.2 0.2 0.2\n"
                                "attenuation 0 0 2\n"
                                "point 0 0 0 1 1 1\n");
  REQUIRE(scene.lights.size() == 4);
  CHECK(scene.lights[0].attenuation == rt::Vec3d(1, 0, 0));
  CHECK(scene.lights[1].attenuation == rt::Vec3d(1, 0.1, 0.05));
  CHECK(scene.lights[1].position == rt::Vec4d(0, 0.44, -1.5, 1));  // world space despite the translate
  CHECK(scene.lights[1].color == rt::Color(0.8f));
  CHECK(scene.lights[2].is_directional());
  CHECK(scene.lights[2].position == rt::Vec4d(0, 1, -1, 0));
  CHECK(scene.lights[2].attenuation == rt::Vec3d(1, 0, 0));  // directional: never attenuated
  CHECK(scene.lights[3].attenuation == rt::Vec3d(0, 0, 2));
}

TEST_CASE("test scenes: spheres are exact spheres in object space under the current transform", "[io][cse167x]") {
  const std::string text = std::string(kHeader) +
                           "pushTransform\n"
                           "translate 1 0 0\n"
                           "scale 1 2 1\n"
                           "sphere 0 0 1 0.5\n"
                           "popTransform\n"
                           "sphere 0 0 1 0.5\n"
                           "sphere 0 0 0 0.5\n";
  const rt::Scene scene = rt::parse_test_scene(text, kPath);
  const auto nodes = geometry_nodes(scene);
  REQUIRE(nodes.size() == 3);
  CHECK(near(apply(nodes[0]->parent_from_node, {0, 1, 1}), {1, 2, 1}));  // ellipsoid: y doubled
  CHECK(near(nodes[1]->parent_from_node, rt::Mat4d(1.0)));
  for (const rt::Node* node : nodes) {
    REQUIRE(node->models.size() == 1);
    CHECK_FALSE(node->models[0].mesh);
    REQUIRE(node->models[0].sphere);
    CHECK(node->models[0].sphere->radius == 0.5);
  }
  CHECK(nodes[0]->models[0].sphere->center == rt::Vec3d(0, 0, 1));
  CHECK(nodes[2]->models[0].sphere->center == rt::Vec3d(0, 0, 0));

  // Flattened: one analytic ellipsoid with semi-axes (0.5, 1, 0.5) about (1, 0, 1) under the
  // transform, or a tessellation of it on request.
  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.spheres.size() == 3);
  CHECK(flat.triangle_count() == 0);
  const rt::Mat4d& m = flat.spheres[0].world_from_object;
  CHECK(near(apply(m, {0, 0, 0}), {1, 0, 1}));
  CHECK(near(apply(m, {0, 1, 0}), {1, 1, 1}));
  CHECK(near(apply(m, {1, 0, 0}), {1.5, 0, 1}));
  rt::FlattenOptions tessellate;
  tessellate.sphere_tessellation = 12;
  const rt::FlatScene meshes = rt::flatten_scene(scene, tessellate);
  CHECK(meshes.spheres.empty());
  CHECK(meshes.triangle_count() == 3u * 2u * 12u * 5u);
}

TEST_CASE("test scenes: trinormal uses the vertexnormal data", "[io][cse167x]") {
  const rt::Scene scene = parse(std::string(kHeader) +
                                "maxvertnorms 3\n"
                                "vertexnormal 0 0 0 0 0 2\n"
                                "vertexnormal 1 0 0 1 0 1\n"
                                "vertexnormal 0 1 0 0 3 0\n"
                                "trinormal 0 1 2\n");
  const auto nodes = geometry_nodes(scene);
  REQUIRE(nodes.size() == 1);
  const rt::TriangleMesh& mesh = *nodes[0]->models.at(0).mesh;
  CHECK(mesh.positions == std::vector<rt::Vec3f>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  REQUIRE(mesh.normals.size() == 3);
  CHECK(mesh.normals[0] == rt::Vec3f(0, 0, 1));
  CHECK(near(rt::Vec3d(mesh.normals[1]), rt::Vec3d(1, 0, 1) / std::sqrt(2.0)));
  CHECK(mesh.normals[2] == rt::Vec3f(0, 1, 0));
}

TEST_CASE("test scenes: output, maxdepth, CRLF, comments and whitespace", "[io][cse167x]") {
  const std::string lf =
      "# a comment before size\n"
      "\n"
      "size 40 30\n"
      "  camera 0 0 5 0 0 0 0 1 0 45   \n"
      "\t# an indented comment\n"
      "   \t \n"
      "output some/dir/picture.png\n"
      "maxdepth 2\n"
      "maxverts 3\n"
      "vertex -1 -1 0\n"
      "vertex +1 -1 0\n"
      "vertex +1. +.1e1 -.0\n"  // = 1 1 0
      "tri\t0 1   2";  // last line without a newline
  std::string crlf;
  for (char c : lf) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  for (const std::string& text : {lf, crlf}) {
    const rt::Scene scene = parse(text);
    CHECK(scene.settings.output == "some/dir/picture.png");
    CHECK(scene.settings.max_depth == 2);
    CHECK(scene.camera.fovy_degrees == 45.0);
    const auto nodes = geometry_nodes(scene);
    REQUIRE(nodes.size() == 1);
    CHECK(nodes[0]->models.at(0).mesh->positions ==
          std::vector<rt::Vec3f>{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}});
  }
  // An error on a CRLF line names the right line and no stray '\r'.
  const std::string message = error_of("size 40 30\r\ncamera 0 0 5 0 0 0 0 1 0 45\r\nbogus 1\r\n");
  CHECK(message == "bad.test:3: unknown command 'bogus'");
}

TEST_CASE("test scenes: each kind of bad input is one error naming the file and line", "[io][cse167x]") {
  struct Case {
    const char* what;
    std::string text;
    int line;
    const char* reason;  // a part of the message
  };
  const std::string h = kHeader;
  const std::string verts = "maxverts 3\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n";  // lines 3-6
  const std::vector<Case> cases = {
      {"unknown command", h + "sphere 0 0 0 1\nfrobnicate 1 2\n", 4, "unknown command 'frobnicate'"},
      {"wrong case", h + "pushtransform\n", 3, "did you mean 'pushTransform'"},
      {"too few parameters", h + "translate 1 2\n", 3, "'translate' takes 3 parameter(s) (x y z), got 2"},
      {"too many parameters", h + "sphere 0 0 0 1 2\n", 3, "'sphere' takes 4 parameter(s)"},
      {"parameters where none are taken", h + "pushTransform 1\n", 3, "'pushTransform' takes no parameters"},
      {"trailing comment", h + "translate 1 2 3 # right\n", 3, "comment must be on a line of its own"},
      {"non-numeric", h + "translate 1 x 2\n", 3, "parameter 2 of 'translate' is not a number: 'x'"},
      {"number with junk", h + "scale 1 2 3q\n", 3, "parameter 3 of 'scale' is not a number: '3q'"},
      {"infinite", h + "translate 1 inf 2\n", 3, "parameter 2 of 'translate' is not finite"},
      {"nan", h + "diffuse nan 0 0\n", 3, "parameter 1 of 'diffuse' is not finite"},
      {"overflow", h + "point 1e999 0 0 1 1 1\n", 3, "out of range"},
      {"beyond float32", h + "maxverts 1\nvertex 0 1e39 0\n", 4, "beyond the range of float32"},
      {"colour beyond float32", h + "emission 0 0 1e300\n", 3, "beyond the range of float32"},
      {"size not first", "camera 0 0 5 0 0 0 0 1 0 45\nsize 40 30\n", 1, "'size' must be the first command"},
      {"size after a comment is fine, after a command not", "# c\n\nmaxdepth 3\nsize 4 3\n", 3,
       "'size' must be the first command, found 'maxdepth'"},
      {"size missing", "# nothing but a comment\n\n", 2, "no 'size' command"},
      {"empty file", "", 1, "no 'size' command"},
      {"size twice", h + "size 40 30\n", 3, "'size' given twice"},
      {"zero size", "size 0 30\n", 1, "image width 0 is outside 1..65536"},
      {"negative size", "size 40 -30\n", 1, "image height -30 is outside 1..65536"},
      {"fractional size", "size 40.5 30\n", 1, "image width must be an integer"},
      {"negative maxdepth", h + "maxdepth -1\n", 3, "maxdepth -1 is outside 0..1000"},
      {"popTransform on an empty stack", h + "pushTransform\npopTransform\npopTransform\n", 5,
       "'popTransform' without a matching 'pushTransform'"},
      {"tri before maxverts", h + "tri 0 1 2\n", 3, "'tri' before 'maxverts'"},
      {"vertex before maxverts", h + "vertex 0 0 0\n", 3, "'vertex' before 'maxverts'"},
      {"vertex beyond maxverts", h + verts + "vertex 1 1 1\n", 7, "more vertices than maxverts 3"},
      {"tri index not yet defined", h + "maxverts 5\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\ntri 0 1 3\n", 7,
       "vertex index 3 is out of range: 3 vertices defined so far"},
      {"tri index beyond maxverts", h + verts + "tri 0 1 3\n", 7, "vertex index 3 is beyond maxverts 3"},
      {"negative tri index", h + verts + "tri 0 -1 2\n", 7, "vertex index '-1' is not a non-negative integer"},
      {"fractional tri index", h + verts + "tri 0 1.5 2\n", 7, "vertex index '1.5' is not a non-negative integer"},
      {"absurd maxverts", h + "maxverts 1e9\n", 3, "'maxverts' 1e9 exceeds the limit of 100000000"},
      {"absurd maxvertnorms", h + "maxvertnorms 200000000\n", 3, "'maxvertnorms' 200000000 exceeds the limit of 100000000"},
      {"maxverts twice", h + "maxverts 3\nmaxverts 4\n", 4, "'maxverts' given twice"},
      {"trinormal before maxvertnorms", h + verts + "trinormal 0 1 2\n", 7, "'trinormal' before 'maxvertnorms'"},
      {"vertexnormal beyond maxvertnorms", h + "maxvertnorms 1\nvertexnormal 0 0 0 0 0 1\nvertexnormal 0 0 0 0 0 1\n",
       5, "more vertex normals than maxvertnorms 1"},
      {"zero vertex normal", h + "maxvertnorms 1\nvertexnormal 0 0 0 0 0 0\n", 4, "the normal is zero"},
      {"camera up parallel to the view", "size 4 3\ncamera 0 0 5 0 0 0 0 0 1 45\n", 2,
       "up vector is zero or parallel to the view direction"},
      {"camera fovy 180", "size 4 3\ncamera 0 0 5 0 0 0 0 1 0 180\n", 2, "fovy 180 is outside (0, 180)"},
      {"camera fovy 0", "size 4 3\ncamera 0 0 5 0 0 0 0 1 0 0\n", 2, "fovy 0 is outside (0, 180)"},
      {"camera eye at target", "size 4 3\ncamera 1 1 1 1 1 1 0 1 0 45\n", 2, "target is the same point as eye"},
      {"no camera", "size 4 3\nmaxverts 3\n\n", 3, "no 'camera' command"},
      {"negative colour", h + "specular 0.5 -0.1 0\n", 3, "colour components of 'specular' must be >= 0"},
      {"negative light colour", h + "point 0 0 0 1 -1 1\n", 3, "colour components of 'point' must be >= 0"},
      {"negative shininess", h + "shininess -2\n", 3, "shininess must be >= 0"},
      {"zero scale", h + "scale 1 0 1\n", 3, "scale factors must be non-zero"},
      {"zero rotation axis", h + "rotate 0 0 0 30\n", 3, "rotation axis is zero"},
      {"zero sphere radius", h + "sphere 0 0 0 0\n", 3, "sphere radius must be > 0"},
      {"zero attenuation", h + "attenuation 0 0 0\n", 3, "attenuation coefficients must be >= 0 and not all zero"},
      {"zero light direction", h + "directional 0 0 0 1 1 1\n", 3, "directional light has a zero direction"},
  };
  for (const Case& c : cases) {
    INFO(c.what << ":\n" << c.text);
    const std::string message = error_of(c.text);
    CHECK_THAT(message, Catch::Matchers::StartsWith(fmt::format("bad.test:{}: ", c.line)));
    CHECK_THAT(message, Catch::Matchers::ContainsSubstring(c.reason));
    CHECK(message.find('\n') == std::string::npos);  // one line
  }
}

TEST_CASE("test scenes: load_scene dispatches .test files, any case of the extension", "[io][cse167x]") {
  rt_test::TempDir dir;
  const std::string text = std::string(kHeader) + "output out.png\nsphere 0 0 0 1\n";
  for (const char* name : {"scene.test", "SCENE.TEST", "Scene.Test"}) {
    rt_test::write_file(dir / name, text);
    const rt::Scene scene = rt::load_scene(dir / name);
    CHECK(scene.source == dir / name);
    CHECK(scene.settings.output == "out.png");
    CHECK(scene.nodes.size() == 2);
  }
  rt_test::write_file(dir / "broken.test", std::string(kHeader) + "tri 0 1 2\n");
  CHECK_THROWS_WITH(rt::load_scene(dir / "broken.test"),
                    Catch::Matchers::StartsWith(dir / "broken.test:3: ") && Catch::Matchers::ContainsSubstring("'tri' before 'maxverts'"));
  CHECK_THROWS_WITH(rt::load_scene(dir / "missing.test"), Catch::Matchers::ContainsSubstring("no such file"));
  CHECK_THROWS_WITH(rt::load_test_scene(dir.path().string()), Catch::Matchers::ContainsSubstring("not a regular file"));
}

TEST_CASE("test scenes: ambient is added once per object, whatever the lights and shadows", "[io][cse167x]") {
  // A quad filling the view, lit by two lights, diffuse and specular 0. Were the course's ambient
  // the shader's per-light Material::ambient, it would count twice here; it must count once.
  const rt::Scene scene = parse(
      "size 8 6\n"
      "camera 0 0 2 0 0 0 0 1 0 45\n"
      "point 0 0 1 1 1 1\n"
      "directional 0 0 1 1 1 1\n"
      "ambient 0.3 0.2 0.1\n"
      "emission 0.1 0.1 0.1\n"
      "maxverts 4\n"
      "vertex -10 -10 0\n"
      "vertex 10 -10 0\n"
      "vertex 10 10 0\n"
      "vertex -10 10 0\n"
      "tri 0 1 2\n"
      "tri 0 2 3\n");
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
  const rt::RenderResult result = rt::render_image(scene, flat, *accel, {});
  const std::vector<std::uint8_t> bytes = rt::to_rgb8(result.image);
  REQUIRE(bytes.size() == 8u * 6u * 3u);
  for (std::size_t p = 0; p < bytes.size(); p += 3) {
    // floor(255 * (ambient + emission)): 0.4 -> 102, 0.3 -> 76, 0.2 -> 51.
    CHECK(int(bytes[p]) == 102);
    CHECK(int(bytes[p + 1]) == 76);
    CHECK(int(bytes[p + 2]) == 51);
  }
}

// ---------------------------------------------------------------------------------------------
// The shared course corpus (RT_SHARED_DATA_DIR/data/cse167x): skipped when absent.

namespace {

std::optional<fs::path> corpus_dir() {
  const fs::path dir = fs::path(RT_SHARED_DATA_DIR) / "data" / "cse167x";
  std::error_code error;
  if (fs::is_directory(dir / "scenes", error)) return dir;
  WARN("shared corpus not found at " << dir.string() << " (RT_SHARED_DATA_DIR): skipping the CSE167x corpus tests");
  return std::nullopt;
}

struct Rendered {
  rt::Scene scene;
  rt::Image image;
  std::size_t triangles = 0, spheres = 0;
  double seconds = 0.0;
};

// sphere_tessellation: 0 renders exact spheres, N >= 3 UV spheres of N slices (FlattenOptions).
Rendered render_file(const fs::path& file, int sphere_tessellation, int width = 0, int height = 0) {
  const auto start = std::chrono::steady_clock::now();
  Rendered r{rt::load_test_scene(file.string()), {}, 0, 0, 0.0};
  if (width > 0) {
    r.scene.settings.width = width;
    r.scene.settings.height = height;
  }
  rt::FlattenOptions options;
  options.sphere_tessellation = sphere_tessellation;
  const rt::FlatScene flat = rt::flatten_scene(r.scene, options);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
  r.image = rt::render_image(r.scene, flat, *accel, {}).image;
  r.triangles = flat.triangle_count();
  r.spheres = flat.spheres.size();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

// What the primary ray of each pixel hits in our render: 0 nothing, 1 a tri, 2 a sphere.
// Renders a copy of the scene without lights or reflections, sphere models emitting red and
// triangle models green.
std::vector<int> primary_hit_classes(const rt::Scene& original) {
  rt::Scene scene = original;
  scene.lights.clear();
  scene.settings.max_depth = 0;
  scene.materials.assign(2, rt::Material{});
  scene.materials[0].emission = rt::Color(0, 1, 0);
  scene.materials[1].emission = rt::Color(1, 0, 0);
  for (rt::Node& node : scene.nodes)
    for (rt::Model& model : node.models) model.material = node.name.starts_with("sphere") ? 1 : 0;
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
  const rt::Image image = rt::render_image(scene, flat, *accel, {}).image;
  std::vector<int> classes;
  for (const rt::Color& c : image.pixels) classes.push_back(c.r > 0.5f ? 2 : c.g > 0.5f ? 1 : 0);
  return classes;
}

struct Match {
  std::size_t compared = 0, within_one = 0, identical = 0;
  double fraction() const { return compared ? double(within_one) / double(compared) : 0.0; }
  std::string describe() const {
    return fmt::format("{}/{} = {:.3f}% within 1 ({:.3f}% identical)", within_one, compared, 100.0 * fraction(),
                       compared ? 100.0 * double(identical) / double(compared) : 0.0);
  }
};

std::uint8_t to_byte(float c) { return static_cast<std::uint8_t>(std::lround(255.0 * double(c))); }

// Spheres of the reference comparison: exact, or tessellated with N slices from the environment
// variable RT_CSE167X_SPHERES=N (e.g. 128), to compare the two.
int reference_sphere_tessellation() {
  if (const char* value = std::getenv("RT_CSE167X_SPHERES")) {
    int slices = 0;
    if (std::sscanf(value, "%d", &slices) == 1 && slices >= 3) return slices;
    WARN("ignoring RT_CSE167X_SPHERES='" << value << "' (expected a slice count >= 3)");
  }
  return 0;
}

}  // namespace

TEST_CASE("test scenes: every corpus file loads and renders", "[io][cse167x][corpus]") {
  const auto dir = corpus_dir();
  if (!dir) return;
  const std::vector<std::string> files = {
      "scenes/scene4-ambient.test", "scenes/scene4-diffuse.test", "scenes/scene4-emission.test",
      "scenes/scene4-specular.test", "scenes/scene5.test", "scenes/scene6.test", "scenes/scene7.test",
      "scenes/testscenes/scene1.test", "scenes/testscenes/scene2.test", "scenes/testscenes/scene3.test"};
  // Reduced size: this checks loading and rendering, not pixels (see below).
  for (const std::string& name : files) {
    INFO(name);
    const fs::path file = *dir / name;
    REQUIRE(fs::exists(file));
    const Rendered r = render_file(file, 0, 160, 120);
    std::cout << fmt::format("{}: {} triangles, {} spheres, {} lights, {} materials, {:.2f} s (160x120)\n", name,
                             r.triangles, r.spheres, r.scene.lights.size(), r.scene.materials.size(), r.seconds);
    CHECK(r.scene.settings.width == 160);
    CHECK(r.triangles + r.spheres > 0);
    // Something is visible: at least 2% of the pixels are not black.
    const auto lit = std::count_if(r.image.pixels.begin(), r.image.pixels.end(),
                                   [](const rt::Color& c) { return c.r + c.g + c.b > 0.0f; });
    CHECK(lit > static_cast<long>(r.image.pixels.size() / 50));
  }
  // A few facts of the files (README "Scene descriptions").
  const rt::Scene scene7 = rt::load_test_scene((*dir / "scenes/scene7.test").string());
  CHECK(scene7.settings.output == "scene7.png");
  CHECK(scene7.materials.size() == 1);          // 100,000 tris, one material
  CHECK(scene7.nodes.size() == 2);              // root + one mesh under translate 0 -5 0
  const rt::Scene scene5 = rt::load_test_scene((*dir / "scenes/scene5.test").string());
  CHECK(scene5.nodes.size() == 1001);           // root + 1000 spheres
  CHECK(scene5.materials.size() == 1);
  CHECK(scene5.lights.size() == 2);
  const rt::Scene scene1 = rt::load_test_scene((*dir / "scenes/testscenes/scene1.test").string());
  CHECK(scene1.settings.output.empty());
  CHECK(scene1.camera.eye == rt::Vec3d(-4, -4, 4));  // the only camera line not commented out
}

TEST_CASE("test scenes: corpus renders match the official grader images", "[io][cse167x][corpus]") {
  const auto dir = corpus_dir();
  if (!dir) return;
  const rt::Image mask = rt::read_image((*dir / "reference/watermark-mask.png").string());
  const int tessellation = reference_sphere_tessellation();
  const std::string spheres = tessellation ? fmt::format("tessellated, {} slices", tessellation) : "exact";
  for (const char* name : {"scene4-ambient", "scene4-diffuse", "scene4-emission", "scene4-specular", "scene5"}) {
    INFO(name);
    const fs::path reference_file = *dir / "reference" / (std::string(name) + ".png");
    REQUIRE(fs::exists(reference_file));
    const rt::Image reference = rt::read_image(reference_file.string());
    const Rendered r = render_file(*dir / "scenes" / (std::string(name) + ".test"), tessellation);
    REQUIRE(r.image.width == reference.width);
    REQUIRE(r.image.height == reference.height);
    REQUIRE(mask.width == reference.width);
    REQUIRE(mask.height == reference.height);
    const std::vector<std::uint8_t> ours = rt::to_rgb8(r.image);
    const std::vector<int> classes = primary_hit_classes(r.scene);

    Match all, by_class[3];
    for (std::size_t p = 0; p < reference.pixels.size(); ++p) {
      if (to_byte(mask.pixels[p].r) != 0) continue;  // watermarked row
      int worst = 0;
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, std::abs(int(ours[3 * p + c]) - int(to_byte(reference.pixels[p][c]))));
      for (Match* m : {&all, &by_class[classes[p]]}) {
        ++m->compared;
        m->within_one += worst <= 1;
        m->identical += worst == 0;
      }
    }
    std::cout << fmt::format("{} vs official image (spheres {}, {} triangles, {} spheres, {:.1f} s): {}\n", name,
                             spheres, r.triangles, r.spheres, r.seconds, all.describe())
              << fmt::format("    primary ray hits a tri: {}\n", by_class[1].describe())
              << fmt::format("    primary ray hits a sphere: {}\n", by_class[2].describe())
              << fmt::format("    primary ray misses: {}\n", by_class[0].describe());
    CHECK(all.compared == 259200u);
    if (tessellation == 0) CHECK(all.fraction() >= 0.995);
  }
}
