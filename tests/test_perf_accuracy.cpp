// rt-perf accuracy: the sweep plan, the CSV and Markdown output, and the error metrics on images
// whose errors are known by construction.

#include "catch.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "accuracy.h"
#include "metrics.h"
#include "test_util.h"

namespace {

rt::Image constant_image(int width, int height, float value) {
  rt::Image image(width, height);
  for (rt::Color& c : image.pixels) c = rt::Color(value);
  return image;
}

}  // namespace

TEST_CASE("compare_images: identical, constant offset, one pixel, clamping, size mismatch", "[perf]") {
  const rt::Image truth = constant_image(10, 10, 0.5f);
  SECTION("identical images: zero error, infinite PSNR") {
    const rt::perf::ImageError e = rt::perf::compare_images(truth, truth);
    CHECK(e.rmse == 0.0);
    CHECK(e.max_abs == 0.0);
    CHECK(e.pct_over_1_255 == 0.0);
    CHECK(std::isinf(e.psnr));
  }
  SECTION("every channel off by 0.1: RMSE 0.1, PSNR 20 dB, every pixel over 1/255") {
    const rt::perf::ImageError e = rt::perf::compare_images(constant_image(10, 10, 0.6f), truth);
    CHECK(e.rmse == Approx(0.1).epsilon(1e-5));
    CHECK(e.psnr == Approx(20.0).epsilon(1e-4));
    CHECK(e.max_abs == Approx(0.1).epsilon(1e-5));
    CHECK(e.pct_over_1_255 == Approx(100.0));
  }
  SECTION("one pixel of 100 off by 2/255 in one channel, another by half a step") {
    rt::Image image = truth;
    image.at(3, 4).g += 2.0f / 255.0f;
    image.at(7, 1).r += 0.5f / 255.0f;
    const rt::perf::ImageError e = rt::perf::compare_images(image, truth);
    CHECK(e.pct_over_1_255 == Approx(1.0));
    CHECK(e.max_abs == Approx(2.0 / 255.0).epsilon(1e-4));
    // RMSE over 300 channel values: sqrt(((2/255)^2 + (0.5/255)^2) / 300).
    CHECK(e.rmse == Approx(std::sqrt((4.0 + 0.25) / (255.0 * 255.0) / 300.0)).epsilon(1e-4));
  }
  SECTION("values are clamped to [0, 1] first, as the 8-bit output is") {
    const rt::perf::ImageError e = rt::perf::compare_images(constant_image(10, 10, 3.0f), constant_image(10, 10, 1.0f));
    CHECK(e.rmse == 0.0);
  }
  SECTION("different sizes are an error") {
    CHECK_THROWS_AS(rt::perf::compare_images(constant_image(4, 4, 0.0f), truth), std::invalid_argument);
  }
}

TEST_CASE("plan_sweep: one knob at a time, everything else at the defaults", "[perf]") {
  const auto points = rt::perf::plan_sweep(rt::perf::knob_names(), 5, true, true);
  const rt::perf::RenderConfig base = rt::perf::default_config(5);
  int defaults = 0;
  for (const auto& p : points) {
    INFO(p.knob << " = " << p.value);
    defaults += p.is_default;
    CHECK(p.truth == (p.knob == "spp"                                            ? "spp"
                      : p.knob == "light_samples" || p.knob == "light_sampling" ? "light"
                                                                                 : "1spp"));
    // Exactly one setting differs from the defaults, the knob's own (or none at its default value).
    int differing = (p.config.spp != base.spp) + (p.config.max_depth != base.max_depth) +
                    (p.config.sphere_tessellation != base.sphere_tessellation) +
                    (p.config.accel.embree_robust != base.accel.embree_robust) +
                    (p.config.accel.embree_quality != base.accel.embree_quality) +
                    (p.config.accel.embree_kernel != base.accel.embree_kernel) +
                    (rt::to_string(p.config.ray_offset) != rt::to_string(base.ray_offset)) +
                    (p.config.effects.min_throughput != base.effects.min_throughput) +
                    (p.config.effects.min_light_contribution != base.effects.min_light_contribution) +
                    (p.config.effects.light_samples != base.effects.light_samples) +
                    (p.config.effects.light_sampling != base.effects.light_sampling);
    CHECK(differing == (p.is_default ? 0 : 1));
  }
  CHECK(defaults == int(rt::perf::knob_names().size()));  // each knob's sweep contains the default once
  const auto count = [&](const std::string& knob) {
    return std::count_if(points.begin(), points.end(), [&](const auto& p) { return p.knob == knob; });
  };
  CHECK(count("spp") == 4);
  CHECK(count("max_depth") == 9);
  CHECK(count("sphere_tessellation") == 7);
  CHECK(count("ray_offset") == 6);
  CHECK(count("light_samples") == 5);
  CHECK(count("light_sampling") == 3);
  CHECK(rt::perf::plan_sweep({"sphere_tessellation"}, 5, false, false).empty());  // no spheres, nothing to sweep
  CHECK(rt::perf::plan_sweep({"light_samples", "light_sampling"}, 5, false, false).empty());  // no emitters
  CHECK(rt::perf::plan_sweep({"max_depth"}, 12, false, false).size() == 10);      // 0..8 and the scene's own 12
  CHECK_THROWS_AS(rt::perf::plan_sweep({"spp", "colour"}, 5, false, false), std::invalid_argument);

  const rt::perf::RenderConfig truth = rt::perf::truth_config(5, 10, 256, 64);
  CHECK(truth.spp == 256);
  CHECK(truth.effects.light_samples == 64);
  CHECK(truth.max_depth == 10);
  CHECK(truth.accel.embree_kernel == rt::EmbreeKernel::exact);
  CHECK(truth.sphere_tessellation == 0);
}

