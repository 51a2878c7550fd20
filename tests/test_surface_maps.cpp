// Texture maps sampled per hit (issue 22, item 3): MikkTSpace-style tangents, normal maps
// (analytic tilt, the green channel on the NormalTangentTest sample), metallic-roughness per
// texel, KHR_texture_transform, TEXCOORD_1 and COLOR_0.

#include "catch.h"

#include <cmath>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_gltf.h"
#include "rt/io/load_obj.h"
#include "rt/render/render.h"
#include "rt/render/surface_maps.h"
#include "rt/render/surface_test.h"
#include "rt/scene/tangents.h"
#include "test_util.h"

namespace {

constexpr double kPi = 3.14159265358979323846;

// 1x1 and 2x1 RGB PNGs (Python's zlib): a tangent-space normal (218, 128, 218) tilted towards
// +u, (128, 218, 218) tilted towards +Y (up the image); red | green texels; metallic-roughness
// texels (G 255, B 0) | (G 255, B 255).
constexpr const char* kTiltU = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGO41XALAARsAjUQ4/RCAAAAAElFTkSuQmCC";
constexpr const char* kTiltY = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAIAAACQd1PeAAAADElEQVR4nGNouHULAAQSAjVDXWrsAAAAAElFTkSuQmCC";
constexpr const char* kRedGreen =
    "iVBORw0KGgoAAAANSUhEUgAAAAIAAAABCAIAAAB7QOjdAAAAD0lEQVR4nGP4z8DA8J8BAAf/Af8Bf4mnAAAAAElFTkSuQmCC";
constexpr const char* kDielectricMetal =
    "iVBORw0KGgoAAAANSUhEUgAAAAIAAAABCAIAAAB7QOjdAAAAD0lEQVR4nGNg+M/A8P8/AAf/Av5yGjE6AAAAAElFTkSuQmCC";

// A quad (-1..1)^2 in z = 0 facing +z; NORMAL +z; TEXCOORD_0 (u, v) = ((x + 1) / 2, (1 - y) / 2),
// so the image's top is at y = 1; TEXCOORD_1 (0.75, 0.5) everywhere. No TANGENT.
constexpr const char* kQuadBuffer =
    "AACAvwAAgL8AAAAAAACAPwAAgL8AAAAAAACAPwAAgD8AAAAAAACAvwAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAIA/AAAAAAAAAAAAAIA/"
    "AAAAAAAAAAAAAIA/AAAAAAAAgD8AAIA/AACAPwAAgD8AAAAAAAAAAAAAAAAAAEA/AAAAPwAAQD8AAAA/AABAPwAAAD8AAEA/AAAAPwAAAQACAAAA"
    "AgADAA==";

// The quad with material `material` (JSON, may name images 0..3 = kTiltU, kTiltY, kRedGreen,
// kDielectricMetal through textures 0..3), seen from z = 3, lit by a directional light shining
// along `light_direction`.
std::string quad_gltf(const std::string& material, const rt::Vec3d& light_direction, const std::string& extra_attributes = "") {
  // The light's node looks down its -z: rotate -z onto `light_direction` (a quaternion).
  const rt::Vec3d from(0, 0, -1), to = glm::normalize(light_direction);
  const rt::Vec3d axis = glm::cross(from, to);
  const double w = 1.0 + glm::dot(from, to);
  const glm::dvec4 q = glm::normalize(glm::dvec4(axis, w));
  const auto image = [](const char* png) { return fmt::format(R"({{ "uri": "data:image/png;base64,{}" }})", png); };
  return fmt::format(R"({{
    "asset": {{ "version": "2.0" }}, "scene": 0, "scenes": [ {{ "nodes": [0, 1, 2] }} ],
    "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_ior", "KHR_texture_transform"],
    "extensions": {{ "KHR_lights_punctual": {{ "lights": [ {{ "type": "directional", "intensity": 1 }} ] }} }},
    "nodes": [ {{ "mesh": 0 }}, {{ "camera": 0, "translation": [0, 0, 3] }},
               {{ "rotation": [{}, {}, {}, {}], "extensions": {{ "KHR_lights_punctual": {{ "light": 0 }} }} }} ],
    "cameras": [ {{ "type": "perspective", "perspective": {{ "yfov": 0.8, "znear": 0.1, "aspectRatio": 1 }} }} ],
    "materials": [ {} ],
    "images": [ {}, {}, {}, {} ],
    "samplers": [ {{ "magFilter": 9728, "wrapS": 33071, "wrapT": 33071 }} ],
    "textures": [ {{ "source": 0 }}, {{ "source": 1 }}, {{ "source": 2, "sampler": 0 }}, {{ "source": 3, "sampler": 0 }} ],
    "meshes": [ {{ "primitives": [ {{ "attributes": {{ "POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3 {} }},
                                      "indices": 4, "material": 0 }} ] }} ],
    "accessors": [
      {{ "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0] }},
      {{ "bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC3" }},
      {{ "bufferView": 0, "byteOffset": 96, "componentType": 5126, "count": 4, "type": "VEC2" }},
      {{ "bufferView": 0, "byteOffset": 128, "componentType": 5126, "count": 4, "type": "VEC2" }},
      {{ "bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR" }} ],
    "bufferViews": [ {{ "buffer": 0, "byteLength": 160 }}, {{ "buffer": 0, "byteOffset": 160, "byteLength": 12 }} ],
    "buffers": [ {{ "byteLength": 172, "uri": "data:application/octet-stream;base64,{}" }} ]
  }})", q.x, q.y, q.z, q.w, material, image(kTiltU), image(kTiltY), image(kRedGreen), image(kDielectricMetal),
                     extra_attributes, kQuadBuffer);
}

// White, rough, non-metallic and with index 1 (no highlight, no mirror: F0 = 0), plus `extra`.
std::string matte(const std::string& extra = "") {
  return R"({ "pbrMetallicRoughness": { "metallicFactor": 0, "roughnessFactor": 1 },
              "extensions": { "KHR_materials_ior": { "ior": 1.0 } })" + extra + " }";
}

