// What a new user trips over on the command line (issue 17): a batch overwriting its own output,
// one image side breaking the aspect ratio, bad flag values, typos, misleading notes, output
// formats. Each case runs the real `rt` executable.

#include "catch.h"

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "rt/io/image_io.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

using rt_test::RtRun;
using rt_test::TempDir;
using rt_test::small_json_scene;
using rt_test::write_file;

RtRun run_rt(const TempDir& cwd, const std::string& args) { return rt_test::run_rt_in(cwd, args); }

std::size_t line_count(const std::string& text) { return std::count(text.begin(), text.end(), '\n'); }

// A glTF file with one triangle, no camera and no lights (the buffer is the triangle
// (0,0,0), (1,0,0), (0,1,0) as float32, base64).
const char* const kBareGltf = R"({
  "asset": { "version": "2.0" },
  "buffers": [ { "byteLength": 36, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA" } ],
  "bufferViews": [ { "buffer": 0, "byteLength": 36 } ],
  "accessors": [ { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 1, 0] } ],
  "meshes": [ { "primitives": [ { "attributes": { "POSITION": 0 } } ] } ],
  "nodes": [ { "mesh": 0 } ],
  "scenes": [ { "nodes": [0] } ],
  "scene": 0
})";

// A command line and a part of the one-line usage error it must give.
struct UsageCase {
  std::string args, message;
};

// Checks that `run` failed as a usage error: status 2, one line "rt: error: ..." containing `message`.
void check_usage_error(const RtRun& run, const std::string& message) {
  INFO("stderr: " << run.err);
  CHECK(run.status == 2);
  CHECK(line_count(run.err) == 1);
  CHECK_THAT(run.err, Catch::Matchers::StartsWith("rt: error: ") && Catch::Matchers::ContainsSubstring(message));
}

// The first bytes of a file.
std::string magic(const fs::path& path, std::size_t n) { return rt_test::read_file(path).substr(0, n); }

}  // namespace

TEST_CASE("cli: a batch whose scenes would write the same file is refused before anything is rendered", "[cli]") {
  TempDir dir;
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  write_file(dir / "a/scene.json", small_json_scene());
  write_file(dir / "b/scene.json", small_json_scene());                          // same stem: both scene.png
  write_file(dir / "one.json", small_json_scene(R"("output": "same.png",)"));     // the same declared output
  write_file(dir / "two.json", small_json_scene(R"("output": "./same.png",)"));
  write_file(dir / "three.json", small_json_scene());

  for (const char* batch : {"a/scene.json b/scene.json", "a/scene.json three.json b/scene.json", "one.json two.json",
                            "a/scene.json b/scene.json --outdir out"}) {
    DYNAMIC_SECTION("rt render " << batch) {
      const RtRun run = run_rt(dir, std::string("render -q ") + batch);
      INFO("stderr: " << run.err);
      CHECK(run.status == 2);
      CHECK(line_count(run.err) == 1);
      CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring("would both write"));
      CHECK_FALSE(fs::exists(dir / "scene.png"));
      CHECK_FALSE(fs::exists(dir / "three.png"));
      CHECK_FALSE(fs::exists(dir / "same.png"));
      CHECK_FALSE(fs::exists(dir / "out"));
    }
  }
  // Distinct outputs still make a batch.
  const RtRun ok = run_rt(dir, "render -q a/scene.json three.json one.json");
  INFO("stderr: " << ok.err);
  CHECK(ok.status == 0);
  CHECK(fs::exists(dir / "scene.png"));
  CHECK(fs::exists(dir / "three.png"));
  CHECK(fs::exists(dir / "same.png"));
}

TEST_CASE("cli: --width or --height alone keeps the scene's aspect ratio, both are taken as given", "[cli]") {
  TempDir dir;
  write_file(dir / "scene.json", small_json_scene());  // 32x24
  struct Case {
    std::string flags;
    int width, height;
  };
  for (const Case& c : {Case{"--width 320", 320, 240}, Case{"--height 60", 80, 60}, Case{"--width 50", 50, 38},
                        Case{"--width 40 --height 40", 40, 40}, Case{"--width 1", 1, 1}}) {
    DYNAMIC_SECTION(c.flags) {
      const RtRun run = run_rt(dir, "render -q scene.json -o out.png " + c.flags);
      INFO("stderr: " << run.err);
      REQUIRE(run.status == 0);
      const rt::Image image = rt::read_image(dir / "out.png");
      CHECK(image.width == c.width);
      CHECK(image.height == c.height);
    }
  }
  // The built-in default scene is 640x480.
  REQUIRE(run_rt(dir, "render -q -o default.png --width 320").status == 0);
  CHECK(rt::read_image(dir / "default.png").height == 240);
  // A side that would exceed the largest image is a usage error naming the flag to add.
  const RtRun tall = run_rt(dir, "render -q scene.json --height 65536");
  CHECK(tall.status == 2);
  CHECK_THAT(tall.err, Catch::Matchers::ContainsSubstring("--height 65536 at the scene's aspect ratio makes the width 87381 pixels") &&
                           Catch::Matchers::ContainsSubstring("give --width too"));
}

