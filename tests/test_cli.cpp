// The `rt` executable, run as a user would: exit codes, files written, messages on stderr.

#include "catch.h"

#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

using rt_test::read_file;
using rt_test::write_file;

using Run = rt_test::RtRun;

std::string quoted(const std::string& s) { return "'" + s + "'"; }

Run run_rt(const rt_test::TempDir& cwd, const std::string& args) { return rt_test::run_rt_in(cwd, args); }

std::size_t line_count(const std::string& text) { return std::count(text.begin(), text.end(), '\n'); }

// A small valid scene; the bad-input cases below each break one thing in it.
const std::string kGoodScene = rt_test::small_json_scene();

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("test scene template lacks '" + from + "'");
  return text.replace(at, from.size(), to);
}

}  // namespace

TEST_CASE("rt render without a scene writes default.png in the working directory", "[cli]") {
  rt_test::TempDir dir;
  const Run run = run_rt(dir, "render --quiet");
  INFO("stderr: " << run.err);
  REQUIRE(run.status == 0);
  CHECK(run.err.empty());
  CHECK(run.out.empty());  // --quiet
  REQUIRE(dir.entries() == std::vector<std::string>{"default.png"});
  const rt::Scene scene = rt::make_default_scene();
  const rt::Image image = rt::read_image(dir / "default.png");
  CHECK(image.width == scene.settings.width);
  CHECK(image.height == scene.settings.height);
}

TEST_CASE("rt render --stats writes the documented JSON", "[cli]") {
  rt_test::TempDir dir;
  const Run run = run_rt(dir, "render --width 80 --height 60 --stats stats.json -o small.png");
  INFO("stderr: " << run.err);
  REQUIRE(run.status == 0);
  CHECK(line_count(run.out) == 1);  // the summary line without --quiet
  REQUIRE(dir.entries() == std::vector<std::string>{"small.png", "stats.json"});

  const nlohmann::json stats = nlohmann::json::parse(read_file(dir.path() / "stats.json"));
  CHECK(stats.at("image").at("width") == 80);
  CHECK(stats.at("image").at("height") == 60);
  const rt::Scene scene = rt::make_default_scene();
  CHECK(stats.at("triangles") == rt::flatten_scene(scene).triangle_count());
  CHECK(stats.at("lights") == scene.lights.size());
  const nlohmann::json& rays = stats.at("rays");
  CHECK(rays.at("camera") == 80 * 60);
  // The default scene has lights and a mirror, so both kinds of secondary ray occur.
  CHECK(rays.at("shadow").get<std::uint64_t>() > 0);
  CHECK(rays.at("reflection").get<std::uint64_t>() > 0);
  double sum = 0.0;
  for (const char* phase : {"load", "flatten", "build", "render", "write", "total"}) {
    INFO("time_s." << phase);
    REQUIRE(stats.at("time_s").at(phase).is_number());
    const double seconds = stats.at("time_s").at(phase).get<double>();
    CHECK(seconds >= 0.0);
    if (std::string(phase) != "total") sum += seconds;
  }
  CHECK(stats.at("time_s").at("total").get<double>() >= stats.at("time_s").at("render").get<double>());
  CHECK(stats.at("time_s").at("total").get<double>() >= sum - 1e-6);  // phases are disjoint parts of it
  // The first finished tile comes after loading, flattening and building, before the render ends.
  const nlohmann::json& time = stats.at("time_s");
  const double first_pixel = time.at("first_pixel").get<double>();
  CHECK(first_pixel >= time.at("load").get<double>() + time.at("flatten").get<double>() + time.at("build").get<double>());
  CHECK(first_pixel <= time.at("total").get<double>() - time.at("write").get<double>() + 1e-6);

  // The effects plan and the ray budget: per-light shadow rays and per-depth reflections add up to
  // the totals, shares of render time to about 1, skipped rays are listed per rule.
  const nlohmann::json& effects = stats.at("effects");
  CHECK(effects.at("prune") == true);
  CHECK(effects.at("lights").size() == scene.lights.size());
  CHECK(effects.at("useful_depth") == scene.settings.max_depth);
  const nlohmann::json& budget = stats.at("ray_budget");
  CHECK(budget.at("camera").at("rays") == 80 * 60);
  std::uint64_t shadow = 0, reflection = 0;
  double shares = budget.at("camera").at("share").get<double>() + budget.at("shading").at("share").get<double>();
  for (const auto& light : budget.at("shadow")) {
    shadow += light.at("rays").get<std::uint64_t>();
    shares += light.at("share").get<double>();
  }
  for (const auto& depth : budget.at("reflection")) {
    reflection += depth.at("rays").get<std::uint64_t>();
    shares += depth.at("share").get<double>();
  }
  CHECK(shadow == rays.at("shadow").get<std::uint64_t>());
  CHECK(reflection == rays.at("reflection").get<std::uint64_t>());
  CHECK(shares == Approx(1.0).margin(1e-9));
  CHECK(budget.at("skipped").at("black_reflection").get<std::uint64_t>() > 0);
  CHECK(budget.at("traced") == rays.at("total"));

  const rt::Image image = rt::read_image(dir / "small.png");
  CHECK(image.width == 80);
  CHECK(image.height == 60);
}