// Renders `gltf` (written to `dir`) at 16x16, linear, with its surface test, as rt render does.
rt::Image render_gltf(const rt_test::TempDir& dir, const std::string& gltf) {
  rt_test::write_file(dir / "quad.gltf", gltf);
  rt::Scene scene = rt::load_gltf_scene(dir / "quad.gltf");
  scene.settings.width = scene.settings.height = 16;
  return rt_test::render_as_rt_does(scene);
}

// The tangent-space normal a 8-bit texel encodes, unit (glTF: 2 c / 255 - 1 per channel).
rt::Vec3d decoded_normal(int r, int g, int b) {
  return glm::normalize(rt::Vec3d(2.0 * r / 255.0 - 1.0, 2.0 * g / 255.0 - 1.0, 2.0 * b / 255.0 - 1.0));
}

}  // namespace

TEST_CASE("generated tangents run along +u with bitangents up the image, mirrored UVs flip the handedness",
          "[surface-maps][tangents]") {
  // Two triangles of the quad in z = 0, v = (1 - y) / 2 (the image's top at y = 1).
  rt::TriangleMesh mesh;
  mesh.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  mesh.normals.assign(4, rt::Vec3f(0, 0, 1));
  for (const rt::Vec3f& p : mesh.positions) mesh.texcoords.push_back({(p.x + 1) / 2, (1 - p.y) / 2});
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  CHECK(rt::generate_tangents(mesh) == 0);
  REQUIRE(mesh.tangents.size() == 4);
  for (const rt::Vec4f& t : mesh.tangents) {
    CHECK(rt::Vec3d(t) == rt::Vec3d(1, 0, 0));
    CHECK(t.w == 1.0f);  // w cross(n, t) = (0, 1, 0): up the image, the normal map's +Y
  }
  // Mirrored in u: the tangent turns to -x, and the bitangent keeps pointing up: w = -1.
  for (rt::Vec2f& uv : mesh.texcoords) uv.x = 1 - uv.x;
  rt::generate_tangents(mesh);
  for (const rt::Vec4f& t : mesh.tangents) {
    CHECK(t.x == Approx(-1.0f));
    CHECK(t.w == -1.0f);
    CHECK(glm::dot(float(t.w) * glm::cross(rt::Vec3f(0, 0, 1), rt::Vec3f(t)), rt::Vec3f(0, 1, 0)) == Approx(1.0f));
  }
  // One triangle mirrored against the other: their shared vertices are split, one copy per handedness.
  mesh.texcoords = {{0, 1}, {1, 1}, {1, 0}, {2, 0}};  // triangle 2's u runs backwards over (0, 2, 3)
  mesh.tangents.clear();
  rt::generate_tangents(mesh);
  CHECK(mesh.positions.size() == 6);
  CHECK(mesh.tangents.size() == 6);
}

