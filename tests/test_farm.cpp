// Rendering an image in parts and stitching it back (the render farm, docs/render-farm.md):
// tile_region's cut, regions that are bit-identical to the whole render, rt merge's checks,
// batches on one Embree device, and the scene fingerprint that ties the parts together.

#include "catch.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "rt/accel/accel.h"
#include "rt/accel/embree_accel.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/render/fingerprint.h"
#include "rt/render/region.h"
#include "rt/render/render.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

rt::RenderResult render(const rt::Scene& scene, const rt::RenderOptions& options) {
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const std::unique_ptr<rt::Accel> accel = rt::build_accel(rt::AccelKind::embree, flat);
  return rt::render_image(scene, flat, *accel, options);
}

// Sizes that are odd, prime or smaller than the render's 16-pixel tiles.
rt::Scene odd_sized_default_scene(int width, int height) {
  rt::Scene scene = rt::make_default_scene();
  scene.settings.width = width;
  scene.settings.height = height;
  return scene;
}

std::string scene_dir() { return (fs::path(RT_SOURCE_DIR) / "scenes").string(); }

}  // namespace

TEST_CASE("tile_region cuts the image into N bands that cover it exactly once", "[farm]") {
  for (const auto& [width, height] : {std::pair{640, 480}, {61, 37}, {1, 1}, {7, 1000}, {65536, 65536}}) {
    for (const int n : {1, 2, 3, 5, 16, 37, 256}) {
      if (n > height) continue;
      INFO(width << "x" << height << " in " << n << " tiles");
      int next_row = 0, smallest = height, largest = 0;
      for (int k = 1; k <= n; ++k) {
        const rt::PixelRegion tile = rt::tile_region(k, n, width, height);
        CHECK(tile.x0 == 0);
        CHECK(tile.x1 == width);
        CHECK(tile.y0 == next_row);  // no gap, no overlap with the previous band
        CHECK(!tile.empty());
        next_row = tile.y1;
        smallest = std::min(smallest, tile.height());
        largest = std::max(largest, tile.height());
      }
      CHECK(next_row == height);
      CHECK(largest - smallest <= 1);
    }
  }
}

TEST_CASE("a region's pixels equal the whole render's, bit for bit, whatever the threads and tiles", "[farm]") {
  const rt::Scene scene = odd_sized_default_scene(67, 45);
  for (const int spp : {1, 3}) {
    rt::RenderOptions whole_options;
    whole_options.samples_per_pixel = spp;
    whole_options.threads = 2;
    const rt::RenderResult whole = render(scene, whole_options);
    for (const rt::PixelRegion& region :
         {rt::PixelRegion{0, 0, 67, 45}, {13, 7, 14, 8}, {5, 11, 66, 44}, {0, 17, 67, 18}, {31, 0, 37, 45}}) {
      for (const int threads : {1, 2}) {
        INFO("spp " << spp << ", region " << rt::to_string(region) << ", " << threads << " thread(s)");
        rt::RenderOptions options = whole_options;
        options.threads = threads;
        options.tile_size = threads == 1 ? 5 : 16;
        options.region = region;
        const rt::RenderResult part = render(scene, options);
        CHECK(part.region == region);
        REQUIRE(part.image.width == region.width());
        REQUIRE(part.image.height == region.height());
        std::size_t differing = 0;
        for (int y = region.y0; y < region.y1; ++y)
          for (int x = region.x0; x < region.x1; ++x)
            differing += part.image.at(x - region.x0, y - region.y0) != whole.image.at(x, y);
        CHECK(differing == 0);
      }
    }
  }
  rt::RenderOptions outside;
  outside.region = rt::PixelRegion{60, 40, 68, 45};
  CHECK_THROWS_WITH(render(scene, outside), Catch::Matchers::ContainsSubstring("the region 60 40 68 45 (x0 y0 x1 y1) is empty or outside the 67x45 image"));
}

