// The glTF 2.0 loader: hand-built fixtures written to a scratch directory, the `rt` command line
// on them, and the shared glTF sample models (RT_SHARED_DATA_DIR/data/models/gltf) when present.

#include "catch.h"

#include <sys/wait.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <optional>
#include <set>
#include <tuple>

#include <nlohmann/json.hpp>

#include "rt/accel/accel.h"
#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_gltf.h"
#include "rt/scene/framing.h"
#include "rt/io/load_scene.h"
#include "rt/render/surface_test.h"
#include "rt/render/render.h"
#include "test_util.h"

namespace fs = std::filesystem;
using json = nlohmann::json;
using Catch::Matchers::ContainsSubstring;

namespace {

constexpr int kFloat = 5126, kUnsignedShort = 5123;

// Builds a glTF document whose binary data goes to one external .bin (or a data: URI).
class GltfBuilder {
 public:
  GltfBuilder() {
    doc["asset"] = {{"version", "2.0"}};
    doc["scene"] = 0;
    doc["scenes"] = json::array({json{{"nodes", json::array()}}});
  }

  // Appends `bytes` (padded to 4) as a new bufferView; returns its index.
  int view(const std::string& bytes) {
    const std::size_t offset = bin.size();
    bin += bytes;
    bin.resize((bin.size() + 3) / 4 * 4, '\0');
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes.size()}});
    return static_cast<int>(doc["bufferViews"].size()) - 1;
  }
  int accessor(json accessor) {
    doc["accessors"].push_back(std::move(accessor));
    return static_cast<int>(doc["accessors"].size()) - 1;
  }
  int vec3s(const std::vector<rt::Vec3f>& values) {
    return accessor({{"bufferView", view(bytes_of(values))}, {"componentType", kFloat}, {"count", values.size()}, {"type", "VEC3"}});
  }
  int indices(const std::vector<std::uint16_t>& values) {
    return accessor(
        {{"bufferView", view(bytes_of(values))}, {"componentType", kUnsignedShort}, {"count", values.size()}, {"type", "SCALAR"}});
  }
  // A mesh with one primitive; returns the mesh index.
  int mesh(json primitive) {
    doc["meshes"].push_back({{"primitives", json::array({std::move(primitive)})}});
    return static_cast<int>(doc["meshes"].size()) - 1;
  }
  // A node, listed among the scene's roots when `root`; returns its index.
  int node(json node, bool root = true) {
    doc["nodes"].push_back(std::move(node));
    const int index = static_cast<int>(doc["nodes"].size()) - 1;
    if (root) doc["scenes"][0]["nodes"].push_back(index);
    return index;
  }
  // The counter-clockwise triangle (0,0,0), (1,0,0), (0,1,0) as node 0 of the scene.
  void triangle(bool indexed) {
    json primitive = {{"attributes", {{"POSITION", vec3s({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}})}}}};
    if (indexed) primitive["indices"] = indices({0, 1, 2});
    node({{"mesh", mesh(primitive)}});
  }

  // Writes NAME.gltf and NAME.bin into `dir`; returns the .gltf path.
  std::string write(const rt_test::TempDir& dir, const std::string& name = "scene") {
    json out = doc;
    if (!bin.empty()) out["buffers"] = json::array({json{{"uri", name + ".bin"}, {"byteLength", bin.size()}}});
    rt_test::write_file(dir / (name + ".bin"), bin);
    rt_test::write_file(dir / (name + ".gltf"), out.dump(1));
    return dir / (name + ".gltf");
  }

  template <class T>
  static std::string bytes_of(const std::vector<T>& values) {
    return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  }

  json doc;
  std::string bin;
};

rt::Scene load(const std::string& path, const rt::GltfOptions& options = {}) { return rt::load_gltf_scene(path, options); }

// The InputError message of loading `path` ("" if it loads).
std::string load_error(const std::string& path, const rt::GltfOptions& options = {}) {
  try {
    load(path, options);
  } catch (const rt::InputError& error) {
    return error.what();
  }
  return "";
}

// What loading throws when a --camera or --gltf-scene value does not fit the file: a usage error.
std::string flag_error(const std::string& path, const rt::GltfOptions& options) {
  try {
    load(path, options);
  } catch (const rt::UsageError& error) {
    return error.what();
  }
  return "";
}

bool has_notice(const rt::Scene& scene, const std::string& text) {
  for (const std::string& notice : scene.notices)
    if (notice.find(text) != std::string::npos) return true;
  return false;
}

bool near(const rt::Vec3d& a, const rt::Vec3d& b, double tolerance = 1e-5) { return glm::length(a - b) <= tolerance; }

rt::Image render(const rt::Scene& scene, int width, int height) {
  rt::Scene sized = scene;
  sized.settings.width = width;
  sized.settings.height = height;
  const rt::FlatScene flat = rt::flatten_scene(sized);
  const std::unique_ptr<rt::Accel> accel = rt::build_accel(rt::AccelKind::embree, flat);
  rt::RenderOptions options;
  options.threads = 2;
  return rt::render_image(sized, flat, *accel, options).image;
}

}  // namespace

