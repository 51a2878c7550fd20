// The display transform (issue 22): how linear images become 8-bit files and window pixels.

#include "catch.h"

#include <cmath>
#include <string>

#include "rt/core/display.h"
#include "rt/core/error.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "test_util.h"

using Catch::Matchers::ContainsSubstring;
using rt::DisplayEncoding;
using rt::DisplayTransform;
using rt::ToneMap;

namespace {

std::uint8_t grey_byte(float c, const DisplayTransform& display) {
  std::uint8_t out[3];
  rt::encode_8bit(rt::Color(c), display, out);
  CHECK(out[0] == out[1]);
  CHECK(out[1] == out[2]);
  return out[0];
}

// IEC 61966-2-1, written out here independently of the renderer's code.
double srgb(double c) { return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055; }

}  // namespace

TEST_CASE("display: the default is the course's floor(255 c), bit for bit", "[display]") {
  for (int i = -10; i <= 2600; ++i) {
    const float c = float(i) / 2550.0f;
    CHECK(grey_byte(c, {}) == rt::quantize_8bit(c));
  }
  CHECK(grey_byte(NAN, {}) == 0);
  CHECK(grey_byte(INFINITY, {}) == 255);
}

TEST_CASE("display: sRGB encodes with IEC 61966-2-1 and rounds", "[display]") {
  const DisplayTransform s{DisplayEncoding::srgb, 0.0, ToneMap::none};
  CHECK(grey_byte(0.0f, s) == 0);
  CHECK(grey_byte(1.0f, s) == 255);
  CHECK(grey_byte(2.0f, s) == 255);
  CHECK(grey_byte(-1.0f, s) == 0);
  CHECK(grey_byte(NAN, s) == 0);
  for (const float c : {0.001f, 0.0031308f, 0.01f, 0.18f, 0.5f, 0.9f})
    CHECK(grey_byte(c, s) == std::lround(255.0 * srgb(c)));
  CHECK(grey_byte(0.18f, s) == 118);  // middle grey
  CHECK(grey_byte(0.5f, s) == 188);
}

TEST_CASE("display: exposure scales by 2^EV before the encoding", "[display]") {
  CHECK(grey_byte(0.25f, {DisplayEncoding::linear, 1.0, ToneMap::none}) == 127);   // 0.5
  CHECK(grey_byte(0.25f, {DisplayEncoding::linear, -2.0, ToneMap::none}) == 15);   // 0.0625
  CHECK(grey_byte(0.6f, {DisplayEncoding::linear, 1.0, ToneMap::none}) == 255);    // clipped
}

TEST_CASE("display: ACES (Narkowicz) and Khronos PBR Neutral tone maps", "[display]") {
  const DisplayTransform aces{DisplayEncoding::linear, 0.0, ToneMap::aces};
  // x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14) at x = 1: 2.54 / 3.16.
  CHECK(grey_byte(1.0f, aces) == std::uint8_t(std::floor(255.0 * 2.54 / 3.16)));
  CHECK(grey_byte(0.0f, aces) == 0);
  CHECK(grey_byte(1e6f, aces) == 255);
  const DisplayTransform neutral{DisplayEncoding::linear, 0.0, ToneMap::pbr_neutral};
  // Below the compression start, a colour whose smallest channel is at least 0.08 loses the 0.04
  // specular offset the curve assumes, and nothing else.
  std::uint8_t out[3];
  rt::encode_8bit(rt::Color(0.5f, 0.3f, 0.1f), neutral, out);
  CHECK(out[0] == std::uint8_t(std::floor(255.0 * (0.5 - 0.04))));
  CHECK(out[1] == std::uint8_t(std::floor(255.0 * (0.3 - 0.04))));
  CHECK(out[2] == std::uint8_t(std::floor(255.0 * (0.1 - 0.04))));
  // Grey 1: offset 0.04, peak 0.96 past 0.76, new peak 1 - 0.24^2 / (0.96 + 0.24 - 0.76).
  CHECK(grey_byte(1.0f, neutral) == std::uint8_t(std::floor(255.0 * (1.0 - 0.0576 / 0.44))));
  // Highlights are compressed below 1 and keep their order.
  CHECK(grey_byte(4.0f, neutral) < 255);
  CHECK(grey_byte(4.0f, neutral) > grey_byte(2.0f, neutral));
}

TEST_CASE("display: names round-trip, bad ones are errors", "[display]") {
  for (const DisplayTransform& d : {DisplayTransform{}, DisplayTransform{DisplayEncoding::srgb, 0.0, ToneMap::none},
                                    DisplayTransform{DisplayEncoding::srgb, -1.5, ToneMap::pbr_neutral},
                                    DisplayTransform{DisplayEncoding::linear, 2.0, ToneMap::aces}})
    CHECK(rt::parse_display_transform(rt::to_string(d)) == d);
  CHECK(rt::to_string(DisplayTransform{DisplayEncoding::srgb, 1.0, ToneMap::aces}) == "srgb, exposure +1 EV, tone map aces");
  CHECK_THROWS_AS(rt::parse_display_transform("gamma"), rt::InputError);
  CHECK_THROWS_AS(rt::parse_display_transform("srgb, exposure x EV"), rt::InputError);
  CHECK_THROWS_AS(rt::parse_tonemap("reinhard"), rt::InputError);
}