TEST_CASE("rt render --explain prints the plan and the budget, --no-prune traces more, same image", "[cli]") {
  rt_test::TempDir dir;
  const Run pruned = run_rt(dir, "render --quiet --explain --width 80 --height 60 -o pruned.png --stats pruned.json");
  INFO("stderr: " << pruned.err);
  REQUIRE(pruned.status == 0);
  for (const char* text : {"effects plan", "light 0", "reflections on", "ray budget", "camera", "shadow light 1",
                           "reflection depth 1", "skipped black_reflection"})
    CHECK_THAT(pruned.out, Catch::Matchers::ContainsSubstring(text));
  const Run full = run_rt(dir, "render --quiet --no-prune --width 80 --height 60 -o full.png --stats full.json");
  REQUIRE(full.status == 0);
  CHECK(read_file(dir.path() / "pruned.png") == read_file(dir.path() / "full.png"));
  const auto traced = [&](const char* name) {
    return nlohmann::json::parse(read_file(dir.path() / name)).at("rays").at("total").get<std::uint64_t>();
  };
  CHECK(traced("pruned.json") < traced("full.json"));

  const Run sampled = run_rt(dir, "render --quiet --spp 4 --width 80 --height 60 -o spp.png --stats spp.json");
  REQUIRE(sampled.status == 0);
  const nlohmann::json spp_stats = nlohmann::json::parse(read_file(dir.path() / "spp.json"));
  CHECK(spp_stats.at("samples_per_pixel") == 4);
  CHECK(spp_stats.at("rays").at("camera") == 4 * 80 * 60);
  CHECK(run_rt(dir, "render --quiet --spp 0 -o never.png").status == 2);

  const Run bad = run_rt(dir, "render --quiet --min-throughput 2 -o never.png");
  CHECK(bad.status == 2);
  CHECK_THAT(bad.err, Catch::Matchers::ContainsSubstring("--min-throughput"));
  CHECK_FALSE(fs::exists(dir.path() / "never.png"));
}

TEST_CASE("rt info describes a scene", "[cli]") {
  rt_test::TempDir dir;
  const Run builtin = run_rt(dir, "info");
  CHECK(builtin.status == 0);
  CHECK(builtin.err.empty());
  CHECK(line_count(builtin.out) > 3);
  const Run file = run_rt(dir, "info " + quoted(std::string(RT_SOURCE_DIR) + "/scenes/default.json"));
  CHECK(file.status == 0);
  CHECK_THAT(file.out, Catch::Matchers::ContainsSubstring("default.json"));
  CHECK_THAT(file.out, Catch::Matchers::ContainsSubstring("effects") && Catch::Matchers::ContainsSubstring("reflections on"));
  CHECK(dir.entries().empty());
}

TEST_CASE("rt render of a valid scene file writes <stem>.png", "[cli]") {
  rt_test::TempDir dir;
  write_file(dir.path() / "good.json", kGoodScene);
  const Run run = run_rt(dir, "render --quiet good.json");
  INFO("stderr: " << run.err);
  CHECK(run.status == 0);
  CHECK(dir.entries() == std::vector<std::string>{"good.json", "good.png"});
}

TEST_CASE("rt render rejects bad input with exit 1 and one line naming the file", "[cli]") {
  struct Case {
    const char* name;
    std::string content;
    std::vector<std::string> expected;  // substrings of the message, besides the file name
  };
  const std::string good = kGoodScene;
  const std::vector<Case> cases = {
      // Line 3, column 13 is the '@'.
      {"syntax error", "{\n  \"image\": { \"width\": 64 },\n  \"camera\": @\n}\n", {"bad.json:3:13"}},
      {"unknown key", replace(good, "\"fovy\": 45", "\"fovy\": 45, \"fov\": 45"), {"/camera/fov"}},
      {"unknown geometry type", replace(good, "\"type\": \"sphere\"", "\"type\": \"torus\""),
       {"/nodes/0/models/0/geometry/type", "torus"}},
      {"string where a number belongs", replace(good, "\"fovy\": 45", "\"fovy\": \"45\""), {"/camera/fovy"}},
      // The parser itself rejects the literal, so the message points at line 3, column 29.
      {"number overflowing to infinity", replace(good, "\"eye\": [0, 0, 5]", "\"eye\": [0, 0, 1e999]"),
       {"bad.json:3:29", "1e999", "finite"}},
      {"negative image width", replace(good, "\"width\": 32", "\"width\": -5"), {"/image/width"}},
      {"up parallel to the view direction", replace(good, "\"up\": [0, 1, 0]", "\"up\": [0, 0, -2]"),
       {"/camera/up"}},
      {"fovy 0", replace(good, "\"fovy\": 45", "\"fovy\": 0"), {"/camera/fovy"}},
      {"fovy 180", replace(good, "\"fovy\": 45", "\"fovy\": 180"), {"/camera/fovy"}},
  };
  for (const Case& c : cases) {
    DYNAMIC_SECTION(c.name) {
      rt_test::TempDir dir;
      write_file(dir.path() / "bad.json", c.content);
      const Run run = run_rt(dir, "render bad.json");
      INFO("stderr: " << run.err);
      CHECK(run.status == 1);
      CHECK(line_count(run.err) == 1);
      CHECK(run.err.back() == '\n');
      CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("bad.json"));
      for (const std::string& part : c.expected) CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring(part));
      CHECK(dir.entries() == std::vector<std::string>{"bad.json"});  // no bad.png
    }
  }
  SECTION("missing scene file") {
    rt_test::TempDir dir;
    const Run run = run_rt(dir, "render nothere.json -o out.png");
    INFO("stderr: " << run.err);
    CHECK(run.status == 1);
    CHECK(line_count(run.err) == 1);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("nothere.json"));
    CHECK(dir.entries().empty());
  }
}