TEST_CASE("gltf: an indexed and a non-indexed triangle load alike, flat-shaded without normals", "[gltf]") {
  for (const bool indexed : {true, false}) {
    rt_test::TempDir dir;
    GltfBuilder builder;
    builder.triangle(indexed);
    const rt::Scene scene = load(builder.write(dir));
    const rt::FlatScene flat = rt::flatten_scene(scene);
    REQUIRE(flat.triangle_count() == 1);
    CHECK(flat.positions[flat.triangles[0].y] == rt::Vec3f(1, 0, 0));
    CHECK(flat.positions[flat.triangles[0].z] == rt::Vec3f(0, 1, 0));
    CHECK(flat.normals[0] == rt::Vec3f(0, 0, 1));
    CHECK(has_notice(scene, "no lights"));
    CHECK(has_notice(scene, "no camera"));
    CHECK(scene.lights.size() == rt::make_default_lights(scene.camera).size());  // the default rig
  }
}

TEST_CASE("gltf: TRS and matrix nodes compose parent-first into the same world positions", "[gltf]") {
  // Parent: translate (1, 2, 3), rotate 90 degrees about +y; child: scale 2 along x.
  // The triangle's (1, 0, 0) -> scale (2, 0, 0) -> rotate (0, 0, -2) -> translate (1, 2, 1).
  const double h = std::sqrt(0.5);
  const json trs_parent = {{"translation", {1, 2, 3}}, {"rotation", {0, h, 0, h}}};
  const json matrix_parent = {{"matrix", {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 2, 3, 1}}};  // column-major
  for (const json& parent : {trs_parent, matrix_parent}) {
    rt_test::TempDir dir;
    GltfBuilder builder;
    const int mesh = builder.mesh({{"attributes", {{"POSITION", builder.vec3s({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}})}}}});
    const int child = builder.node({{"mesh", mesh}, {"scale", {2, 1, 1}}}, false);
    json p = parent;
    p["children"] = {child};
    builder.node(p);
    const rt::FlatScene flat = rt::flatten_scene(load(builder.write(dir)));
    REQUIRE(flat.triangle_count() == 1);
    CHECK(near(rt::Vec3d(flat.positions[flat.triangles[0].x]), {1, 2, 3}));
    CHECK(near(rt::Vec3d(flat.positions[flat.triangles[0].y]), {1, 2, 1}));
    CHECK(near(rt::Vec3d(flat.positions[flat.triangles[0].z]), {1, 3, 3}));
  }
}

TEST_CASE("gltf: sparse accessors substitute values, with and without a base bufferView", "[gltf]") {
  for (const bool dense_base : {true, false}) {
    rt_test::TempDir dir;
    GltfBuilder builder;
    json positions = {{"componentType", kFloat}, {"count", 3}, {"type", "VEC3"}};
    if (dense_base)
      positions["bufferView"] = builder.view(GltfBuilder::bytes_of(std::vector<rt::Vec3f>{{0, 0, 0}, {1, 0, 0}, {0, 0, 0}}));
    positions["sparse"] = {
        {"count", dense_base ? 1 : 2},
        {"indices",
         {{"bufferView", builder.view(GltfBuilder::bytes_of(dense_base ? std::vector<std::uint16_t>{2}
                                                                       : std::vector<std::uint16_t>{1, 2}))},
          {"componentType", kUnsignedShort}}},
        {"values", {{"bufferView", builder.view(GltfBuilder::bytes_of(dense_base ? std::vector<rt::Vec3f>{{0, 2, 0}}
                                                                                 : std::vector<rt::Vec3f>{{1, 0, 0}, {0, 2, 0}}))}}}};
    const int accessor = builder.accessor(positions);
    builder.node({{"mesh", builder.mesh({{"attributes", {{"POSITION", accessor}}}})}});
    const rt::FlatScene flat = rt::flatten_scene(load(builder.write(dir)));
    REQUIRE(flat.triangle_count() == 1);
    CHECK(flat.positions[flat.triangles[0].y] == rt::Vec3f(1, 0, 0));
    CHECK(flat.positions[flat.triangles[0].z] == rt::Vec3f(0, 2, 0));
  }
}