TEST_CASE("cli: every bad flag value is a usage error (status 2) naming the flag, and writes nothing", "[cli]") {
  TempDir dir;
  write_file(dir / "scene.json", small_json_scene());
  write_file(dir / "bare.gltf", kBareGltf);
  const std::vector<UsageCase> cases = {
      {"scene.json --ray-offset fixed:-1", "--ray-offset: 'fixed:-1' is neither robust nor fixed:EPS"},
      {"scene.json --ray-offset fixed:abc", "--ray-offset: 'fixed:abc'"},
      {"scene.json --width abc", "--width: 'abc' is not a whole number"},
      {"scene.json --width 1.5", "--width: '1.5' is not a whole number"},
      {"scene.json --width 70000", "--width: 70000 is outside 1..65536"},
      {"scene.json --spp x", "--spp: 'x' is not a whole number"},
      {"scene.json --threads -1", "--threads: -1 is outside 0..1024"},
      {"scene.json --light-samples 0", "--light-samples: 0 is outside 1..65536"},
      {"scene.json --min-light x", "--min-light: 'x' is not a finite number"},
      {"scene.json --min-throughput 2", "--min-throughput: 2 is outside [0, 1]"},
      {"scene.json --sphere-tessellation 2", "--sphere-tessellation: 2 is neither 0 nor 3..4096"},
      {"scene.json --sphere-tessellation abc", "--sphere-tessellation: 'abc' is not a whole number"},
      {"scene.json --accel embre", "--accel: 'embre' is not one of embree, reference, reference-barycentric (did you "
                                   "mean embree?)"},
      {"scene.json --eye 1 2", "--eye takes 3 values (X Y Z)"},
      {"scene.json --debug-pixel a b", "--debug-pixel: 'a' is not a whole number"},
      {"scene.json --debug-pixel 32 0", "--debug-pixel 32 0 is outside the 32x24 image"},
      {"scene.json --crop a 0 1 1", "--crop: 'a' is not a whole number"},
      {"scene.json --crop 5 5 1 1", "--crop: 5 5 1 1 is empty"},
      {"scene.json --crop 0 0 10000 10", "--crop 0 0 10000 10 reaches outside the 32x24 image (X1 10000 > width 32)"},
      {"scene.json --crop 0 20 8 30", "--crop 0 20 8 30 reaches outside the 32x24 image (Y1 30 > height 24)"},
      {"scene.json --tile 1/100", "--tile 1/100: the 24-row image cannot be cut into 100 tiles"},
      {"scene.json --camera 0", "--camera applies to .gltf/.glb scenes only"},
      {"scene.json --gltf-scene 1", "--gltf-scene applies to .gltf/.glb scenes only"},
      {"bare.gltf --camera 0", "--camera 0 is out of range (the file has 0 camera(s))"},
      {"bare.gltf --camera front", "--camera 'front': no camera or camera node has this name (the file has no cameras)"},
      {"bare.gltf --gltf-scene 3", "--gltf-scene 3 is out of range (the file has 1 scene(s))"},
      {"scene.json -o out.foo", "-o out.foo: unknown image format '.foo' (writable: .png .ppm .exr"},
      {"scene.json -o out", "-o out: output file has no extension"},
  };
  for (const UsageCase& c : cases) {
    DYNAMIC_SECTION("rt render " << c.args) {
      check_usage_error(run_rt(dir, "render -q " + c.args), c.message);
      CHECK(dir.entries() == std::vector<std::string>{"bare.gltf", "scene.json"});
    }
  }
  // Only the flag given is blamed.
  CHECK_THAT(run_rt(dir, "render -q scene.json --camera 0").err, !Catch::Matchers::ContainsSubstring("--gltf-scene"));
}

