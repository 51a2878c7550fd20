// The render loop (backend agreement, thread-count independence, pixel layout) and image IO.

#include "catch.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <sstream>

#include "rt/accel/accel.h"
#include "rt/core/error.h"
#include "rt/flatten/flatten.h"
#include "rt/io/image_io.h"
#include "rt/io/load_scene.h"
#include "rt/render/render.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

using rt_test::read_file;
using rt_test::write_file;

rt::RenderResult render(const rt::Scene& scene, rt::AccelKind kind, int threads, int tile_size = 16, int spp = 1) {
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const std::unique_ptr<rt::Accel> accel = rt::build_accel(kind, flat);
  rt::RenderOptions options;
  options.threads = threads;
  options.tile_size = tile_size;
  options.samples_per_pixel = spp;
  return rt::render_image(scene, flat, *accel, options);
}

// The built-in default scene at width x height pixels, flattened, with an Embree accel.
struct SmallDefaultScene {
  rt::Scene scene;
  rt::FlatScene flat;
  std::unique_ptr<rt::Accel> accel;

  SmallDefaultScene(int width, int height) : scene(rt::make_default_scene()) {
    scene.settings.width = width;
    scene.settings.height = height;
    flat = rt::flatten_scene(scene);
    accel = rt::build_accel(rt::AccelKind::embree, flat);
  }
};

}  // namespace

TEST_CASE("Embree and the reference render the default scene alike", "[render]") {
  // Full 640x480: the reference takes ~20 s on two cores, which the default suite affords.
  const rt::Scene scene = rt::make_default_scene();
  REQUIRE(scene.settings.width == 640);
  REQUIRE(scene.settings.height == 480);
  const rt::RenderResult embree = render(scene, rt::AccelKind::embree, 0);
  const rt::RenderResult reference = render(scene, rt::AccelKind::reference, 0);
  const std::vector<std::uint8_t> a = rt::to_rgb8(embree.image), b = rt::to_rgb8(reference.image);
  REQUIRE(a.size() == 640u * 480u * 3u);
  REQUIRE(b.size() == a.size());

  std::size_t differing = 0, identical = 0;
  for (std::size_t p = 0; p < a.size() / 3; ++p) {
    int worst = 0;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int(a[3 * p + c]) - int(b[3 * p + c])));
    if (worst > 1) ++differing;
    if (worst == 0) ++identical;
  }
  const std::size_t pixels = a.size() / 3;
  std::cout << "default scene, embree vs reference: " << differing << " of " << pixels
            << " pixels differ by more than 1/255, " << identical << " identical\n";
  CHECK(differing * 1000 <= pixels);  // at most 0.1 %
  CHECK(embree.rays.camera == pixels);
  CHECK(reference.rays.camera == pixels);
  // The scene is not trivially uniform: the comparison compares something.
  CHECK(std::count(a.begin(), a.end(), a[0]) < static_cast<long>(a.size() / 2));
}

TEST_CASE("rendering is independent of thread count and tile size", "[render]") {
  rt::Scene scene = rt::make_default_scene();
  scene.settings.width = 200;
  scene.settings.height = 150;
  const int spp = GENERATE(1, 4);
  INFO("spp " << spp);
  const rt::RenderResult one = render(scene, rt::AccelKind::embree, 1, 16, spp);
  const rt::RenderResult two = render(scene, rt::AccelKind::embree, 2, 16, spp);
  const rt::RenderResult odd_tiles = render(scene, rt::AccelKind::embree, 2, 7, spp);
  REQUIRE(one.image.pixels.size() == 200u * 150u);
  for (const rt::RenderResult* other : {&two, &odd_tiles}) {
    REQUIRE(other->image.pixels.size() == one.image.pixels.size());
    std::size_t different = 0;
    for (std::size_t i = 0; i < one.image.pixels.size(); ++i)
      if (std::memcmp(&one.image.pixels[i], &other->image.pixels[i], sizeof(rt::Color)) != 0) ++different;
    CHECK(different == 0);
    CHECK(rt::to_rgb8(one.image) == rt::to_rgb8(other->image));
    CHECK(other->rays.camera == one.rays.camera);
    CHECK(other->rays.shadow == one.rays.shadow);
    CHECK(other->rays.reflection == one.rays.reflection);
  }
  CHECK(one.rays.camera == 200u * 150u * unsigned(spp));
  CHECK(one.rays.shadow > 0);
  CHECK(one.rays.reflection > 0);
}