TEST_CASE("gltf: KHR_lights_punctual point, spot and directional lights land in world space", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.triangle(true);
  builder.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  builder.doc["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "point"}, {"intensity", 10.0}, {"color", {1, 0.5, 0}}},
      {{"type", "spot"}, {"intensity", 3.0}, {"spot", {{"innerConeAngle", 0.2}, {"outerConeAngle", 0.4}}}},
      {{"type", "directional"}, {"intensity", 2.0}}};
  const double h = std::sqrt(0.5);
  const auto light_node = [](int light) { return json{{"extensions", {{"KHR_lights_punctual", {{"light", light}}}}}}; };
  json point = light_node(0), spot = light_node(1), sun = light_node(2);
  point["translation"] = {1, 2, 3};
  spot["translation"] = {0, 5, 0};
  spot["rotation"] = {-h, 0, 0, h};  // -90 degrees about x: -z turns into -y (pointing down)
  sun["rotation"] = {-h, 0, 0, h};
  builder.node(point);
  builder.node(spot);
  builder.node(sun);
  const rt::Scene scene = load(builder.write(dir));
  REQUIRE(scene.lights.size() == 3);
  CHECK_FALSE(has_notice(scene, "no lights"));
  const double pi = std::numbers::pi;

  const rt::Light& p = scene.lights[0];
  CHECK(p.position == rt::Vec4d(1, 2, 3, 1));
  CHECK(p.attenuation == rt::Vec3d(0, 0, 1));  // inverse square
  CHECK(near(rt::Vec3d(p.color), rt::Vec3d(10 / pi, 5 / pi, 0)));
  CHECK_FALSE(p.is_spot());

  const rt::Light& s = scene.lights[1];
  REQUIRE(s.is_spot());
  CHECK(near(rt::Vec3d(s.position), {0, 5, 0}));
  CHECK(near(s.spot_direction, {0, -1, 0}));
  CHECK(s.spot_cos_inner == Approx(std::cos(0.2)));
  CHECK(s.spot_cos_outer == Approx(std::cos(0.4)));

  const rt::Light& d = scene.lights[2];
  REQUIRE(d.is_directional());
  CHECK(near(rt::Vec3d(d.position), {0, 1, 0}));  // towards the light: opposite its -y travel
  CHECK(d.color.r == Approx(2 / pi));
}

TEST_CASE("gltf: a spot light lights its cone and nothing outside it", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  // A 20 x 20 floor at y = 0 seen from straight above; a spot 2 above it pointing down, 10 degree cone.
  const int floor = builder.mesh({{"attributes", {{"POSITION", builder.vec3s({{-10, 0, 10}, {10, 0, 10}, {10, 0, -10}, {-10, 0, -10}})}}},
                                  {"indices", builder.indices({0, 1, 2, 0, 2, 3})},
                                  {"material", 0}});
  builder.doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 1}}, {"metallicFactor", 0.0}}}}};
  builder.node({{"mesh", floor}});
  builder.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 1.2}, {"znear", 0.1}}}}};
  const double h = std::sqrt(0.5);
  builder.node({{"camera", 0}, {"translation", {0, 6, 0}}, {"rotation", {-h, 0, 0, h}}});
  builder.doc["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "spot"}, {"intensity", 40.0}, {"spot", {{"innerConeAngle", 0.1}, {"outerConeAngle", 0.17}}}}};
  builder.node({{"translation", {0, 2, 0}}, {"rotation", {-h, 0, 0, h}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  const rt::Image image = render(load(builder.write(dir)), 41, 41);
  CHECK(image.at(20, 20).r > 0.5f);   // under the spot: 40 / (pi 2^2) ~ 3, clamped later
  CHECK(image.at(2, 2).r == 0.0f);    // far outside the cone
  CHECK(image.at(20, 2).r == 0.0f);
}

TEST_CASE("gltf: cameras are chosen by name or index, orthographic ones are refused", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.triangle(true);
  builder.doc["cameras"] = {{{"type", "orthographic"}, {"name", "ortho"}, {"orthographic", {{"xmag", 1}, {"ymag", 1}, {"znear", 0.1}, {"zfar", 10}}}},
                            {{"type", "perspective"}, {"name", "wide"}, {"perspective", {{"yfov", 1.0}, {"aspectRatio", 2.0}, {"znear", 0.1}}}},
                            {{"type", "perspective"}, {"name", "narrow"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}}};
  builder.node({{"camera", 0}, {"translation", {0, 0, 9}}});
  builder.node({{"camera", 1}, {"translation", {0, 0, 5}}, {"name", "wide node"}});
  builder.node({{"camera", 2}, {"translation", {1, 0, 7}}});
  const std::string path = builder.write(dir);

  const rt::Scene first = load(path);  // default: the first perspective one, orthographic skipped with a notice
  CHECK(first.camera.eye == rt::Vec3d(0, 0, 5));
  CHECK(first.camera.fovy_degrees == Approx(180.0 / std::numbers::pi));
  CHECK(first.settings.width == 960);  // aspect ratio 2 at 480 rows
  CHECK(has_notice(first, "orthographic"));
  CHECK(load(path, {std::nullopt, "narrow"}).camera.eye == rt::Vec3d(1, 0, 7));
  CHECK(load(path, {std::nullopt, "2"}).camera.eye == rt::Vec3d(1, 0, 7));
  CHECK(load(path, {std::nullopt, "wide node"}).camera.eye == rt::Vec3d(0, 0, 5));
  CHECK(load(path, {std::nullopt, "narrow"}).camera.target == rt::Vec3d(1, 0, 6));
  CHECK_THAT(flag_error(path, {std::nullopt, "0"}), ContainsSubstring("--camera 0") && ContainsSubstring("not supported"));
  CHECK_THAT(flag_error(path, {std::nullopt, "7"}), ContainsSubstring("--camera 7 is out of range"));
  CHECK_THAT(flag_error(path, {std::nullopt, "tele"}),
             ContainsSubstring("--camera 'tele': no camera or camera node has this name") && ContainsSubstring("1 'wide'"));
}

TEST_CASE("gltf: --gltf-scene picks a scene, the default is the file's 'scene'", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.triangle(true);
  builder.doc["scenes"].push_back({{"nodes", json::array()}});
  builder.doc["scene"] = 1;
  const std::string path = builder.write(dir);
  CHECK(rt::flatten_scene(load(path)).triangle_count() == 0);
  CHECK(rt::flatten_scene(load(path, {0, ""})).triangle_count() == 1);
  CHECK_THAT(flag_error(path, {5, ""}), ContainsSubstring("--gltf-scene 5 is out of range"));
}

TEST_CASE("gltf: points and lines are skipped and counted, strips and fans are triangulated", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  const int zigzag = builder.vec3s({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}});  // strip order
  const int around = builder.vec3s({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}});  // fan order
  builder.doc["meshes"] = {{{"primitives",
                             {{{"attributes", {{"POSITION", zigzag}}}, {"mode", 0}},
                              {{"attributes", {{"POSITION", zigzag}}}, {"mode", 1}},
                              {{"attributes", {{"POSITION", zigzag}}}, {"mode", 5}},
                              {{"attributes", {{"POSITION", around}}}, {"mode", 6}}}}}};
  builder.node({{"mesh", 0}});
  const rt::Scene scene = load(builder.write(dir));
  CHECK(has_notice(scene, "points or lines skipped (not surfaces) (2x)"));
  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.triangle_count() == 4);  // strip 2 + fan 2
  for (const rt::Vec3f& n : flat.normals) CHECK(n == rt::Vec3f(0, 0, 1));  // every triangle counter-clockwise
}

