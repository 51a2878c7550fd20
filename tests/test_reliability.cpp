// Reliability: resource limits refused before allocation, the NaN/Inf guard, cancellation of the
// render loop (and SIGINT/SIGTERM on the real executable), faults while writing, --debug-pixel.

#include "catch.h"

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fcntl.h>
#include <filesystem>
#include <thread>

#include <fmt/format.h>

#include "rt/accel/accel.h"
#include "rt/accel/embree_accel.h"
#include "rt/core/error.h"
#include "rt/core/memory.h"
#include "rt/flatten/flatten.h"
#include "rt/io/load_scene.h"
#include "rt/render/render.h"
#include "rt/scene/shapes.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

// Caps available_memory_bytes() for the lifetime of the object.
class ScopedMemoryLimit {
 public:
  explicit ScopedMemoryLimit(std::uint64_t bytes) { rt::set_memory_limit(bytes); }
  ~ScopedMemoryLimit() { rt::set_memory_limit(0); }
  ScopedMemoryLimit(const ScopedMemoryLimit&) = delete;
  ScopedMemoryLimit& operator=(const ScopedMemoryLimit&) = delete;
};

// A scene whose root instances `leaf` through `levels` levels of nodes, each with two children
// that are the same node: 2^levels instances of the leaf's sphere mesh.
rt::Scene make_doubling_scene(int levels) {
  rt::Scene scene = rt::make_default_scene();
  scene.nodes.clear();
  scene.root = 0;
  for (int i = 0; i < levels; ++i)
    scene.nodes.push_back(rt::Node{"level", rt::Mat4d(1.0), {std::uint32_t(i + 1), std::uint32_t(i + 1)}, {}});
  rt::Node leaf{"leaf", rt::Mat4d(1.0), {}, {}};
  leaf.models.push_back({std::make_shared<const rt::TriangleMesh>(rt::make_sphere_mesh(1.0, 8, 4)), 0});
  scene.nodes.push_back(leaf);
  return scene;
}

rt::RenderResult render(const rt::Scene& scene, const rt::RenderOptions& options) {
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const std::unique_ptr<rt::Accel> accel = rt::build_accel(rt::AccelKind::embree, flat);
  return rt::render_image(scene, flat, *accel, options);
}

bool is_black(const rt::Color& c) { return c.r == 0.0f && c.g == 0.0f && c.b == 0.0f; }

}  // namespace

TEST_CASE("memory sizes parse and print in binary units", "[reliability]") {
  CHECK(rt::parse_bytes("800") == 800u);
  CHECK(rt::parse_bytes("512M") == 512u << 20);
  CHECK(rt::parse_bytes("2G") == std::uint64_t(2) << 30);
  CHECK(rt::parse_bytes("1.5GiB") == std::uint64_t(3) << 29);
  CHECK(rt::parse_bytes("4kb") == 4096u);
  CHECK_FALSE(rt::parse_bytes("").has_value());
  CHECK_FALSE(rt::parse_bytes("lots").has_value());
  CHECK_FALSE(rt::parse_bytes("-1G").has_value());
  CHECK_FALSE(rt::parse_bytes("3X").has_value());
  CHECK_FALSE(rt::parse_bytes("1e30").has_value());
  CHECK(rt::format_bytes(980) == "980 bytes");
  CHECK(rt::format_bytes(1536) == "1.5 KiB");
  CHECK(rt::format_bytes(std::uint64_t(40) << 30) == "40 GiB");
  CHECK(rt::available_memory_bytes() > 0);
  const ScopedMemoryLimit limit(1 << 20);
  CHECK(rt::available_memory_bytes() <= 1u << 20);
  CHECK_FALSE(rt::memory_shortfall(1000).has_value());
  REQUIRE(rt::memory_shortfall(2 << 20).has_value());
  CHECK(*rt::memory_shortfall(2 << 20) == "needs 2.0 MiB, 1.0 MiB available");
}