// One emissive triangle on black, nothing else: with one sample per pixel every pixel is 0 or 1;
// with N samples an edge pixel is the fraction k / N of its samples that hit, exactly (a box filter).
TEST_CASE("rendering with --spp N averages N stratified samples per pixel, --spp 1 is the pixel centre", "[render]") {
  rt::Scene scene = rt_test::make_scene(
      {{rt_test::make_flat_mesh({{rt::Vec3f(-1.3f, -0.9f, 0), rt::Vec3f(1.1f, -0.7f, 0), rt::Vec3f(0.1f, 1.2f, 0)}}), 0}});
  rt::Material glow;
  glow.emission = rt::Color(1.0f);
  scene.materials = {glow};
  scene.settings.width = 48;
  scene.settings.height = 36;
  scene.settings.max_depth = 0;
  const rt::RenderResult centre = render(scene, rt::AccelKind::embree, 2);
  const rt::RenderResult default_options = [&] {
    const rt::FlatScene flat = rt::flatten_scene(scene);
    return rt::render_image(scene, flat, *rt::build_accel(rt::AccelKind::embree, flat), rt::RenderOptions{});
  }();
  CHECK(std::memcmp(centre.image.pixels.data(), default_options.image.pixels.data(),
                    centre.image.pixels.size() * sizeof(rt::Color)) == 0);
  double coverage_1 = 0.0;
  for (const rt::Color& c : centre.image.pixels) {
    CHECK((c.r == 0.0f || c.r == 1.0f));
    coverage_1 += c.r;
  }
  for (const int spp : {4, 16, 6}) {
    INFO("spp " << spp);
    const rt::RenderResult sampled = render(scene, rt::AccelKind::embree, 2, 16, spp);
    CHECK(sampled.rays.camera == 48u * 36u * unsigned(spp));
    std::size_t partial = 0;
    double coverage = 0.0;
    for (const rt::Color& c : sampled.image.pixels) {
      const double k = double(c.r) * spp;
      CHECK(k == Approx(std::round(k)).margin(1e-4));  // a whole number of the samples hit
      partial += c.r > 0.0f && c.r < 1.0f;
      coverage += c.r;
    }
    CHECK(partial > 0);  // edges are anti-aliased
    // Both estimate the triangle's area in pixels; they agree to within the edge pixels' count.
    CHECK(std::abs(coverage - coverage_1) < double(partial));
  }
}

TEST_CASE("render reports progress once per tile, reaching 1", "[render]") {
  const SmallDefaultScene small(50, 30);
  const rt::Scene& scene = small.scene;
  const rt::FlatScene& flat = small.flat;
  const rt::Accel* const accel = small.accel.get();
  rt::RenderOptions options;
  options.threads = 2;
  options.tile_size = 16;  // 4 x 2 tiles
  std::vector<double> reported;
  options.on_progress = [&](double fraction) { reported.push_back(fraction); };
  rt::render_image(scene, flat, *accel, options);
  REQUIRE(reported.size() == 8);
  for (double fraction : reported) {
    CHECK(fraction > 0.0);
    CHECK(fraction <= 1.0);
  }
  CHECK(*std::max_element(reported.begin(), reported.end()) == 1.0);
}

TEST_CASE("rendering samples one at a time and averaging them in order gives the --spp render bit for bit", "[render]") {
  const SmallDefaultScene small(40, 30);
  const rt::Scene& scene = small.scene;
  const rt::FlatScene& flat = small.flat;
  const rt::Accel* const accel = small.accel.get();
  rt::RenderOptions options;
  options.threads = 2;
  options.samples_per_pixel = 5;
  const rt::RenderResult whole = rt::render_image(scene, flat, *accel, options);
  std::vector<rt::Vec3d> sums(whole.image.pixels.size(), rt::Vec3d(0.0));
  std::uint64_t camera_rays = 0;
  for (int s = 0; s < 5; ++s) {
    options.sample_index = s;
    const rt::RenderResult one = rt::render_image(scene, flat, *accel, options);
    camera_rays += one.rays.camera;
    for (std::size_t i = 0; i < sums.size(); ++i) sums[i] += rt::Vec3d(one.image.pixels[i]);
  }
  CHECK(camera_rays == whole.rays.camera);
  std::size_t differing = 0;
  for (std::size_t i = 0; i < sums.size(); ++i) {
    const rt::Color average(sums[i] / 5.0);  // as render_block averages
    differing += std::memcmp(&whole.image.pixels[i], &average, sizeof(rt::Color)) != 0;
  }
  CHECK(differing == 0);
  options.sample_index = 5;
  CHECK_THROWS_AS(rt::render_image(scene, flat, *accel, options), std::invalid_argument);
}