TEST_CASE("cli: a mistyped command or flag gets the nearest name suggested", "[cli]") {
  TempDir dir;
  const std::vector<UsageCase> cases = {
      {"rendr x.json", "unknown command 'rendr' (did you mean 'render'?); the commands are render, view, merge and info"},
      {"ifno", "unknown command 'ifno' (did you mean 'info'?)"},
      {"frobnicate", "unknown command 'frobnicate'; the commands are"},
      {"", "no command given: the commands are render, view, merge and info"},
      {"render --widht 32", "unknown option --widht for rt render (did you mean --width?)"},
      {"render --explian", "(did you mean --explain?)"},
      {"render --spp=4 --light-sample 4", "unknown option --light-sample for rt render (did you mean --light-samples?)"},
      {"info --gltf-scnee 0", "unknown option --gltf-scnee for rt info (did you mean --gltf-scene?)"},
      {"--verison", "unknown option --verison for rt (did you mean --version?)"},
      {"--spp 4 render", "--spp is an option of rt render: put it after the command"},
      {"render --bogus", "unknown option --bogus for rt render (rt render --help lists the options)"},
      {"render -x", "unknown option -x for rt render (rt render --help lists the options)"},
      {"info a.json b.json", "unexpected argument 'b.json' for rt info"},
  };
  for (const UsageCase& c : cases) {
    DYNAMIC_SECTION("rt " << c.args) {
      check_usage_error(run_rt(dir, c.args), c.message);
      CHECK(dir.entries().empty());
    }
  }
  // --help and --version are not errors.
  const auto version = run_rt(dir, "--version");
  CHECK(version.status == 0);
  // Which Embree the build uses, for bug reports from Debian 12 (3.13) and 13 (4.x).
  CHECK_THAT(version.out, Catch::Matchers::StartsWith("rt 0.") && Catch::Matchers::ContainsSubstring("(Embree "));
  CHECK(run_rt(dir, "render --help").status == 0);
}

TEST_CASE("cli: notes say what was made up truthfully, and a directory is not an unknown format", "[cli]") {
  TempDir dir;
  write_file(dir / "bare.gltf", kBareGltf);
  write_file(dir / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  // glTF frames obliquely (from the front, right and above); OBJ straight along -z.
  const RtRun gltf = run_rt(dir, "render bare.gltf --width 16");
  INFO("stderr: " << gltf.err);
  REQUIRE(gltf.status == 0);
  CHECK_THAT(gltf.err, Catch::Matchers::ContainsSubstring("framed its bounding box looking along (-0.42, -0.34, -0.84)"));
  const RtRun obj = run_rt(dir, "render tri.obj --width 16");
  REQUIRE(obj.status == 0);
  CHECK_THAT(obj.err, Catch::Matchers::ContainsSubstring("framed its bounding box looking along -z"));

  fs::create_directories(dir / "models");
  const RtRun directory = run_rt(dir, "render models");
  CHECK(directory.status == 1);
  CHECK(line_count(directory.err) == 1);
  CHECK_THAT(directory.err, Catch::Matchers::ContainsSubstring("models: is a directory, not a scene file"));
  CHECK_THAT(directory.err, !Catch::Matchers::ContainsSubstring("unsupported scene format"));
}

TEST_CASE("cli: rt info -q is silent on stderr, and counts are singular when one", "[cli]") {
  TempDir dir;
  write_file(dir / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const RtRun noisy = run_rt(dir, "info tri.obj");
  REQUIRE(noisy.status == 0);
  CHECK_THAT(noisy.err, Catch::Matchers::ContainsSubstring("note:"));
  const RtRun quiet = run_rt(dir, "info -q tri.obj");
  REQUIRE(quiet.status == 0);
  CHECK(quiet.err.empty());
  CHECK(quiet.out == noisy.out);
  CHECK_THAT(quiet.out, Catch::Matchers::ContainsSubstring("1 triangle, 3 vertices, 0 degenerate triangles dropped, 0 spheres"));

  write_file(dir / "scene.json", small_json_scene());
  const RtRun render = run_rt(dir, "render scene.json --threads 1");
  REQUIRE(render.status == 0);
  CHECK_THAT(render.out, Catch::Matchers::ContainsSubstring("0 triangles, 1 sphere, 1 light,") && Catch::Matchers::ContainsSubstring("(embree, 1 thread)"));
}

TEST_CASE("cli: outputs in any case of extension, lossy formats noted, formats listed", "[cli]") {
  TempDir dir;
  write_file(dir / "scene.json", small_json_scene());
  REQUIRE(run_rt(dir, "render -q scene.json -o upper.PNG").status == 0);
  CHECK(magic(dir / "upper.PNG", 4) == "\x89PNG");
  const RtRun gif = run_rt(dir, "render scene.json -o out.gif");
  INFO("stderr: " << gif.err);
  REQUIRE(gif.status == 0);
  CHECK(magic(dir / "out.gif", 3) == "GIF");
  CHECK_THAT(gif.err, Catch::Matchers::ContainsSubstring("out.gif: GIF keeps at most 256 colours"));
  const RtRun jpg = run_rt(dir, "render scene.json -o out.JPG");
  REQUIRE(jpg.status == 0);
  CHECK(magic(dir / "out.JPG", 2) == "\xFF\xD8");
  CHECK_THAT(jpg.err, Catch::Matchers::ContainsSubstring("jpg is compressed lossily"));
  const RtRun png = run_rt(dir, "render scene.json -o out.png");
  CHECK(png.err.empty());
  CHECK(run_rt(dir, "render -q scene.json -o quiet.webp").err.empty());
  CHECK_THAT(run_rt(dir, "render --help").out, Catch::Matchers::ContainsSubstring("png, ppm (written by rt), exr, hdr"));
}