TEST_CASE("a constant tilted normal map shades like the tilted plane it stands for", "[surface-maps][normal-map]") {
  rt_test::TempDir dir;
  // Light from the upper right (travelling along -x -y -z, towards the quad).
  const rt::Vec3d travel(-0.5, -0.4, -1.0), to_light = -glm::normalize(travel);
  // White diffuse, n = +z; a directional light of 1 lux gives intensity 1 / pi (docs/scene-formats.md).
  const double flat = render_gltf(dir, quad_gltf(matte(), travel)).at(8, 8).r;
  REQUIRE(flat == Approx(to_light.z / kPi).epsilon(1e-4));
  // Tilted towards +u = +x, and towards the image's +Y = +y (the green channel).
  const rt::Vec3d tilt_u = decoded_normal(218, 128, 218), tilt_y = decoded_normal(128, 218, 218);
  const double lit_u =
      render_gltf(dir, quad_gltf(matte(R"(, "normalTexture": { "index": 0 })"), travel)).at(8, 8).r;
  const double lit_y =
      render_gltf(dir, quad_gltf(matte(R"(, "normalTexture": { "index": 1 })"), travel)).at(8, 8).r;
  CHECK(lit_u == Approx(glm::dot(tilt_u, to_light) / kPi).epsilon(1e-3));
  CHECK(lit_y == Approx(glm::dot(tilt_y, to_light) / kPi).epsilon(1e-3));
  // A flipped green channel would give (x, -y, z): visibly darker here.
  CHECK(std::abs(lit_y - glm::dot(rt::Vec3d(tilt_y.x, -tilt_y.y, tilt_y.z), to_light) / kPi) > 0.03);
  // normalTexture.scale scales X and Y: 0 flattens the map.
  const double unscaled =
      render_gltf(dir, quad_gltf(matte(R"(, "normalTexture": { "index": 0, "scale": 0 })"), travel)).at(8, 8).r;
  CHECK(unscaled == Approx(flat).epsilon(1e-4));
}

TEST_CASE("NormalTangentTest (glTF sample): normal-mapped bumps are lit from the side real bumps are",
          "[surface-maps][normal-map][gltf][shared]") {
  const std::filesystem::path path =
      std::filesystem::path(RT_SHARED_DATA_DIR) / "data/models/gltf/NormalTangentTest/glTF/NormalTangentTest.gltf";
  if (!std::filesystem::exists(path)) {
    WARN("glTF sample NormalTangentTest not found at " << path.string() << " (RT_SHARED_DATA_DIR): skipping");
    return;
  }
  // Face-on at 240x240 with light from above: each cell pair holds a real bump (left) and a
  // normal-mapped quad (right, 30 pixels on); the sample has no TANGENT, so rt generates them.
  rt_test::TempDir dir;
  const rt_test::RtRun run = rt_test::run_rt_in(
      dir, "render '" + path.string() +
               "' -o cells.ppm --width 240 --height 240 --eye 0 0 3.2 --target 0 -0.12 0 --directional-light 0 1 1 1 1 1 --quiet");
  REQUIRE(run.status == 0);
  const rt::Image image = rt::read_image(dir / "cells.ppm");
  const auto brightness = [&](int x0, int y0, int y1) {  // summed over 5 columns around x0, rows y0..y1
    double sum = 0.0;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0 - 2; x <= x0 + 2; ++x) sum += double(image.at(x, y).r) + image.at(x, y).g + image.at(x, y).b;
    return sum;
  };
  for (const int real_x : {32, 107})        // the two columns of diffuse cells (the third is a mirror)
    for (const int y : {35, 72, 109, 146, 183}) {  // bump centres, one per row
      for (const int x : {real_x, real_x + 30}) {
        INFO("bump at pixel (" << x << ", " << y << ")" << (x == real_x ? " (geometry)" : " (normal map)"));
        CHECK(brightness(x, y - 7, y - 3) > 1.2 * brightness(x, y + 3, y + 7));  // upper half brighter
      }
    }
}