TEST_CASE("render hands every finished tile to on_tile once, with its final pixels", "[render]") {
  const SmallDefaultScene small(50, 30);
  const rt::Scene& scene = small.scene;
  const rt::FlatScene& flat = small.flat;
  const rt::Accel* const accel = small.accel.get();
  rt::RenderOptions options;
  options.threads = 2;
  options.tile_size = 16;
  options.region = rt::PixelRegion{3, 2, 50, 30};
  rt::Image seen(47, 28);
  std::vector<int> times_seen(seen.pixels.size(), 0);
  options.on_tile = [&](const rt::PixelRegion& tile, const rt::Image& image) {
    for (int y = tile.y0; y < tile.y1; ++y)
      for (int x = tile.x0; x < tile.x1; ++x) {
        seen.at(x - 3, y - 2) = image.at(x - 3, y - 2);
        ++times_seen[std::size_t((y - 2) * 47 + (x - 3))];
      }
  };
  const rt::RenderResult result = rt::render_image(scene, flat, *accel, options);
  CHECK(std::count(times_seen.begin(), times_seen.end(), 1) == std::ptrdiff_t(times_seen.size()));
  CHECK(std::memcmp(seen.pixels.data(), result.image.pixels.data(), seen.pixels.size() * sizeof(rt::Color)) == 0);
}

TEST_CASE("render puts row 0 at the top and column 0 at the left", "[render]") {
  // Camera at (0, 0, 1) looking down -z, up +y, fovy 90, 4x4 pixels: pixel (i, j) looks at
  // (alpha, beta, 0) with alpha, beta in {-0.75, -0.25, 0.25, 0.75}. A red emitter covers y > 0
  // (the top two rows); a green one covers x < 0, y < 0 (bottom-left); the rest is background.
  const auto red = rt_test::make_flat_mesh({{rt::Vec3f(-20, 0.01f, 0), rt::Vec3f(20, 0.01f, 0), rt::Vec3f(0, 40, 0)}});
  const auto green =
      rt_test::make_flat_mesh({{rt::Vec3f(-0.01f, -0.01f, 0), rt::Vec3f(-0.01f, -20, 0), rt::Vec3f(-20, -0.01f, 0)}});
  rt::Scene scene = rt_test::make_scene({{red, 0}, {green, 1}});
  scene.materials.resize(2);
  scene.materials[0].emission = rt::Color(1, 0, 0);
  scene.materials[1].emission = rt::Color(0, 1, 0);
  scene.settings.background = rt::Color(0, 0, 1);
  scene.settings.width = scene.settings.height = 4;
  scene.camera.eye = {0, 0, 1};
  scene.camera.target = {0, 0, 0};
  scene.camera.up = {0, 1, 0};
  scene.camera.fovy_degrees = 90.0;
  const rt::AccelKind kind = GENERATE(rt::AccelKind::embree, rt::AccelKind::reference);
  const rt::RenderResult result = render(scene, kind, 1);
  REQUIRE(result.image.width == 4);
  REQUIRE(result.image.height == 4);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      INFO("pixel (" << i << ", " << j << ")");
      const rt::Color expected = j < 2 ? rt::Color(1, 0, 0) : i < 2 ? rt::Color(0, 1, 0) : rt::Color(0, 0, 1);
      CHECK(result.image.at(i, j) == expected);
    }
  CHECK(result.rays.camera == 16);
}

TEST_CASE("quantize_8bit clamps and floors", "[io]") {
  // byte = floor(255 * clamp(c, 0, 1)), worked out by hand.
  CHECK(rt::quantize_8bit(0.0f) == 0);
  CHECK(rt::quantize_8bit(0.5f) == 127);  // 127.5
  CHECK(rt::quantize_8bit(1.0f) == 255);
  CHECK(rt::quantize_8bit(-1.0f) == 0);
  CHECK(rt::quantize_8bit(2.0f) == 255);
  CHECK(rt::quantize_8bit(0.25f) == 63);   // 63.75
  CHECK(rt::quantize_8bit(0.999f) == 254);  // 254.745
  CHECK(rt::quantize_8bit(0.004f) == 1);    // 1.02
  CHECK(rt::quantize_8bit(0.003f) == 0);    // 0.765
  CHECK(rt::quantize_8bit(std::numeric_limits<float>::infinity()) == 255);

  rt::Image image(2, 1);
  image.at(0, 0) = {0.5f, 1.0f, 0.0f};
  image.at(1, 0) = {0.0f, 0.25f, 2.0f};
  CHECK(rt::to_rgb8(image) == std::vector<std::uint8_t>{127, 255, 0, 0, 63, 255});
}