TEST_CASE("rt render --tile K/N then rt merge gives the whole render's file byte for byte", "[farm][cli]") {
  rt_test::TempDir dir;
  const std::string scene = scene_dir() + "/hall-of-mirrors.json";
  // 61x37 in 5 tiles: 37 rows do not divide by 5 (bands of 7 and 8 rows); 3 spp jitters each pixel.
  const std::string common = "--width 61 --height 37 --spp 3 -q '" + scene + "'";
  REQUIRE(rt_test::run_rt_in(dir, "render -o whole.png " + common).status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render -o whole.exr " + common).status == 0);
  std::string tiles;
  for (int k = 5; k >= 1; --k) {  // any order
    const rt_test::RtRun run = rt_test::run_rt_in(dir, "render --tile " + std::to_string(k) + "/5 " + common);
    INFO(run.err);
    REQUIRE(run.status == 0);
    tiles += " hall-of-mirrors.tile-" + std::to_string(k) + "-of-5.exr";
  }
  const rt_test::RtRun merged = rt_test::run_rt_in(dir, "merge" + tiles + " -o merged.png");
  INFO(merged.err);
  REQUIRE(merged.status == 0);
  CHECK_THAT(merged.out, Catch::Matchers::ContainsSubstring("merged.png: 61x37 from 5 region file(s)"));
  CHECK(rt_test::read_file(dir / "merged.png") == rt_test::read_file(dir / "whole.png"));
  // EXR output: the same float pixels (the files differ in their DateTime attribute).
  REQUIRE(rt_test::run_rt_in(dir, "merge -q" + tiles + " -o merged.exr").status == 0);
  CHECK(rt::read_image(dir / "merged.exr").pixels == rt::read_image(dir / "whole.exr").pixels);

  // A tile file says where it belongs and what rendered it.
  rt::ImageHeader header;
  const rt::Image tile = rt::read_image(dir / "hall-of-mirrors.tile-2-of-5.exr", &header);
  CHECK(tile.width == 61);
  REQUIRE(header.data_window.has_value());
  CHECK(*header.data_window == rt::tile_region(2, 5, 61, 37));
  CHECK(header.full_width == 61);
  CHECK(header.full_height == 37);
  std::vector<std::string> names;
  for (const auto& [name, value] : header.attributes) names.push_back(name + "=" + value);
  CHECK_THAT(fmt::format("{}", fmt::join(names, " ")), Catch::Matchers::ContainsSubstring("rt:part=tile 2/5") &&
                                                           Catch::Matchers::ContainsSubstring("rt:settings=spp=3 accel=embree") &&
                                                           Catch::Matchers::ContainsSubstring("rt:scene="));
}

TEST_CASE("rt render --crop writes the region, in place for .exr and alone for .png", "[farm][cli]") {
  rt_test::TempDir dir;
  REQUIRE(rt_test::run_rt_in(dir, "render -q --width 50 --height 40 -o whole.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render -q --width 50 --height 40 --crop 7 9 31 40").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render -q --width 50 --height 40 --crop 7 9 31 40 -o crop.png").status == 0);
  const rt::Image whole = rt::read_image(dir / "whole.exr");
  rt::ImageHeader header;
  const rt::Image crop = rt::read_image(dir / "default.crop-7-9-31-40.exr", &header);
  REQUIRE(header.data_window == rt::PixelRegion{7, 9, 31, 40});
  const rt::Image crop_png = rt::read_image(dir / "crop.png");
  REQUIRE(crop_png.width == 24);
  REQUIRE(crop_png.height == 31);
  std::size_t differing = 0;
  for (int y = 9; y < 40; ++y)
    for (int x = 7; x < 31; ++x) differing += crop.at(x - 7, y - 9) != whole.at(x, y);
  CHECK(differing == 0);

  // Mistakes: outside the image; a tile written as PNG; K outside 1..N; more tiles than rows.
  const rt_test::RtRun outside = rt_test::run_rt_in(dir, "render -q --width 50 --height 40 --crop 0 0 51 40");
  CHECK(outside.status == 2);
  CHECK_THAT(outside.err, Catch::Matchers::ContainsSubstring("--crop 0 0 51 40 reaches outside the 50x40 image (X1 51 > width 50)"));
  const rt_test::RtRun png_tile = rt_test::run_rt_in(dir, "render -q --tile 1/2 -o tile.png");
  CHECK(png_tile.status == 2);
  CHECK_THAT(png_tile.err, Catch::Matchers::ContainsSubstring("--tile writes an OpenEXR region file for rt merge; 'tile.png' is not .exr"));
  for (const char* bad : {"0/4", "5/4", "2", "1/0", "a/b", "1/2x"}) {
    const rt_test::RtRun run = rt_test::run_rt_in(dir, std::string("render -q --tile ") + bad);
    INFO(bad << ": " << run.err);
    CHECK(run.status == 2);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("expected K/N with 1 <= K <= N"));
  }
  const rt_test::RtRun too_many = rt_test::run_rt_in(dir, "render -q --height 40 --tile 1/41");
  CHECK(too_many.status == 2);
  CHECK_THAT(too_many.err, Catch::Matchers::ContainsSubstring("--tile 1/41: the 40-row image cannot be cut into 41 tiles"));
  CHECK_FALSE(fs::exists(dir / "tile.png"));
}

TEST_CASE("rt merge refuses missing, overlapping, foreign and mismatched parts, naming them", "[farm][cli]") {
  rt_test::TempDir dir;
  const std::string common = " -q --width 40 --height 30 ";
  for (int k = 1; k <= 3; ++k)
    REQUIRE(rt_test::run_rt_in(dir, "render" + common + "--tile " + std::to_string(k) + "/3").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render" + common + "--tile 2/3 --spp 2 -o spp2.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render" + common + "--tile 2/3 --eye 0 1 9 -o moved.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render -q --width 40 --height 31 --tile 2/3 -o taller.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render" + common + "--crop 0 5 40 15 -o crop.exr").status == 0);
  REQUIRE(rt_test::run_rt_in(dir, "render" + common + "-o whole.png").status == 0);
  const std::string t1 = " default.tile-1-of-3.exr", t2 = " default.tile-2-of-3.exr", t3 = " default.tile-3-of-3.exr";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {t1 + t3, "leave 400 of the 40x30 image's pixels uncovered, the first at (0, 10) (missing tile 2 of 3)"},
      {t1, "leave 800 of the 40x30 image's pixels uncovered, the first at (0, 10) (missing tiles 2, 3 of 3)"},
      {t1 + t2 + t3 + " crop.exr", "crop.exr: overlaps default.tile-1-of-3.exr in pixels 0 5 40 10 (x0 y0 x1 y1)"},
      {t1 + t2 + t3 + t2, "default.tile-2-of-3.exr: given twice"},
      {t1 + " spp2.exr" + t3, "spp2.exr: rt:settings is 'spp=2 accel=embree"},
      {t1 + " moved.exr" + t3, "moved.exr: rt:scene is '"},
      {t1 + " taller.exr" + t3, "taller.exr: rt:scene is '"},  // the image size is part of the scene
      {t1 + " whole.png", "whole.png: not a region file (no rt:scene attribute)"},
      {t1 + " missing.exr", "missing.exr: cannot read image"},
  };
  for (const auto& [files, message] : cases) {
    const rt_test::RtRun run = rt_test::run_rt_in(dir, "merge" + files + " -o out.png");
    INFO("merge" << files << "\n" << run.err);
    CHECK(run.status == 1);
    CHECK_THAT(run.err, Catch::Matchers::StartsWith("rt: error: ") && Catch::Matchers::ContainsSubstring(message));
    CHECK_FALSE(fs::exists(dir / "out.png"));
  }
  CHECK(rt_test::run_rt_in(dir, "merge" + t1 + t2 + t3 + " -o out.png -q").status == 0);
  CHECK(rt_test::read_file(dir / "out.png") == rt_test::read_file(dir / "whole.png"));
}

TEST_CASE("rt render A B C: a batch on one Embree device, --outdir, --skip-existing, failures reported", "[farm][cli]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir / "broken.json", "{ \"camera\": ");
  const std::string scenes = " '" + scene_dir() + "/default.json' broken.json '" + scene_dir() + "/transforms.json' ";
  const rt_test::RtRun batch = rt_test::run_rt_in(dir, "render --width 32 --height 24 --outdir out" + scenes);
  INFO(batch.err);
  CHECK(batch.status == 1);  // one scene failed, the others were rendered
  CHECK_THAT(batch.err, Catch::Matchers::ContainsSubstring("rt: error: broken.json:") &&
                            Catch::Matchers::ContainsSubstring("rt: batch of 3 scenes in") &&
                            Catch::Matchers::ContainsSubstring(": 2 rendered, 0 skipped, 1 failed: broken.json"));
  rt_test::TempDir out_check;
  const std::vector<std::string> expected{"default.png", "transforms.png"};
  std::vector<std::string> written;
  for (const auto& entry : fs::directory_iterator(dir.path() / "out")) written.push_back(entry.path().filename());
  std::sort(written.begin(), written.end());
  CHECK(written == expected);
  // Each batch image equals the scene rendered alone.
  REQUIRE(rt_test::run_rt_in(dir, "render -q --width 32 --height 24 -o alone.png '" + scene_dir() + "/transforms.json'").status == 0);
  CHECK(rt_test::read_file(dir / "out/transforms.png") == rt_test::read_file(dir / "alone.png"));

  // Resuming: finished outputs are skipped, untouched.
  const auto before = fs::last_write_time(dir.path() / "out/default.png");
  rt_test::write_file(dir / "broken.json", rt_test::read_file(scene_dir() + "/default.json"));
  const rt_test::RtRun resumed = rt_test::run_rt_in(dir, "render --width 32 --height 24 --outdir out --skip-existing" + scenes);
  INFO(resumed.err);
  CHECK(resumed.status == 0);
  CHECK_THAT(resumed.err, Catch::Matchers::ContainsSubstring("out/default.png exists, skipped (--skip-existing)") &&
                              Catch::Matchers::ContainsSubstring("1 rendered, 2 skipped, 0 failed"));
  CHECK(fs::last_write_time(dir.path() / "out/default.png") == before);
  CHECK(fs::exists(dir.path() / "out/broken.png"));

  // Mistakes found before anything renders.
  const rt_test::RtRun one_output = rt_test::run_rt_in(dir, "render -o x.png" + scenes);
  CHECK(one_output.status == 2);
  CHECK_THAT(one_output.err, Catch::Matchers::ContainsSubstring("-o names one output file; with several scenes use --outdir DIR"));
  const rt_test::RtRun same_name =
      rt_test::run_rt_in(dir, "render --outdir same '" + scene_dir() + "/default.json' default.json");
  CHECK(same_name.status == 2);
  CHECK_THAT(same_name.err, Catch::Matchers::ContainsSubstring("would both write same/default.png"));
  CHECK_FALSE(fs::exists(dir / "same/default.png"));
}

TEST_CASE("accels built one after another on a shared Embree device answer like their own", "[farm]") {
  const rt::Scene scene = rt::make_default_scene();
  const rt::FlatScene flat = rt::flatten_scene(scene);
  rt::AccelOptions shared;
  shared.embree_device = std::make_shared<rt::EmbreeDevice>();
  const rt::EmbreeAccel own(flat, {});
  for (int round = 0; round < 3; ++round) {
    const rt::EmbreeAccel accel(flat, shared);
    CHECK(accel.memory_bytes() > 0);
    rt::RenderOptions options;
    options.threads = 1;
    CHECK(rt::render_image(scene, flat, accel, options).image.pixels ==
          rt::render_image(scene, flat, own, options).image.pixels);
  }
}

TEST_CASE("scene_fingerprint follows the pixel-deciding values, not the file", "[farm]") {
  rt_test::TempDir dir;
  const std::string text = rt_test::read_file(scene_dir() + "/default.json");
  rt_test::write_file(dir / "a.json", text);
  rt_test::write_file(dir / "b.json", "\n\n" + text + "\n  ");  // same scene, other name and layout
  const auto fingerprint = [](const rt::Scene& scene) { return rt::scene_fingerprint(scene, rt::flatten_scene(scene)); };
  const rt::Scene a = rt::load_scene(dir / "a.json");
  const std::string base = fingerprint(a);
  CHECK(base.size() == 16);
  CHECK(fingerprint(rt::load_scene(dir / "b.json")) == base);
  CHECK(fingerprint(rt::load_scene(dir / "a.json")) == base);
  rt::Scene changed = a;
  changed.lights.at(0).color.g += 1e-6f;
  CHECK(fingerprint(changed) != base);
  changed = a;
  changed.camera.eye.x = std::nextafter(changed.camera.eye.x, 1e9);
  CHECK(fingerprint(changed) != base);
  changed = a;
  changed.settings.height += 1;
  CHECK(fingerprint(changed) != base);
  changed = a;
  changed.materials.at(0).reflective = changed.materials.at(0).specular;  // same values, but set explicitly
  CHECK(fingerprint(changed) != base);
  changed = a;
  changed.settings.output = "elsewhere.png";
  changed.notices.push_back("a notice");
  CHECK(fingerprint(changed) == base);
}