TEST_CASE("metallic-roughness is evaluated per texel, not from the texture's mean", "[surface-maps][gltf]") {
  rt_test::TempDir dir;
  // Left half dielectric, right half metal (blue 0 | 255), roughness 0.5 x 1 everywhere; the light
  // grazes from the side away from the camera, so the highlight (exponent 2 / 0.5^4 - 2 = 30, n.h
  // ~ 0.7) is negligible: diffuse b (1 - m + m r).
  const rt::Vec3d travel(1.0, 0.0, -0.2);  // from -x, away from the metal half's mirror direction
  const std::string material = R"({ "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.8, 0.8, 1],
      "metallicFactor": 1, "roughnessFactor": 0.5, "metallicRoughnessTexture": { "index": 3 } },
      "extensions": { "KHR_materials_ior": { "ior": 1.0 } } })";
  const rt::Image image = render_gltf(dir, quad_gltf(material, travel));
  const double n_dot_l = glm::normalize(-travel).z;
  CHECK(image.at(3, 8).r == Approx(0.8 * n_dot_l / kPi).epsilon(2e-3));        // dielectric texel
  CHECK(image.at(12, 8).r == Approx(0.8 * 0.5 * n_dot_l / kPi).epsilon(2e-3));  // metal texel
}

TEST_CASE("textures read TEXCOORD_1 and KHR_texture_transform", "[surface-maps][gltf]") {
  rt_test::TempDir dir;
  const rt::Vec3d travel(0.0, 0.0, -1.0);
  const auto base = [&](const std::string& texture_info) {
    return render_gltf(dir, quad_gltf(matte(R"(, "pbrMetallicRoughness": { "baseColorTexture": )" + texture_info +
                                            R"(, "metallicFactor": 0 })"),
                                      travel));
  };
  // TEXCOORD_0 puts pixel column 3 in the red texel (u ~ 0.14); TEXCOORD_1 is (0.75, 0.5): green.
  // Head-on light: a pure texel reads 1 / pi in its channel, 0 in the others.
  const float full = float(0.99 / kPi);
  const rt::Image set0 = base(R"({ "index": 2 })");
  CHECK(set0.at(3, 8).r > full);
  CHECK(set0.at(3, 8).g < 0.01f);
  const rt::Image set1 = base(R"({ "index": 2, "texCoord": 1 })");
  CHECK(set1.at(3, 8).g > full);
  CHECK(set1.at(3, 8).r < 0.01f);
  // An offset of 0.7 moves u ~ 0.14 into the green texel; the extension's texCoord wins.
  const rt::Image offset = base(R"({ "index": 2, "extensions": { "KHR_texture_transform": { "offset": [0.7, 0] } } })");
  CHECK(offset.at(3, 8).g > full);
  const rt::Image overridden =
      base(R"({ "index": 2, "texCoord": 1, "extensions": { "KHR_texture_transform": { "texCoord": 0 } } })");
  CHECK(overridden.at(3, 8).r > full);
  // The extension's own example: rotation by pi/2 turns (1, 0) into (0, 1).
  rt::TextureTransform rotate;
  rotate.rotation = float(std::acos(-1.0) / 2);
  CHECK(rotate.apply({1, 0}).x == Approx(0.0f).margin(1e-6));
  CHECK(rotate.apply({1, 0}).y == Approx(1.0f));
  rt::TextureTransform all;
  all.offset = {0.5f, 0.25f};
  all.scale = {2.0f, 3.0f};
  CHECK(all.apply({1, 1}) == rt::Vec2f(2.5f, 3.25f));
}