TEST_CASE("display: glTF and OBJ default to sRGB, .test and native scenes to linear, and the native 'display' key", "[display]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  CHECK(rt::load_scene(dir / "t.obj").settings.display.encoding == DisplayEncoding::srgb);
  rt_test::write_file(dir / "t.test", "size 8 8\ncamera 0 0 5 0 0 0 0 1 0 45\nsphere 0 0 0 1\n");
  CHECK(rt::load_scene(dir / "t.test").settings.display == DisplayTransform{});
  CHECK(rt::parse_scene_json(rt_test::small_json_scene(), "s.json").settings.display == DisplayTransform{});
  const rt::Scene srgb_scene = rt::parse_scene_json(rt_test::small_json_scene(R"("display": "srgb",)"), "s.json");
  CHECK(srgb_scene.settings.display.encoding == DisplayEncoding::srgb);
  const rt::Scene full = rt::parse_scene_json(
      rt_test::small_json_scene(R"("display": { "encoding": "srgb", "exposure": -1, "tonemap": "pbr-neutral" },)"), "s.json");
  CHECK(full.settings.display == DisplayTransform{DisplayEncoding::srgb, -1.0, ToneMap::pbr_neutral});
  const auto error = [](const std::string& extra) {
    try {
      rt::parse_scene_json(rt_test::small_json_scene(extra), "s.json");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK_THAT(error(R"("display": "gamma",)"), ContainsSubstring("/display: 'gamma' is not linear or srgb"));
  CHECK_THAT(error(R"("display": { "tonemap": "reinhard" },)"), ContainsSubstring("/display/tonemap: 'reinhard'"));
  CHECK_THAT(error(R"("display": { "exposure": 100 },)"), ContainsSubstring("/display/exposure"));
  CHECK_THAT(error(R"("display": 5,)"), ContainsSubstring("/display"));
  CHECK_THAT(error(R"("display": { "encoding": [1] },)"), ContainsSubstring("/display/encoding"));
  CHECK_THAT(error(R"("display": { "gamma": 2.2 },)"), ContainsSubstring("gamma"));
}

TEST_CASE("display: rt render applies --display, --exposure and --tonemap to 8-bit files and records them in EXR",
          "[display][cli]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "s.json", rt_test::small_json_scene());
  REQUIRE(rt_test::run_rt_in(dir, "render s.json -q -o linear.ppm").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render s.json -q -o srgb.ppm --display srgb").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render s.json -q -o float.exr --display srgb --exposure 1 --tonemap aces").status == 0);
  const rt::Image linear = rt::read_image(dir / "linear.ppm"), encoded = rt::read_image(dir / "srgb.ppm");
  rt::ImageHeader header;
  const rt::Image exr = rt::read_image(dir / "float.exr", &header);
  // The PPMs are the EXR's linear floats through each transform.
  const std::vector<std::uint8_t> expect_linear = rt::to_rgb8(exr), expect_srgb = rt::to_rgb8(exr, {DisplayEncoding::srgb, 0.0, ToneMap::none});
  int linear_wrong = 0, srgb_wrong = 0, brighter = 0;
  for (std::size_t i = 0; i < exr.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      linear_wrong += std::lround(linear.pixels[i][c] * 255.0f) != expect_linear[3 * i + c];
      srgb_wrong += std::lround(encoded.pixels[i][c] * 255.0f) != expect_srgb[3 * i + c];
      brighter += expect_srgb[3 * i + c] > expect_linear[3 * i + c];
    }
  CHECK(linear_wrong == 0);
  CHECK(srgb_wrong == 0);
  CHECK(brighter > 0);
  bool recorded = false;
  for (const auto& [name, value] : header.attributes)
    if (name == rt::kDisplayAttribute) recorded = value == "srgb, exposure +1 EV, tone map aces";
  CHECK(recorded);
  const rt_test::RtRun bad = rt_test::run_rt_in(dir, "render s.json -q -o x.png --tonemap reinhard");
  CHECK(bad.status == 2);
  CHECK_THAT(bad.err, ContainsSubstring("--tonemap"));
}

TEST_CASE("display: rt merge encodes the stitched tiles as the whole render does", "[display][cli]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "s.json", rt_test::small_json_scene(R"("display": { "encoding": "srgb", "tonemap": "pbr-neutral" },)"));
  REQUIRE(rt_test::run_rt_in(dir, "render s.json -q -o whole.png").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render s.json -q --tile 1/2 -o a.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render s.json -q --tile 2/2 -o b.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "merge a.exr b.exr -q -o merged.png").status == 0);
  CHECK(rt_test::read_file(dir / "merged.png") == rt_test::read_file(dir / "whole.png"));
}