TEST_CASE("gltf: bad files give one line naming the file, the JSON path and the reason", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.triangle(true);
  const std::string path = builder.write(dir, "good");
  REQUIRE(load_error(path).empty());

  SECTION("missing .bin") {
    fs::remove(dir / "good.bin");
    CHECK_THAT(load_error(path), ContainsSubstring(path + ":/buffers/0/uri: buffer file 'good.bin' not found"));
  }
  SECTION("index out of range") {
    GltfBuilder bad;
    bad.node({{"mesh", bad.mesh({{"attributes", {{"POSITION", bad.vec3s({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}})}}},
                                 {"indices", bad.indices({0, 1, 3})}})}});
    const std::string bad_path = bad.write(dir, "bad");
    CHECK_THAT(load_error(bad_path),
               ContainsSubstring(bad_path + ":/meshes/0/primitives/0/indices: index 3") && ContainsSubstring("out of range"));
  }
  SECTION("accessor count beyond its bufferView") {
    builder.doc["accessors"][0]["count"] = 4;
    const std::string bad_path = builder.write(dir, "bad");
    CHECK_THAT(load_error(bad_path), ContainsSubstring(bad_path + ":/accessors/0:") && ContainsSubstring("need 48 bytes"));
  }
  SECTION("mesh index out of range") {
    builder.doc["nodes"][0]["mesh"] = 3;
    const std::string bad_path = builder.write(dir, "bad");
    CHECK_THAT(load_error(bad_path), ContainsSubstring(bad_path + ":/nodes/0/mesh: mesh index 3 is out of range"));
  }
  SECTION("truncated file") {
    const std::string text = rt_test::read_file(path);
    rt_test::write_file(dir / "cut.gltf", text.substr(0, text.size() / 2));
    const std::string message = load_error(dir / "cut.gltf");
    CHECK_THAT(message, ContainsSubstring(dir / "cut.gltf"));
    CHECK(message.find('\n') == std::string::npos);
  }
  SECTION("no such file") { CHECK_THAT(load_error(dir / "nothere.gltf"), ContainsSubstring("no such file")); }
}