TEST_CASE("requests that cannot fit are refused before allocation, naming what was asked", "[reliability]") {
  SECTION("an image") {
    rt::Scene scene = rt::make_default_scene();
    scene.settings.width = scene.settings.height = 2000;
    const ScopedMemoryLimit limit(16 << 20);
    CHECK_THROWS_WITH(rt::check_render_memory(scene),
                      Catch::Matchers::ContainsSubstring("2000x2000 image needs 103 MiB, 16 MiB available"));
    CHECK_THROWS_AS(render(scene, rt::RenderOptions{}), rt::InputError);
  }
  SECTION("flattening instances, counted through shared nodes") {
    // 2^30 instances of the leaf's sphere mesh, in a few dozen nodes.
    const rt::Scene scene = make_doubling_scene(30);
    const std::uint64_t leaf_triangles = scene.nodes.back().models[0].mesh->triangles.size();
    CHECK(rt::sum_over_instances(scene, [](const rt::Node&) { return std::uint64_t(1); }) == (std::uint64_t(1) << 31) - 1);
    CHECK_THROWS_WITH(rt::flatten_scene(scene),
                      Catch::Matchers::ContainsSubstring(fmt::format("flattening {} triangles", leaf_triangles << 30)) &&
                          Catch::Matchers::ContainsSubstring("available"));
  }
  SECTION("instance counts saturate instead of wrapping") {
    const rt::Scene scene = make_doubling_scene(70);
    CHECK(rt::sum_over_instances(scene, [](const rt::Node&) { return std::uint64_t(1); }) == UINT64_MAX);
  }
  SECTION("a cycle is reported, not walked") {
    rt::Scene scene = make_doubling_scene(3);
    scene.nodes[2].children.push_back(1);
    CHECK_THROWS_WITH(rt::sum_over_instances(scene, [](const rt::Node&) { return std::uint64_t(1); }),
                      Catch::Matchers::ContainsSubstring("node hierarchy contains a cycle"));
    CHECK_THROWS_WITH(rt::flatten_scene(scene), Catch::Matchers::ContainsSubstring("node hierarchy contains a cycle"));
  }
  SECTION("Embree's BVH build, through its memory monitor") {
    const rt::FlatScene flat = rt::flatten_scene(make_doubling_scene(10));  // 1,024 spheres of 48 triangles
    const ScopedMemoryLimit limit(64 << 10);
    CHECK_THROWS_WITH(rt::EmbreeAccel(flat, rt::AccelOptions{}),
                      Catch::Matchers::ContainsSubstring("out of memory: Embree asked for") && Catch::Matchers::ContainsSubstring("64 KiB were available"));
  }
}

TEST_CASE("JSON node nesting: 255 levels load, 256 are refused, without exhausting the stack", "[reliability]") {
  // Run by the AddressSanitizer suite too, whose much larger frames overflowed at ~1,000 levels.
  const auto nested = [](int levels) {
    std::string nodes = R"({ "models": [ { "geometry": { "type": "sphere" }, "material": "m" } ] })";
    for (int i = 0; i < levels; ++i) nodes = R"({ "children": [ )" + nodes + " ] }";
    return R"({ "camera": { "eye": [0, 0, 5], "target": [0, 0, 0], "fovy": 45 },
               "materials": { "m": { "diffuse": 0.5 } }, "nodes": [ )" + nodes + " ] }";
  };
  const rt::Scene scene = rt::parse_scene_json(nested(255), "deep.json");
  CHECK(scene.nodes.size() == 257);  // the root, 255 chained nodes and the leaf
  CHECK_THROWS_WITH(rt::parse_scene_json(nested(256), "deep.json"),
                    Catch::Matchers::ContainsSubstring("deep.json:/nodes/0/children/...: node hierarchy deeper than 256 levels"));
}

TEST_CASE("non-finite samples become black, are counted and the first pixel is reported", "[reliability]") {
  rt::Scene scene = rt::make_default_scene();
  scene.settings.width = 64;
  scene.settings.height = 48;
  // Two lights each near the float32 maximum: their sum overflows to infinity wherever both light a
  // surface, and infinity times a zero term gives NaN.
  scene.lights.resize(2);
  for (rt::Light& light : scene.lights) light.color = rt::Color(3e38f);
  rt::RenderOptions options;
  const rt::RenderResult result = render(scene, options);
  REQUIRE(result.non_finite_samples > 0);
  REQUIRE(result.first_non_finite_pixel.has_value());
  const auto [fx, fy] = *result.first_non_finite_pixel;
  CHECK(is_black(result.image.at(fx, fy)));
  for (const rt::Color& c : result.image.pixels) CHECK((std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b)));
  // It is the first in row-major order: no earlier pixel traces to a non-finite colour.
  const rt::FlatScene flat = rt::flatten_scene(scene);
  const std::unique_ptr<rt::Accel> accel = rt::build_accel(rt::AccelKind::embree, flat);
  const std::vector<std::string> trace = rt::trace_pixel(scene, flat, *accel, options, fx, fy);
  CHECK(std::any_of(trace.begin(), trace.end(), [](const std::string& l) { return l.find("NOT FINITE") != std::string::npos; }));
  const int before = fy * scene.settings.width + fx;
  for (int p = std::max(0, before - 3); p < before; ++p) {
    const std::vector<std::string> earlier = rt::trace_pixel(scene, flat, *accel, options, p % 64, p / 64);
    CHECK(std::none_of(earlier.begin(), earlier.end(), [](const std::string& l) { return l.find("NOT FINITE") != std::string::npos; }));
  }
}