TEST_CASE("accuracy CSV and Markdown rows carry every column", "[perf]") {
  rt::perf::Measurement m;
  m.point = rt::perf::plan_sweep({"ray_offset"}, 5, false, false).front();
  m.time_median = 0.5;
  m.time_min = 0.25;
  m.time_max = 0.75;
  m.rays = 1234;
  m.error.rmse = 0.01;
  m.error.psnr = 40.0;
  m.error.max_abs = 0.2;
  m.error.pct_over_1_255 = 3.5;
  const std::string header = rt::perf::csv_header();
  for (const char* column : {"knob", "value", "time_s_median", "time_s_min", "time_s_max", "rays", "rmse", "psnr",
                             "max_abs", "pct_over_1_255"})
    CHECK_THAT(header, Catch::Matchers::ContainsSubstring(column));
  const std::string row = rt::perf::csv_row(m);
  CHECK(std::count(row.begin(), row.end(), ',') == std::count(header.begin(), header.end(), ','));
  CHECK_THAT(row, Catch::Matchers::StartsWith("ray_offset,fixed:1e-2,0,1spp,0.500000,0.250000,0.750000,"));
  CHECK_THAT(row, Catch::Matchers::ContainsSubstring(",1234,0.01,40.0000,0.2,3.5000"));
  const std::string table = rt::perf::markdown_table({m, m});
  CHECK(std::count(table.begin(), table.end(), '\n') == 4);  // header, rule, two rows
}

TEST_CASE("fit_spp_slope recovers a power law from the points the truth does not bias", "[perf]") {
  std::vector<rt::perf::Measurement> points;
  for (const rt::perf::SweepPoint& point : rt::perf::plan_sweep({"spp", "max_depth"}, 5, false, false)) {
    rt::perf::Measurement m;
    m.point = point;
    // RMSE = 0.02 spp^-0.75 on the spp points; the max_depth points must be ignored.
    m.error.rmse = point.knob == "spp" ? 0.02 * std::pow(double(point.config.spp), -0.75) : 1.0;
    points.push_back(m);
  }
  // spp 64 (with a 256-spp truth) is left out: make it an outlier to prove it.
  for (rt::perf::Measurement& m : points)
    if (m.point.knob == "spp" && m.point.config.spp == 64) m.error.rmse = 1e-9;
  REQUIRE(rt::perf::fit_spp_slope(points, 256).has_value());
  CHECK(*rt::perf::fit_spp_slope(points, 256) == Approx(-0.75).epsilon(1e-12));
  // A 16-spp truth leaves only spp 1: no fit.
  CHECK_FALSE(rt::perf::fit_spp_slope(points, 16).has_value());
  // An exact match (RMSE 0) cannot go on a log scale and is skipped.
  for (rt::perf::Measurement& m : points)
    if (m.point.knob == "spp" && m.point.config.spp == 4) m.error.rmse = 0.0;
  CHECK(*rt::perf::fit_spp_slope(points, 256) == Approx(-0.75).epsilon(1e-12));
}

TEST_CASE("rt-perf accuracy writes the CSV, the table and the truth, bad arguments are usage errors", "[perf]") {
  rt_test::TempDir dir;
  const rt_test::RtRun run = rt_test::run_in(
      dir, RT_PERF_EXECUTABLE,
      "accuracy --out result --width 32 --runs 1 --truth-spp 128 --knobs max_depth,ray_offset --no-plots");
  INFO("stderr: " << run.err);
  REQUIRE(run.status == 0);
  const std::string csv = rt_test::read_file(dir.path() / "result" / "accuracy.csv");
  CHECK(std::count(csv.begin(), csv.end(), '\n') == 1 + 9 + 6);  // header, depths 0..8, six offsets
  CHECK_THAT(csv, Catch::Matchers::StartsWith(rt::perf::csv_header()));
  CHECK(std::filesystem::exists(dir.path() / "result" / "accuracy.md"));
  CHECK(std::filesystem::exists(dir.path() / "result" / "truth.exr"));
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("| max_depth | 5 (default) |"));

  CHECK(rt_test::run_in(dir, RT_PERF_EXECUTABLE, "accuracy --out x --knobs colour").status == 2);
  CHECK(rt_test::run_in(dir, RT_PERF_EXECUTABLE, "accuracy").status == 2);  // --out is required
  const rt_test::RtRun missing = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "accuracy missing.json --out x");
  CHECK(missing.status == 1);
  CHECK_THAT(missing.err, Catch::Matchers::ContainsSubstring("missing.json"));
}