TEST_CASE("gltf: KHR_materials_transmission, _ior and _volume make glass, thin without a volume", "[gltf][glass]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.doc["materials"] = json::array();
  const auto add_material = [&](json extensions) {
    builder.doc["materials"].push_back({{"pbrMetallicRoughness", {{"baseColorFactor", {0.9, 0.8, 0.7, 1.0}},
                                                                   {"metallicFactor", 0.0}, {"roughnessFactor", 0.0}}},
                                        {"extensions", std::move(extensions)}});
    json primitive = {{"attributes", {{"POSITION", builder.vec3s({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}})}}},
                      {"material", builder.doc["materials"].size() - 1}};
    builder.node({{"mesh", builder.mesh(primitive)}});
  };
  add_material({{"KHR_materials_transmission", {{"transmissionFactor", 0.75}}}});
  add_material({{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                {"KHR_materials_ior", {{"ior", 1.33}}},
                {"KHR_materials_volume", {{"thicknessFactor", 0.1}, {"attenuationDistance", 2.5},
                                          {"attenuationColor", {0.5, 0.6, 0.7}}}}});
  add_material({{"KHR_materials_ior", {{"ior", 2.0}}}});  // opaque: only the reflectance changes
  const std::string path = builder.write(dir, "glass");
  const rt::Scene scene = load(path);
  const auto material = [&](const std::string& name) -> const rt::Material& { return rt_test::material_named(scene, name); };
  const rt::Material& thin = material("material 0");
  CHECK(thin.is_dielectric());
  CHECK(thin.transmission_mix);
  CHECK(thin.transmission_factor == 0.75f);
  CHECK(thin.transmission == rt::Color(0.9f, 0.8f, 0.7f));  // tinted by the base colour
  CHECK(thin.thin_walled);
  CHECK(thin.ior == 1.5f);
  const rt::Material& volume = material("material 1");
  CHECK_FALSE(volume.thin_walled);
  CHECK(volume.ior == 1.33f);
  CHECK(volume.attenuation_distance == 2.5f);
  CHECK(volume.attenuation_color == rt::Color(0.5f, 0.6f, 0.7f));
  const rt::Material& opaque = material("material 2");
  CHECK_FALSE(opaque.is_dielectric());
  CHECK(opaque.specular.r == Approx(1.0 / 9.0));  // ((2 - 1) / (2 + 1))^2 at roughness 0

  SECTION("out-of-range values are errors naming the JSON path") {
    builder.doc["materials"][0]["extensions"]["KHR_materials_transmission"]["transmissionFactor"] = 1.5;
    const std::string bad = builder.write(dir, "bad");
    CHECK_THAT(load_error(bad), ContainsSubstring(bad + ":/materials/0/extensions/KHR_materials_transmission/transmissionFactor"));
    builder.doc["materials"][0]["extensions"]["KHR_materials_transmission"]["transmissionFactor"] = 0.5;
    builder.doc["materials"][1]["extensions"]["KHR_materials_ior"]["ior"] = 0.5;
    CHECK_THAT(load_error(builder.write(dir, "bad")), ContainsSubstring("/materials/1/extensions/KHR_materials_ior/ior: ior 0.5"));
    builder.doc["materials"][1]["extensions"]["KHR_materials_ior"]["ior"] = "glass";
    CHECK_THAT(load_error(builder.write(dir, "bad")), ContainsSubstring("KHR_materials_ior/ior: expected a finite number"));
  }
  SECTION("the extensions may be required") {
    builder.doc["extensionsRequired"] = {"KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"};
    CHECK(load_error(builder.write(dir, "required")).empty());
  }
}

TEST_CASE("gltf: a missing texture falls back to the base colour with a notice", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  const std::vector<rt::Vec3f> corners{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const int uv = builder.accessor({{"bufferView", builder.view(GltfBuilder::bytes_of(std::vector<rt::Vec2f>{{0, 0}, {1, 0}, {0, 1}}))},
                                   {"componentType", kFloat}, {"count", 3}, {"type", "VEC2"}});
  builder.node({{"mesh", builder.mesh({{"attributes", {{"POSITION", builder.vec3s(corners)}, {"TEXCOORD_0", uv}}}, {"material", 0}})}});
  builder.doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}, {"baseColorFactor", {0.5, 0.5, 0.5, 1}}}}}};
  builder.doc["textures"] = {{{"source", 0}}};
  builder.doc["images"] = {{{"uri", "nothere.png"}}};
  const rt::Scene scene = load(builder.write(dir));
  CHECK(has_notice(scene, "/images/0: texture image cannot be read (nothere.png: no such file)"));
  REQUIRE(scene.materials.size() == 1);
  CHECK(scene.materials[0].diffuse_texture.empty());
  CHECK(scene.materials[0].diffuse.r == Approx(0.5f));  // base (1 - metallic + metallic roughness), both 1 by default
}

// A 4x4 RGBA PNG (made with Python's zlib), grey (200, 200, 200) with alpha per texel, row 0 at
// the top: the values straddle the default cutoff 0.5 (127 and 128 of 255) and include 0 and 255.
const std::uint8_t kMaskAlpha[4][4] = {{255, 255, 64, 127}, {255, 255, 0, 127}, {191, 64, 0, 128}, {128, 0, 0, 64}};
const unsigned char kMaskPng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x04, 0x00, 0x00, 0x00, 0x04, 0x08, 0x06, 0x00, 0x00, 0x00, 0xa9, 0xf1, 0x9e, 0x7e, 0x00, 0x00, 0x00, 0x24, 0x49,
    0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0x38, 0x71, 0xe2, 0xc4, 0x7f, 0x28, 0x76, 0x00, 0xe2, 0x7a, 0x06, 0x24, 0x01,
    0x06, 0x98, 0xc0, 0x7e, 0xa8, 0x2c, 0x88, 0xdd, 0x00, 0x26, 0xa0, 0x1c, 0x10, 0x76, 0x00, 0x00, 0x49, 0x53, 0x2c,
    0xfa, 0x03, 0x35, 0x39, 0xb3, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

