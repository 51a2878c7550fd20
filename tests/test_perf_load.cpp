// rt-perf load: which bytes are counted, the JSON and table output, bad arguments.

#include "catch.h"

#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "load.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

const char* const kTriangleObj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

}  // namespace

TEST_CASE("load: a .gltf counts its buffer and image files, once each and other formats the file alone", "[perf]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir.path() / "mesh data.bin", std::string(100, 'x'));
  rt_test::write_file(dir.path() / "albedo.png", std::string(30, 'y'));
  const std::string gltf = R"({"asset": {"version": "2.0"},
    "buffers": [{"uri": "mesh%20data.bin", "byteLength": 100}, {"uri": "data:application/octet-stream;base64,AAAA"},
                {"uri": "mesh data.bin"}, {"uri": "absent.bin"}],
    "images": [{"uri": "albedo.png"}, {"bufferView": 0}]})";
  rt_test::write_file(dir.path() / "scene.gltf", gltf);
  const rt::perf::SceneBytes input = rt::perf::scene_input_files(dir / "scene.gltf");
  CHECK(input.files == std::vector<std::string>{dir / "scene.gltf", dir / "mesh data.bin", dir / "albedo.png"});
  CHECK(input.bytes == gltf.size() + 100 + 30);
  CHECK(input.counted == "the .gltf, 1 buffer file(s), 1 image file(s)");

  rt_test::write_file(dir.path() / "tri.obj", kTriangleObj);
  const rt::perf::SceneBytes obj = rt::perf::scene_input_files(dir / "tri.obj");
  CHECK(obj.files == std::vector<std::string>{dir / "tri.obj"});
  CHECK(obj.bytes == std::string(kTriangleObj).size());
  CHECK(obj.counted == "the file");
  CHECK_THROWS_WITH(rt::perf::scene_input_files(dir / "none.obj"), Catch::Matchers::ContainsSubstring("none.obj: no such file"));
}

TEST_CASE("load: the measurement's MB/s is bytes over the median, 1 MB = 10^6 bytes", "[perf]") {
  rt::perf::LoadMeasurement m;
  m.input.bytes = 3'000'000;
  m.load.seconds = {0.5, 0.1, 0.3};  // median 0.3
  m.read.seconds = {0.01, 0.03};     // median 0.02
  CHECK(m.load_mb_per_second() == Approx(10.0).epsilon(1e-12));
  CHECK(m.read_mb_per_second() == Approx(150.0).epsilon(1e-12));
  const nlohmann::json json = rt::perf::to_json(m);
  CHECK(json.at("load_median_s") == 0.3);
  CHECK(json.at("load_min_s") == 0.1);
  CHECK(json.at("runs") == 3);
  m.load.seconds.clear();
  CHECK(m.load_mb_per_second() == 0.0);
}

TEST_CASE("rt-perf load prints a table or one JSON object per file and bad arguments fail", "[perf]") {
  rt_test::TempDir dir;
  rt_test::write_file(dir.path() / "tri.obj", kTriangleObj);
  rt_test::write_file(dir.path() / "bad.obj", "v 0 0 0\nf 1 2 3\n");

  const rt_test::RtRun json_run = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "load tri.obj tri.obj --runs 3 --json");
  INFO("stderr: " << json_run.err);
  REQUIRE(json_run.status == 0);
  std::istringstream lines(json_run.out);
  std::string line;
  int objects = 0;
  while (std::getline(lines, line)) {
    const nlohmann::json json = nlohmann::json::parse(line);
    CHECK(json.at("file") == "tri.obj");
    CHECK(json.at("bytes") == std::string(kTriangleObj).size());
    CHECK(json.at("runs") == 3);
    CHECK(json.at("load_min_s").get<double>() > 0.0);
    CHECK(json.at("load_median_s").get<double>() >= json.at("load_min_s").get<double>());
    CHECK(json.at("load_mb_per_s").get<double>() ==
          Approx(double(std::string(kTriangleObj).size()) / json.at("load_median_s").get<double>() * 1e-6));
    CHECK(json.at("read_median_s").get<double>() > 0.0);
    ++objects;
  }
  CHECK(objects == 2);

  const rt_test::RtRun table = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "load tri.obj --runs 1");
  REQUIRE(table.status == 0);
  CHECK_THAT(table.out, Catch::Matchers::ContainsSubstring("| file | bytes |") && Catch::Matchers::ContainsSubstring("| tri.obj | 32 | the file |"));

  const rt_test::RtRun zero_runs = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "load tri.obj --runs 0");
  CHECK(zero_runs.status == 1);
  CHECK_THAT(zero_runs.err, Catch::Matchers::ContainsSubstring("--runs must be at least 1"));
  const rt_test::RtRun missing = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "load none.obj");
  CHECK(missing.status == 1);
  CHECK_THAT(missing.err, Catch::Matchers::ContainsSubstring("none.obj: no such file"));
  const rt_test::RtRun malformed = rt_test::run_in(dir, RT_PERF_EXECUTABLE, "load bad.obj --runs 1");
  CHECK(malformed.status == 1);
  CHECK_THAT(malformed.err, Catch::Matchers::ContainsSubstring("bad.obj:2: vertex index 2 out of range"));
  CHECK(rt_test::run_in(dir, RT_PERF_EXECUTABLE, "load").status == 2);
}