// Every output argument is checked before rendering, so a bad --stats path leaves no image behind.
TEST_CASE("rt render with an unwritable --stats path writes no image", "[cli]") {
  rt_test::TempDir dir;
  const Run run = run_rt(dir, "render --width 32 --height 24 --stats missing/stats.json");
  INFO("stderr: " << run.err);
  CHECK(run.status == 1);
  CHECK(line_count(run.err) == 1);
  CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("missing/stats.json"));
  CHECK(dir.entries().empty());
}

TEST_CASE("rt usage errors exit with status 2", "[cli]") {
  for (const char* args : {"render --bogus", "render --accel bogus", "render --width -5", "render --height 0",
                           "frobnicate", ""}) {
    DYNAMIC_SECTION("rt " << args) {
      rt_test::TempDir dir;
      const Run run = run_rt(dir, args);
      INFO("stderr: " << run.err);
      CHECK(run.status == 2);
      CHECK_FALSE(run.err.empty());
      CHECK(dir.entries().empty());
    }
  }
}

TEST_CASE("every scene in scenes/ loads and renders", "[cli]") {
  std::vector<fs::path> scenes;
  for (const auto& entry : fs::directory_iterator(fs::path(RT_SOURCE_DIR) / "scenes"))
    if (entry.path().extension() == ".json") scenes.push_back(entry.path());
  std::sort(scenes.begin(), scenes.end());
  REQUIRE_FALSE(scenes.empty());
  for (const fs::path& scene : scenes) {
    DYNAMIC_SECTION(scene.filename().string()) {
      rt_test::TempDir dir;
      const Run run = run_rt(dir, "render --quiet --width 64 --height 48 -o out.png " + quoted(scene.string()));
      INFO("stderr: " << run.err);
      CHECK(run.status == 0);
      REQUIRE(dir.entries() == std::vector<std::string>{"out.png"});
      const rt::Image image = rt::read_image(dir / "out.png");
      CHECK(image.width == 64);
      CHECK(image.height == 48);
      CHECK(run_rt(dir, "info " + quoted(scene.string())).status == 0);
    }
  }
}

TEST_CASE("rt writes PNG and PPM without OpenImageIO and says clearly when its module is missing", "[cli]") {
  // The OpenImageIO module is loaded only for formats rt does not encode itself: with the module
  // pointed at a missing file, PNG and PPM still work and EXR fails with one clear line.
  rt_test::TempDir dir;
  write_file(dir / "scene.json", kGoodScene);
  const std::string missing = "RT_OIIO_MODULE=" + quoted(dir / "absent/rt-oiio.so") + " ";
  const auto run_without_module = [&](const std::string& args) {
    return rt_test::run_in(dir, "/usr/bin/env", missing + quoted(RT_EXECUTABLE) + " " + args);
  };
  for (const char* name : {"out.png", "out.ppm"}) {
    const Run run = run_without_module(std::string("render scene.json --quiet -o ") + name);
    INFO(name << " stderr: " << run.err);
    CHECK(run.status == 0);
    CHECK(fs::exists(dir / name));
  }
  // Same pixels as the module's reader sees in a PNG written through the normal path.
  const Run png = run_rt(dir, "render scene.json --quiet -o again.png");
  REQUIRE(png.status == 0);
  CHECK(read_file(dir / "again.png") == read_file(dir / "out.png"));
  const rt::Image image = rt::read_image(dir / "out.png");
  const std::string ppm = read_file(dir / "out.ppm");
  const std::string header = "P6\n32 24\n255\n";
  REQUIRE(ppm.size() == header.size() + 32 * 24 * 3);
  CHECK(ppm.substr(0, header.size()) == header);
  bool same = true;
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      same = same && static_cast<unsigned char>(ppm[header.size() + 3 * i + c]) ==
                         static_cast<unsigned char>(std::lround(255.0f * image.pixels[i][c]));
  CHECK(same);

  const Run exr = run_without_module("render scene.json --quiet -o out.exr");
  CHECK(exr.status == 1);
  CHECK(line_count(exr.err) == 1);
  CHECK(exr.err.find("cannot load the OpenImageIO module rt-oiio.so") != std::string::npos);
  CHECK(exr.err.find("RT_OIIO_MODULE") != std::string::npos);
  CHECK_FALSE(fs::exists(dir / "out.exr"));
}