TEST_CASE("gltf alpha: MASK cuts out exactly the texels below the cutoff, in every intersector, for every ray kind",
          "[gltf][alpha]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "mask.png", std::string(reinterpret_cast<const char*>(kMaskPng), sizeof(kMaskPng)));
  GltfBuilder builder;
  // The unit quad z = 0 (texture v down from its top edge y = 1), and an opaque wall at z = -1
  // behind it that rays through the holes must hit.
  const std::vector<rt::Vec3f> quad{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const int uv = builder.accessor({{"bufferView", builder.view(GltfBuilder::bytes_of(std::vector<rt::Vec2f>{{0, 1}, {1, 1}, {1, 0}, {0, 0}}))},
                                   {"componentType", kFloat}, {"count", 4}, {"type", "VEC2"}});
  builder.node({{"mesh", builder.mesh({{"attributes", {{"POSITION", builder.vec3s(quad)}, {"TEXCOORD_0", uv}}},
                                       {"indices", builder.indices({0, 1, 2, 0, 2, 3})}, {"material", 0}})}});
  const std::vector<rt::Vec3f> wall{{-5, -5, -1}, {5, -5, -1}, {5, 5, -1}, {-5, 5, -1}};
  builder.node({{"mesh", builder.mesh({{"attributes", {{"POSITION", builder.vec3s(wall)}}},
                                       {"indices", builder.indices({0, 1, 2, 0, 2, 3})}, {"material", 1}})}});
  builder.doc["materials"] = {{{"alphaMode", "MASK"}, {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}},
                              {{"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 1}}}}}};
  builder.doc["textures"] = {{{"source", 0}, {"sampler", 0}}};
  builder.doc["samplers"] = {{{"magFilter", 9728}, {"wrapS", 33071}, {"wrapT", 33071}}};  // NEAREST, CLAMP
  builder.doc["images"] = {{{"uri", "mask.png"}}};
  const std::string path = builder.write(dir, "mask");

  for (const char* mode : {"MASK", "BLEND"}) {
    builder.doc["materials"][0]["alphaMode"] = mode;
    const rt::Scene scene = load(builder.write(dir, "mask"));
    REQUIRE(scene.materials.size() == 2);
    const rt::FlatScene flat = rt::flatten_scene(scene);
    const rt::SceneSurfaceTest test(scene, flat);
    REQUIRE(test.alpha().any());
    const bool mask = std::string(mode) == "MASK";
    // 64 x 64 rays along -z through texel interiors (texel edges fall on multiples of 16).
    std::vector<rt::Ray> rays;
    std::vector<bool> expect_quad, expect_blocked;
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i) {
        rt::Ray ray;
        ray.origin = rt::Vec3f((i + 0.5f) / 64.0f, (j + 0.5f) / 64.0f, 2.0f);
        ray.direction = rt::Vec3f(0, 0, -1);
        rays.push_back(ray);
        const double a = kMaskAlpha[3 - j / 16][i / 16] / 255.0;  // row 0 of the image is the top, y = 1
        expect_quad.push_back(mask ? a >= 0.5 : a > 0.0);  // closest hits: the quad's surface is there
        expect_blocked.push_back(true);                    // the wall blocks every ray anyway
      }
    for (const rt_test::Intersector& k : rt_test::kIntersectors) {
      const auto accel = k.build(flat, &test);
      REQUIRE(accel->surface_test() == &test);
      std::vector<rt::Hit> coherent(rays.size());
      accel->intersect_coherent(rays, coherent);
      std::vector<std::uint8_t> blocked(rays.size());
      int wrong = 0, wrong_coherent = 0, wrong_shadow = 0;
      for (std::size_t r = 0; r < rays.size(); ++r) {
        const rt::Hit hit = accel->intersect(rays[r]);
        REQUIRE(hit.found());
        const bool on_quad = hit.t == Approx(2.0f);
        wrong += on_quad != expect_quad[r] || (!on_quad && hit.t != Approx(3.0f));
        wrong_coherent += coherent[r].primitive != hit.primitive || coherent[r].t != hit.t;
        // A shadow ray that ends before the wall: blocked where the quad blocks.
        rt::Ray shadow = rays[r];
        shadow.tfar = 2.5f;
        const double a = kMaskAlpha[3 - (r / 64) / 16][(r % 64) / 16] / 255.0;
        wrong_shadow += accel->occluded(shadow) != (a >= 0.5);  // mask: the cutoff; blend: 1/2
        rays[r].tfar = 2.5f;
      }
      accel->occluded_coherent(rays, blocked);
      int wrong_shadow_coherent = 0;
      for (std::size_t r = 0; r < rays.size(); ++r) {
        const double a = kMaskAlpha[3 - (r / 64) / 16][(r % 64) / 16] / 255.0;
        wrong_shadow_coherent += (blocked[r] != 0) != (a >= 0.5);
        rays[r].tfar = rt::kInfinity;
      }
      INFO(mode << ", " << k.name);
      CHECK(wrong == 0);
      CHECK(wrong_coherent == 0);
      CHECK(wrong_shadow == 0);
      CHECK(wrong_shadow_coherent == 0);
    }
    CHECK(test.alpha().calls() > 0);
  }
}

TEST_CASE("gltf alpha: alphaMode, alphaCutoff and the base colour alpha map onto the material", "[gltf][alpha]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.triangle(true);
  builder.doc["meshes"][0]["primitives"][0]["material"] = 0;
  builder.doc["materials"] = {{{"alphaMode", "MASK"}, {"alphaCutoff", 0.3},
                               {"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 0.2}}}}}};
  const rt::Material mask = load(builder.write(dir, "a")).materials.at(0);
  CHECK(mask.alpha_mode == rt::AlphaMode::mask);
  CHECK(mask.alpha_cutoff == 0.3f);
  CHECK(mask.alpha == 0.2f);
  builder.doc["materials"][0]["alphaMode"] = "BLEND";
  CHECK(load(builder.write(dir, "a")).materials.at(0).alpha_mode == rt::AlphaMode::blend);
  builder.doc["materials"][0]["alphaMode"] = "OPAQUE";
  CHECK_FALSE(load(builder.write(dir, "a")).materials.at(0).has_alpha());
  builder.doc["materials"][0]["alphaMode"] = "CUTOUT";
  const std::string bad = builder.write(dir, "a");
  CHECK_THAT(load_error(bad), ContainsSubstring(bad + ":/materials/0/alphaMode: 'CUTOUT' is not OPAQUE, MASK or BLEND"));
}

TEST_CASE("gltf: truncated and corrupted copies of a file never crash the loader", "[gltf]") {
  rt_test::TempDir dir;
  GltfBuilder builder;
  builder.triangle(true);
  const std::string text = rt_test::read_file(builder.write(dir));
  const std::string bin = builder.bin;
  int failures = 0;
  for (std::size_t cut = 0; cut < text.size(); cut += std::max<std::size_t>(1, text.size() / 40)) {
    rt_test::write_file(dir / "cut.gltf", text.substr(0, cut));
    failures += !load_error(dir / "cut.gltf").empty();
  }
  for (std::size_t cut = 0; cut < bin.size(); cut += 4) {
    rt_test::write_file(dir / "scene.bin", bin.substr(0, cut));
    failures += !load_error(dir / "scene.gltf").empty();
  }
  CHECK(failures > 0);  // and the process is still alive
}

// --- the shared sample models -----------------------------------------------------------------

namespace {

std::optional<fs::path> models_dir() {
  const fs::path dir = fs::path(RT_SHARED_DATA_DIR) / "data" / "models" / "gltf";
  std::error_code error;
  if (fs::is_directory(dir, error)) return dir;
  WARN("glTF sample models not found at " << dir.string() << " (RT_SHARED_DATA_DIR): skipping");
  return std::nullopt;
}

// World-space vertices of the models of the glTF node named `name`, and the node's world origin.
std::vector<rt::Vec3d> world_vertices(const rt::Scene& scene, const std::string& name, rt::Vec3d* origin = nullptr) {
  std::vector<rt::Vec3d> out;
  std::vector<std::pair<std::uint32_t, rt::Mat4d>> stack{{scene.root, scene.nodes[scene.root].parent_from_node}};
  while (!stack.empty()) {
    const auto [index, world] = stack.back();
    stack.pop_back();
    const rt::Node& node = scene.nodes[index];
    if (node.name == name && origin) *origin = rt::Vec3d(world[3]);
    if (node.name == name)
      for (const rt::Model& model : node.models)
        for (const rt::Vec3f& p : model.mesh->positions) out.push_back(rt::Vec3d(world * rt::Vec4d(rt::Vec3d(p), 1.0)));
    for (std::uint32_t c : node.children) stack.push_back({c, world * scene.nodes[c].parent_from_node});
  }
  return out;
}

rt::Vec3d centroid(const std::vector<rt::Vec3d>& points) {
  rt::Vec3d sum(0.0);
  for (const rt::Vec3d& p : points) sum += p;
  return sum / double(points.size());
}

}  // namespace

TEST_CASE("gltf corpus: every sample model loads and renders something plausible", "[gltf][corpus]") {
  const auto dir = models_dir();
  if (!dir) return;
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(*dir)) {
    const std::string ext = entry.path().extension().string();
    if (ext == ".gltf" || ext == ".glb") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  REQUIRE(files.size() >= 26);
  for (const fs::path& file : files) {
    INFO(file.string());
    const auto start = std::chrono::steady_clock::now();
    const rt::Scene scene = rt::load_scene(file.string());
    const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const rt::Image image = render(scene, 160, 120);
    const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::size_t lit = 0;
    bool finite = true;
    for (const rt::Color& c : image.pixels) {
      finite = finite && std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b);
      lit += c != scene.settings.background;
    }
    CHECK(finite);
    CHECK(lit > image.pixels.size() / 100);  // at least 1 % of the image shows the model
    CHECK(lit < image.pixels.size());        // and the model is framed, not filling everything
    WARN(file.filename().string() << ": load " << load_s << " s, load + render 160x120 " << total_s << " s, "
                                  << 100.0 * lit / image.pixels.size() << " % covered");
  }
}

TEST_CASE("gltf corpus: OrientationTest's arrows point at their targets", "[gltf][corpus]") {
  const auto dir = models_dir();
  if (!dir) return;
  const rt::Scene scene = rt::load_scene((*dir / "OrientationTest/glTF/OrientationTest.gltf").string());
  const auto node_named = [&](const std::string& name) -> const rt::Node& {
    for (const rt::Node& node : scene.nodes)
      if (node.name == name) return node;
    FAIL("no node " << name);
    return scene.nodes[0];
  };
  const auto degrees = [](const rt::Vec3d& a, const rt::Vec3d& b) {
    return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)) * 180.0 / std::numbers::pi;
  };
  for (const std::string axis : {"X1", "X2", "Y1", "Y2", "Z1", "Z2"}) {
    INFO("arrow " << axis);
    // Every node hangs off the identity root. The arrow's node origin is its pivot; the angle at the
    // pivot between the arrow's centroid and the target's centroid is small but not zero (5 to 7
    // degrees: the shapes are not symmetric), while a transposed rotation (the classic
    // row/column-major mix-up) turns the arrow away by twice its rotation angle (11 to 140 degrees).
    const rt::Node& arrow = node_named("Arrow" + axis);
    const rt::Vec3d target = centroid(world_vertices(scene, "Target" + axis));
    const rt::Mat4d& m = arrow.parent_from_node;
    rt::Mat4d transposed = m;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) transposed[c][r] = m[r][c];
    const rt::Vec3d shape = centroid(world_vertices(scene, "Arrow" + axis));
    const rt::Vec3d pivot(m[3]);
    const rt::Vec3d ours = shape - pivot;
    const rt::Vec3d local_centroid(glm::inverse(m) * rt::Vec4d(shape, 1.0));
    const rt::Vec3d wrong = rt::Vec3d(transposed * rt::Vec4d(local_centroid, 1.0)) - pivot;
    const double ours_deg = degrees(ours, target - pivot), wrong_deg = degrees(wrong, target - pivot);
    INFO("ours " << ours_deg << " degrees, transposed " << wrong_deg << " degrees");
    CHECK(ours_deg < 8.0);
    CHECK(wrong_deg > ours_deg + 5.0);
  }
}

TEST_CASE("gltf corpus: the Box and Duck hierarchies give the expected world placement", "[gltf][corpus]") {
  const auto dir = models_dir();
  if (!dir) return;
  for (const char* file : {"Box/glTF/Box.gltf", "Box/glTF-Binary/Box.glb"}) {
    INFO(file);
    // The root's matrix turns the mesh's +z (its "up") into +y; the child has no transform.
    const rt::Scene box = rt::load_scene((*dir / file).string());
    const rt::Mat4d world = box.nodes[1].parent_from_node * box.nodes[2].parent_from_node;
    CHECK(near(rt::Vec3d(world * rt::Vec4d(0, 0, 1, 0)), {0, 1, 0}));
    CHECK(near(rt::Vec3d(world * rt::Vec4d(0, 1, 0, 0)), {0, 0, -1}));
    CHECK(rt::flatten_scene(box).triangle_count() == 12);
  }
  // The duck's mesh node sits under a 0.01 scale; its world bounds are the accessor's min/max
  // scaled by 0.01. The camera node (a sibling) adds nothing.
  const fs::path duck_path = *dir / "Duck/glTF/Duck.gltf";
  const json duck = json::parse(rt_test::read_file(duck_path));
  const int position = duck["meshes"][0]["primitives"][0]["attributes"]["POSITION"];
  const json& accessor = duck["accessors"][position];
  const rt::FlatScene flat = rt::flatten_scene(rt::load_scene(duck_path.string()));
  rt::Vec3d lo(1e30), hi(-1e30);
  for (const rt::Vec3f& p : flat.positions) {
    lo = glm::min(lo, rt::Vec3d(p));
    hi = glm::max(hi, rt::Vec3d(p));
  }
  for (int i = 0; i < 3; ++i) {
    CHECK(lo[i] == Approx(0.01 * accessor["min"][i].get<double>()).margin(1e-4));
    CHECK(hi[i] == Approx(0.01 * accessor["max"][i].get<double>()).margin(1e-4));
  }
  CHECK(flat.triangle_count() == 4212);
}

TEST_CASE("gltf corpus: a texture in a GLB bufferView renders like the same texture as a file", "[gltf][corpus]") {
  const auto dir = models_dir();
  if (!dir) return;
  // BoxTextured.gltf reads CesiumLogoFlat.png by uri; the .glb carries the same PNG in a bufferView.
  const rt::Image by_file = render(rt::load_scene((*dir / "BoxTextured/glTF/BoxTextured.gltf").string()), 160, 120);
  const rt::Image by_view = render(rt::load_scene((*dir / "BoxTextured/glTF-Binary/BoxTextured.glb").string()), 160, 120);
  CHECK(by_view.pixels == by_file.pixels);
  // The logo shows: a flat-shaded box without it has a handful of colours, not hundreds.
  std::set<std::tuple<float, float, float>> colours;
  for (const rt::Color& c : by_view.pixels) colours.emplace(c.r, c.g, c.b);
  CHECK(colours.size() > 100);
}