TEST_CASE("a cancelled render stops, keeps finished tiles exactly and blacks out the rest", "[reliability]") {
  rt::Scene scene = rt::make_default_scene();
  scene.settings.width = 160;
  scene.settings.height = 120;
  rt::RenderOptions options;
  options.threads = 2;
  const rt::RenderResult full = render(scene, options);
  CHECK_FALSE(full.cancelled());
  CHECK(full.tiles_finished() == full.tile_count());

  std::atomic<bool> cancel{true};
  options.cancel = &cancel;
  const rt::RenderResult none = render(scene, options);
  CHECK(none.cancelled());
  CHECK(none.tiles_finished() == 0);
  for (const rt::Color& c : none.image.pixels) CHECK(is_black(c));

  cancel = false;
  options.on_progress = [&](double fraction) {
    if (fraction >= 0.3) cancel = true;
  };
  const rt::RenderResult part = render(scene, options);
  CHECK(part.cancelled());
  CHECK(part.tiles_finished() > 0);
  CHECK(part.tiles_finished() < part.tile_count());
  const int tile = options.tile_size, tiles_x = (scene.settings.width + tile - 1) / tile;
  for (int y = 0; y < scene.settings.height; ++y)
    for (int x = 0; x < scene.settings.width; ++x) {
      const bool done = part.tile_done[std::size_t((y / tile) * tiles_x + x / tile)] != 0;
      const rt::Color expected = done ? full.image.at(x, y) : rt::Color(0.0f);
      const rt::Color got = part.image.at(x, y);
      if (!(got == expected)) FAIL("pixel (" << x << ", " << y << ") of a " << (done ? "finished" : "unfinished") << " tile");
    }
}

TEST_CASE("rt render --debug-pixel prints the pixel's ray tree and writes nothing", "[reliability][cli]") {
  rt_test::TempDir dir;
  const rt_test::RtRun run = rt_test::run_rt_in(dir, "render --debug-pixel 320 240");
  INFO("stderr: " << run.err);
  CHECK(run.status == 0);
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("pixel (320, 240) sample 1 of 1"));
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("camera ray origin"));
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("light 0:"));
  CHECK_THAT(run.out, Catch::Matchers::ContainsSubstring("pixel (320, 240) = ("));
  CHECK(dir.entries().empty());
  const rt_test::RtRun outside = rt_test::run_rt_in(dir, "render --debug-pixel 640 0");
  CHECK(outside.status == 2);
  CHECK_THAT(outside.err, Catch::Matchers::ContainsSubstring("--debug-pixel 640 0 is outside the 640x480 image"));
}

TEST_CASE("rt render --memory-limit refuses an image that does not fit, before rendering", "[reliability][cli]") {
  rt_test::TempDir dir;
  const rt_test::RtRun run = rt_test::run_rt_in(dir, "render --width 4000 --height 3000 --memory-limit 64M");
  INFO("stderr: " << run.err);
  CHECK(run.status == 1);
  CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("4000x3000 image needs 309 MiB, 64 MiB available"));
  CHECK(dir.entries().empty());
  CHECK(rt_test::run_rt_in(dir, "render --memory-limit lots").status == 2);
}

TEST_CASE("faults while writing leave no partial file and an existing file untouched", "[reliability][cli]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir.path() / "out.png", "previous contents");
  SECTION("the disk fills up during the write (file size limit)") {
    // RLIMIT_FSIZE (4 blocks of dash's `ulimit -f`, 2 KiB) makes write() fail with EFBIG, as a
    // full disk makes it fail with ENOSPC; SIGXFSZ is ignored so the failure is an error code.
    const rt_test::RtRun run = rt_test::run_in(dir, "/bin/sh", "-c \"trap '' XFSZ; ulimit -f 4; exec '" +
                                                                   std::string(RT_EXECUTABLE) + "' render -o out.png\"");
    INFO("stderr: " << run.err);
    CHECK(run.status == 1);
    CHECK(std::count(run.err.begin(), run.err.end(), '\n') == 1);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("out.png: cannot write the file: File too large"));
  }
  SECTION("an unknown extension") {
    const rt_test::RtRun run = rt_test::run_rt_in(dir, "render -o out.xyz");
    CHECK(run.status == 2);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("out.xyz: unknown image format '.xyz'"));
  }
  SECTION("a directory that does not exist, or is a file") {
    CHECK_THAT(rt_test::run_rt_in(dir, "render -o missing/out.png").err, Catch::Matchers::ContainsSubstring("output directory does not exist"));
    CHECK_THAT(rt_test::run_rt_in(dir, "render -o out.png/x.png").err, Catch::Matchers::ContainsSubstring("'out.png' is not a directory"));
  }
  SECTION("a destination that is not a regular file") {
    REQUIRE(mkfifo((dir.path() / "pipe.png").c_str(), 0600) == 0);
    const rt_test::RtRun run = rt_test::run_rt_in(dir, "render -o pipe.png");
    CHECK(run.status == 1);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("pipe.png: exists and is not a regular file"));
    CHECK(fs::is_fifo(dir.path() / "pipe.png"));
    fs::remove(dir.path() / "pipe.png");
  }
  CHECK(dir.entries() == std::vector<std::string>{"out.png"});
  CHECK(rt_test::read_file(dir.path() / "out.png") == "previous contents");
}