TEST_CASE("COLOR_0 multiplies the base colour", "[surface-maps][gltf]") {
  rt_test::TempDir dir;
  const std::filesystem::path path =
      std::filesystem::path(RT_SHARED_DATA_DIR) / "data/models/gltf/BoxVertexColors/glTF/BoxVertexColors.gltf";
  if (!std::filesystem::exists(path)) {
    WARN("glTF sample BoxVertexColors not found at " << path.string() << " (RT_SHARED_DATA_DIR): skipping");
    return;
  }
  rt::Scene scene = rt::load_gltf_scene(path.string());
  scene.settings.width = scene.settings.height = 32;
  const rt::FlatScene flat = rt::flatten_scene(scene);
  REQUIRE(flat.colors.size() == flat.positions.size());
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
  const rt::Image image = rt::render_image(scene, flat, *accel, {}).image;
  // The box's colours vary per vertex: some pixel is far from grey.
  double most_saturated = 0.0;
  for (const rt::Color& c : image.pixels)
    most_saturated = std::max(most_saturated, double(std::max({c.r, c.g, c.b}) - std::min({c.r, c.g, c.b})));
  CHECK(most_saturated > 0.3);
}

namespace {

// A 2x1 grey PNG (Python's zlib): texels 0 | 255, a height ramp between the texel centres.
const unsigned char kRampPng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x01, 0x08, 0x00, 0x00, 0x00, 0x00, 0xd1, 0x49, 0x20, 0x56, 0x00, 0x00, 0x00, 0x0b, 0x49,
    0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x60, 0xf8, 0x0f, 0x00, 0x01, 0x02, 0x01, 0x00, 0x42, 0xbe, 0xbc, 0x68, 0x00,
    0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

}  // namespace

TEST_CASE("MTL maps: map_Ks, map_Ns, norm and a bump height map that tilts the normal by its slope",
          "[surface-maps][obj]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "ramp.png", std::string(reinterpret_cast<const char*>(kRampPng), sizeof kRampPng));
  // The quad (-1..1)^2 in z = 0 with vt = ((x + 1) / 2, (y + 1) / 2): u runs along +x.
  rt_test::write_file(dir / "quad.obj", "mtllib quad.mtl\nusemtl bumpy\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                                        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
  rt_test::write_file(dir / "quad.mtl", "newmtl bumpy\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nbump -bm 0.5 ramp.png\n"
                                        "newmtl mapped\nKd 1 1 1\nmap_Ks ramp.png\nmap_Ns ramp.png\nnorm ramp.png\n");
  rt::Scene scene = rt::load_obj_scene(dir / "quad.obj");
  const rt::Material& mapped = rt_test::material_named(scene, "mapped");
  CHECK(mapped.specular_texture.path == dir / "ramp.png");
  CHECK(mapped.shininess_texture.path == dir / "ramp.png");
  CHECK(mapped.normal_texture.path == dir / "ramp.png");
  CHECK(mapped.bump_texture.empty());
  const rt::Material& bumpy = rt_test::material_named(scene, "bumpy");
  REQUIRE(bumpy.bump_texture.path == dir / "ramp.png");
  CHECK(bumpy.bump_scale == 0.5f);

  // Height h = 0.5 (u - 1/4) / (1/2) between the texel centres: dh/du = 1, and dp/du = (2, 0, 0),
  // so the displaced surface's normal is cross((2, 0, 1), dp/dv) turned up: (-1, 0, 2) / sqrt(5).
  scene.settings.width = scene.settings.height = 16;
  scene.camera = {rt::Vec3d(0, 0, 3), rt::Vec3d(0), rt::Vec3d(0, 1, 0), 30.0};
  rt::Light light;
  light.position = rt::Vec4d(-1.0, 0.0, 1.0, 0.0);  // towards the light
  scene.lights = {light};
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat);
  const rt::Image image = rt::render_image(scene, flat, *accel, {}).image;
  const rt::Vec3d bumped = glm::normalize(rt::Vec3d(-1, 0, 2)), to_light = glm::normalize(rt::Vec3d(-1, 0, 1));
  CHECK(image.at(8, 8).r == Approx(glm::dot(bumped, to_light)).epsilon(2e-3));  // flat: 0.707
}

