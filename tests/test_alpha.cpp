// Alpha (issue 20): blended surfaces composited by their alpha, the loaders' alpha keys, and
// texture colour read apart from alpha. The cut-outs' texel exactness and the intersectors'
// agreement with filters are in test_load_gltf.cpp (on a glTF MASK material).

#include "catch.h"

#include <string>

#include <fmt/format.h>

#include "rt/accel/accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_scene.h"
#include "rt/render/surface_test.h"
#include "rt/render/render.h"
#include "rt/render/texture.h"
#include "test_util.h"

using Catch::Matchers::ContainsSubstring;

namespace {

// A 2x1 RGBA PNG, made with Python's zlib: texel 0 red (255, 0, 0) at alpha 128, texel 1 green
// (0, 255, 0) at alpha 255.
const unsigned char kRedHalfAlphaPng[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x01, 0x08, 0x06, 0x00, 0x00, 0x00, 0xf4, 0x22, 0x7f, 0x8a, 0x00, 0x00, 0x00, 0x11, 0x49,
    0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0xf8, 0xcf, 0xc0, 0xd0, 0xc0, 0xf0, 0x9f, 0xe1, 0x3f, 0x00, 0x0e, 0x7d, 0x03,
    0x7e, 0x97, 0x19, 0x0c, 0xde, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};

// A unit quad in the plane z = 0 facing +z, seen head-on by a camera at z = 3; `material` is the
// quad's (native-format keys), background 0.2 grey, recursion to `max_depth`.
rt::Scene quad_scene(const std::string& material, int max_depth) {
  return rt::parse_scene_json(fmt::format(R"({{
    "image": {{ "width": 8, "height": 8 }},
    "max_depth": {},
    "background": [0.2, 0.2, 0.2],
    "camera": {{ "eye": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 10 }},
    "materials": {{ "m": {} }},
    "nodes": [ {{ "models": [ {{ "material": "m", "geometry": {{ "type": "mesh",
      "positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "triangles": [[0, 1, 2], [0, 2, 3]] }} }} ] }},
      {{ "translate": [0, 0, -1], "models": [ {{ "material": "m", "geometry": {{ "type": "mesh",
      "positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "triangles": [[0, 1, 2], [0, 2, 3]] }} }} ] }} ]
  }})", max_depth, material), "quad.json");
}

rt::Color centre_pixel(const rt::Scene& scene) {
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const rt::SceneSurfaceTest test(scene, flat);
  const auto accel = rt::build_accel(rt::AccelKind::embree, flat, rt::with_surface_test({}, test));
  return rt::render_image(scene, flat, *accel, {}).image.at(4, 4);
}

}  // namespace

TEST_CASE("a blended surface is seen with weight alpha, what lies behind with 1 - alpha, one level each", "[alpha]") {
  // Two quads one behind the other, each self-emitting 1 at alpha 0.5, before a 0.2 background.
  const std::string half = R"({ "emission": 1, "alpha": 0.5 })";
  // Front 0.5 x 1, then the back quad 0.5 x 1, then the background: 0.5 + 0.5 (0.5 + 0.5 x 0.2).
  CHECK(centre_pixel(quad_scene(half, 2)).r == Approx(0.8).epsilon(1e-6));
  // One level: the see-through ray from the front quad finds the back one at max depth, which is
  // then drawn fully: 0.5 + 0.5 x 1.
  CHECK(centre_pixel(quad_scene(half, 1)).r == Approx(1.0).epsilon(1e-6));
  // No level: the front quad is drawn fully.
  CHECK(centre_pixel(quad_scene(half, 0)).r == Approx(1.0).epsilon(1e-6));
  // Alpha 0 is no surface at all: the background shows, unweighted.
  CHECK(centre_pixel(quad_scene(R"({ "emission": 1, "alpha": 0 })", 3)).r == Approx(0.2).epsilon(1e-6));
  // Mask: alpha 0.5 against cutoffs either side.
  CHECK(centre_pixel(quad_scene(R"({ "emission": 1, "alpha": 0.5, "alpha_mode": "mask", "alpha_cutoff": 0.6 })", 3)).r ==
        Approx(0.2).epsilon(1e-6));
  CHECK(centre_pixel(quad_scene(R"({ "emission": 1, "alpha": 0.5, "alpha_mode": "mask", "alpha_cutoff": 0.4 })", 3)).r ==
        Approx(1.0).epsilon(1e-6));
  // Opaque ignores alpha.
  CHECK(centre_pixel(quad_scene(R"({ "emission": 1, "alpha": 0.5, "alpha_mode": "opaque" })", 3)).r ==
        Approx(1.0).epsilon(1e-6));
}

TEST_CASE("alpha in the native format: keys, defaults and errors naming the JSON path", "[alpha]") {
  const rt::Material blend = quad_scene(R"({ "alpha": 0.25 })", 1).materials.at(0);
  CHECK(blend.alpha_mode == rt::AlphaMode::blend);
  CHECK(blend.alpha == 0.25f);
  CHECK(blend.has_alpha());
  CHECK_FALSE(quad_scene(R"({ "alpha": 1 })", 1).materials.at(0).has_alpha());  // nothing to test
  const auto error = [](const std::string& material) {
    try {
      quad_scene(material, 1);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK_THAT(error(R"({ "alpha": 1.5 })"), ContainsSubstring("/materials/m/alpha: alpha 1.5 is outside [0, 1]"));
  CHECK_THAT(error(R"({ "alpha_mode": "cutout" })"), ContainsSubstring("/materials/m/alpha_mode: 'cutout' is not opaque, mask or blend"));
  CHECK_THAT(error(R"({ "alpha_cutoff": -1 })"), ContainsSubstring("/materials/m/alpha_cutoff"));
}

TEST_CASE("MTL dissolve: d and Tr blend, map_d is a scalar alpha map, glass ignores d", "[alpha][obj]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "a.mtl", R"(newmtl d
d 0.25
newmtl tr
Tr 0.75
newmtl map
map_d mask.png
newmtl opaque
d 1
newmtl glass
illum 7
d 0.5
)");
  std::string obj = "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
  for (const char* name : {"d", "tr", "map", "opaque", "glass"}) obj += fmt::format("usemtl {}\nf 1 2 3\n", name);
  rt_test::write_file(dir / "a.obj", obj);
  const rt::Scene scene = rt::load_scene(dir / "a.obj");
  const auto material = [&](const std::string& name) -> const rt::Material& { return rt_test::material_named(scene, name); };
  CHECK(material("d").alpha_mode == rt::AlphaMode::blend);
  CHECK(material("d").alpha == 0.25f);
  CHECK(material("tr").alpha == Approx(0.25f));  // Tr is 1 - d
  CHECK(material("map").alpha_from_grey);
  CHECK_THAT(material("map").alpha_texture.path, ContainsSubstring("mask.png"));
  CHECK(material("opaque").alpha_mode == rt::AlphaMode::opaque);
  CHECK(material("glass").alpha_mode == rt::AlphaMode::opaque);
  CHECK(material("glass").is_dielectric());
}

TEST_CASE("textures: a half-transparent texel keeps its colour (alpha is not multiplied in)", "[alpha]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "rgba.png", std::string(reinterpret_cast<const char*>(kRedHalfAlphaPng), sizeof(kRedHalfAlphaPng)));
  rt::Scene scene;
  rt::Material m;
  m.diffuse_texture.path = dir / "rgba.png";
  scene.materials.push_back(m);
  const rt::TextureSampler textures(scene);
  REQUIRE(textures.has_diffuse(0));
  // Texel 0's centre: sRGB (255, 0, 0) is linear 1, whatever its alpha of 128 / 255.
  const rt::Color red = textures.diffuse(0, rt::TexCoords{rt::Vec2f(0.25f, 0.5f)});
  CHECK(red.r == Approx(1.0f).epsilon(1e-5));
  CHECK(red.g == Approx(0.0f).margin(1e-6));
  const rt::Color green = textures.diffuse(0, rt::TexCoords{rt::Vec2f(0.75f, 0.5f)});
  CHECK(green.g == Approx(1.0f).epsilon(1e-5));
  // The mean the glTF loader uses for highlights is unassociated too.
  const auto mean = rt::texture_mean(m.diffuse_texture);
  REQUIRE(mean.has_value());
  CHECK(mean->r == Approx(0.5f).epsilon(1e-5));
  CHECK(mean->a == Approx((128.0f / 255.0f + 1.0f) / 2.0f).epsilon(1e-5));
}