namespace {

struct Interrupted {
  int status = -1;        // exit status, or 128 + signal if killed by one
  double seconds = 0.0;   // from the signal to the exit
  std::string err;
};

// Starts `rt ARGS` in `dir`, sends `signal` after `delay`, waits for the exit (at most 20 s).
Interrupted interrupt_rt(const rt_test::TempDir& dir, const std::vector<std::string>& args, int signal,
                         std::chrono::milliseconds delay) {
  rt_test::TempDir capture;
  const std::string err_path = capture / "err";
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    if (chdir(dir.path().c_str()) != 0) _exit(127);
    const int fd = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (fd < 0 || dup2(fd, STDERR_FILENO) < 0) _exit(127);
    std::vector<char*> argv{const_cast<char*>(RT_EXECUTABLE)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(RT_EXECUTABLE, argv.data());
    _exit(127);
  }
  std::this_thread::sleep_for(delay);
  REQUIRE(kill(pid, signal) == 0);
  const auto sent = std::chrono::steady_clock::now();
  Interrupted result;
  int raw = 0;
  while (waitpid(pid, &raw, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() - sent > std::chrono::seconds(20)) {
      kill(pid, SIGKILL);
      waitpid(pid, &raw, 0);
      FAIL("rt did not stop within 20 s of the signal");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  result.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
  result.err = rt_test::read_file(err_path);
  return result;
}

}  // namespace

TEST_CASE("SIGINT and SIGTERM stop a long render within a second, writing nothing unless asked", "[reliability][cli]") {
  // The default scene at 64 samples per pixel: about 20 s on two cores, far beyond the signal.
  const std::vector<std::string> long_render{"render", "--spp", "64", "-o", "out.png"};
  rt_test::TempDir dir;
  SECTION("SIGINT: exit 130, no file") {
    const Interrupted run = interrupt_rt(dir, long_render, SIGINT, std::chrono::milliseconds(2500));
    INFO("stderr: " << run.err);
    CHECK(run.status == 130);
    CHECK(run.seconds < 1.0);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("interrupted by SIGINT") && Catch::Matchers::ContainsSubstring("nothing written"));
    CHECK(dir.entries().empty());
  }
  SECTION("SIGTERM with --partial-output: exit 143, the finished tiles in out.partial.png") {
    std::vector<std::string> args = long_render;
    args.push_back("--partial-output");
    const Interrupted run = interrupt_rt(dir, args, SIGTERM, std::chrono::milliseconds(2500));
    INFO("stderr: " << run.err);
    CHECK(run.status == 143);
    CHECK(run.seconds < 1.0);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("interrupted by SIGTERM") && Catch::Matchers::ContainsSubstring("out.partial.png"));
    CHECK(dir.entries() == std::vector<std::string>{"out.partial.png"});
  }
  SECTION("SIGINT in a batch: the render in progress stops, no other scene starts") {
    const std::string scenes = std::string(RT_SOURCE_DIR) + "/scenes/";
    const Interrupted run = interrupt_rt(dir, {"render", "--spp", "64", "--outdir", "out", scenes + "default.json",
                                               scenes + "transforms.json"}, SIGINT, std::chrono::milliseconds(2500));
    INFO("stderr: " << run.err);
    CHECK(run.status == 130);
    CHECK(run.seconds < 1.0);
    CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("rt: batch interrupted: 0 rendered, 0 skipped, 0 failed, 1 not started"));
    CHECK(dir.entries() == std::vector<std::string>{"out"});
    CHECK(std::filesystem::is_empty(dir.path() / "out"));
  }
}