TEST_CASE("occlusion maps scale the ambient term by 1 + strength (r - 1)", "[surface-maps]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "ramp.png", std::string(reinterpret_cast<const char*>(kRampPng), sizeof kRampPng));
  // One triangle whose texture coordinates are constant: u = 0.25 (the black texel, r = 0) or
  // 0.75 (the white one, r = 1).
  for (const float u : {0.25f, 0.75f})
    for (const float strength : {1.0f, 0.5f}) {
      rt::TriangleMesh mesh = rt_test::make_flat_mesh({{rt::Vec3f(0, 0, 0), rt::Vec3f(1, 0, 0), rt::Vec3f(0, 1, 0)}});
      mesh.texcoords.assign(3, rt::Vec2f(u, 0.5f));
      rt::Scene scene = rt_test::make_scene({{mesh, 0}});
      rt::Material material;
      material.ambient = rt::Color(0.5f);
      material.occlusion_texture.path = dir / "ramp.png";
      material.occlusion_texture.wrap_s = rt::TextureWrap::clamp_to_edge;
      material.occlusion_strength = strength;
      scene.materials.push_back(material);
      const rt::FlatScene flat = rt::flatten_scene(scene);
      const rt::TextureSampler textures(scene);
      rt::Hit hit;
      hit.primitive = 0;
      hit.u = hit.v = 0.25f;
      rt::SurfaceTerms terms;
      terms.ambient = rt::Vec3d(0.5);
      rt::apply_surface_maps(flat, &textures, 0, scene.materials[0], hit, rt::texcoords_at(flat, 0, 0.5f, 0.25f, 0.25f),
                             rt::Vec3d(1.0), terms);
      const double r = u < 0.5f ? 0.0 : 1.0;
      INFO("u " << u << ", strength " << strength);
      CHECK(terms.ambient.r == Approx(0.5 * (1.0 + strength * (r - 1.0))).margin(1e-6));
    }
}

TEST_CASE("rt info lists a material's per-hit maps", "[surface-maps][cli]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "quad.gltf",
                      quad_gltf(matte(R"(, "normalTexture": { "index": 0, "scale": 0.5 },
                                        "occlusionTexture": { "index": 1, "texCoord": 1, "strength": 0.25 })"),
                                rt::Vec3d(0, 0, -1)));
  const rt_test::RtRun run = rt_test::run_rt_in(dir, "info quad.gltf");
  REQUIRE(run.status == 0);
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("normal map ") && Catch::Matchers::ContainsSubstring("(scale 0.5)") &&
                          Catch::Matchers::ContainsSubstring("on TEXCOORD_1 (strength 0.25)"));
}

TEST_CASE("glTF glass under a metallic-roughness texture transmits only where the texel is not metal",
          "[surface-maps][gltf][glass]") {
  rt_test::TempDir dir;
  // Left half dielectric, right half metal; behind the quad, a white background.
  const std::string material = R"({ "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.8, 0.8, 1],
      "metallicFactor": 1, "roughnessFactor": 0.5, "metallicRoughnessTexture": { "index": 3 } },
      "extensions": { "KHR_materials_transmission": { "transmissionFactor": 1 } } })";
  rt_test::write_file(dir / "quad.gltf", quad_gltf(material, rt::Vec3d(0, 0, -1)));
  rt::Scene scene = rt::load_gltf_scene(dir / "quad.gltf");
  REQUIRE(scene.materials.at(0).is_dielectric());
  scene.settings.width = scene.settings.height = 16;
  scene.settings.background = rt::Color(1.0f);
  const rt::Image image = rt_test::render_as_rt_does(scene);
  CHECK(image.at(3, 8).g > 0.7f);   // through the glass: the background x (1 - F) x base colour 0.8
  CHECK(image.at(12, 8).g < 0.3f);  // the metal: lit diffuse only, nothing transmitted
}