TEST_CASE("png round trip gives the quantised bytes", "[io]") {
  rt_test::TempDir dir;
  // 3x2 pixels, 18 channel values with their bytes floor(255 clamp(c)) computed by hand.
  const float values[18] = {0.0f,  0.5f,  1.0f, -1.0f, 2.0f,    0.25f,  0.999f, 0.003f, 0.004f,
                            0.1f,  0.75f, 1e-9f, 0.9999f, 0.996f, 0.6f,   3.5f,   -0.5f,  0.333f};
  const int bytes[18] = {0, 127, 255, 0, 255, 63, 254, 0, 1, 25, 191, 0, 254, 253, 153, 255, 0, 84};
  rt::Image image(3, 2);
  for (int k = 0; k < 18; ++k) image.pixels[k / 3][k % 3] = values[k];
  const std::string path = dir / "round.png";
  rt::write_image(image, path);
  CHECK(dir.entries() == std::vector<std::string>{"round.png"});  // no temporary left behind

  const rt::Image back = rt::read_image(path);
  REQUIRE(back.width == 3);
  REQUIRE(back.height == 2);
  for (int k = 0; k < 18; ++k) {
    INFO("value " << values[k]);
    const float c = back.pixels[k / 3][k % 3];
    CHECK(c * 255.0f == Approx(bytes[k]).margin(1e-3));
    CHECK(rt::quantize_8bit(values[k]) == bytes[k]);
  }
}

TEST_CASE("exr keeps floats exactly", "[io]") {
  rt_test::TempDir dir;
  rt::Image image(5, 3);
  std::mt19937 rng(7u);
  std::uniform_real_distribution<float> value(-2.0f, 50.0f);
  for (rt::Color& c : image.pixels) c = {value(rng), value(rng), value(rng)};
  image.at(0, 0) = {0.0f, 1e-7f, 1234.5678f};
  const std::string path = dir / "floats.exr";
  rt::write_image(image, path);
  const rt::Image back = rt::read_image(path);
  REQUIRE(back.width == 5);
  REQUIRE(back.height == 3);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    INFO("pixel " << i);
    CHECK(back.pixels[i] == image.pixels[i]);
  }
  CHECK(rt::writes_float(path));
  CHECK_FALSE(rt::writes_float(dir / "x.png"));
}

TEST_CASE("write_image failures leave no file and touch no existing file", "[io]") {
  rt_test::TempDir dir;
  rt::Image image(2, 2);
  image.pixels.assign(4, rt::Color(0.5f));

  SECTION("unknown extension") {
    CHECK_THROWS_AS(rt::write_image(image, dir / "out.xyz"), rt::InputError);
    CHECK_THROWS_AS(rt::write_image(image, dir / "no_extension"), rt::InputError);
    CHECK(dir.entries().empty());
  }
  SECTION("non-existent directory") {
    CHECK_THROWS_AS(rt::write_image(image, dir / "missing/out.png"), rt::RuntimeError);
    CHECK(dir.entries().empty());
  }
  SECTION("existing file with an unknown extension") {
    write_file(dir / "keep.xyz", "precious");
    CHECK_THROWS_AS(rt::write_image(image, dir / "keep.xyz"), rt::InputError);
    CHECK(read_file(dir / "keep.xyz") == "precious");
    CHECK(dir.entries() == std::vector<std::string>{"keep.xyz"});
  }
  SECTION("destination is a directory: the final rename fails") {
    fs::create_directory(dir / "out.png");
    write_file(dir / "out.png/inside.txt", "precious");
    CHECK_THROWS_AS(rt::write_image(image, dir / "out.png"), rt::RuntimeError);
    CHECK(fs::is_directory(dir / "out.png"));
    CHECK(read_file(dir / "out.png/inside.txt") == "precious");
    CHECK(dir.entries() == std::vector<std::string>{"out.png"});  // the temporary is gone
  }
  SECTION("a successful write replaces an existing file") {
    write_file(dir / "old.png", "not a png");
    rt::write_image(image, dir / "old.png");
    CHECK(rt::read_image(dir / "old.png").width == 2);
    CHECK(dir.entries() == std::vector<std::string>{"old.png"});
  }
}

TEST_CASE("check_output_path refuses bad outputs before rendering", "[io]") {
  rt_test::TempDir dir;
  CHECK_NOTHROW(rt::check_output_path(dir / "fine.png"));
  CHECK_NOTHROW(rt::check_output_path(dir / "fine.exr"));
  CHECK_THROWS_AS(rt::check_output_path(dir / "bad.xyz"), rt::InputError);
  CHECK_THROWS_AS(rt::check_output_path(dir / "missing/fine.png"), rt::InputError);
  CHECK(dir.entries().empty());
}

TEST_CASE("read_image rejects a missing or malformed file", "[io]") {
  rt_test::TempDir dir;
  CHECK_THROWS_AS(rt::read_image(dir / "missing.png"), rt::InputError);
  write_file(dir / "garbage.png", "this is not an image");
  CHECK_THROWS_AS(rt::read_image(dir / "garbage.png"), rt::InputError);
}
