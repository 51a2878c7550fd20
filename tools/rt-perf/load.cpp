#include "load.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>

#include <fmt/format.h>

#include "rt/core/error.h"
#include "rt/io/load_gltf.h"
#include "rt/io/load_scene.h"

namespace rt::perf {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// The external files a .gltf's "buffers" and "images" name, each once, in order; none when the
// JSON cannot be parsed (the load then fails and reports why).
std::vector<std::string> gltf_external_files(const std::string& path, std::size_t& buffers, std::size_t& images) {
  std::vector<std::string> files;
  std::ifstream in(path, std::ios::binary);
  const nlohmann::json document = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!document.is_object()) return files;
  std::set<std::string> seen;
  for (const char* key : {"buffers", "images"}) {
    const auto array = document.find(key);
    if (array == document.end() || !array->is_array()) continue;
    for (const nlohmann::json& entry : *array) {
      if (!entry.is_object() || !entry.contains("uri") || !entry["uri"].is_string()) continue;
      const std::string uri = entry["uri"].get<std::string>();
      if (uri.starts_with("data:")) continue;
      const fs::path file = fs::path(path).parent_path() / decode_gltf_uri(uri);
      std::error_code error;
      if (!fs::is_regular_file(file, error) || !seen.insert(file.string()).second) continue;
      files.push_back(file.string());
      ++(std::string(key) == "buffers" ? buffers : images);
    }
  }
  return files;
}

// Reads every byte of `path` into `bytes` (resized to the file's size).
void read_whole_file(const std::string& path, std::vector<char>& bytes) {
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) throw InputError(path, "", "cannot open file");
  std::error_code error;
  const std::uintmax_t size = fs::file_size(path, error);
  if (error) throw InputError(path, "", "cannot read the file's size");
  bytes.resize(static_cast<std::size_t>(size));
  if (size > 0 && std::fread(bytes.data(), 1, bytes.size(), file.get()) != bytes.size())
    throw InputError(path, "", "cannot read file");
}

double mb_per_second(std::uint64_t bytes, const Timing& timing) {
  const double median = timing.median_seconds();
  return median > 0.0 ? double(bytes) / median * 1e-6 : 0.0;
}

struct Options {
  std::vector<std::string> scenes;
  int runs = 5;
  bool json = false;
};

int run_load(const Options& options) {
  if (options.scenes.empty()) throw InputError("give at least one SCENE");
  if (options.runs < 1) throw InputError("--runs must be at least 1");
  for (const std::string& path : options.scenes) scene_input_files(path);  // missing files fail before any timing
  if (!options.json)
    fmt::print("# rt-perf load\n\nEach file is loaded with load_scene (parse + the in-memory Scene, as `rt render` "
               "loads it; no flattening, no BVH) and, apart, read whole into memory (raw read), {} times each, page "
               "cache warm; median and min wall-clock seconds; MB/s = bytes / median, 1 MB = 10^6 bytes.\n\n"
               "| file | bytes | counted | load median s | load min s | load MB/s | raw read median s | raw read "
               "MB/s | read / load |\n|---|---:|---|---:|---:|---:|---:|---:|---:|\n",
               options.runs);
  for (const std::string& path : options.scenes) {
    const LoadMeasurement m = measure_load(path, options.runs);
    if (options.json) {
      fmt::print("{}\n", to_json(m).dump());
      continue;
    }
    const double share = m.load.median_seconds() > 0.0 ? m.read.median_seconds() / m.load.median_seconds() : 0.0;
    fmt::print("| {} | {} | {} | {} | {} | {} | {} | {} | {}% |\n", path, m.input.bytes, m.input.counted,
               sig3(m.load.median_seconds()), sig3(m.load.min_seconds()), sig3(m.load_mb_per_second()),
               sig3(m.read.median_seconds()), sig3(m.read_mb_per_second()), sig3(100.0 * share));
  }
  return 0;
}

}  // namespace

SceneBytes scene_input_files(const std::string& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError(path, "", "no such file");
  SceneBytes input;
  input.files.push_back(path);
  input.counted = "the file";
  if (lower(fs::path(path).extension().string()) == ".gltf") {
    std::size_t buffers = 0, images = 0;
    for (std::string& file : gltf_external_files(path, buffers, images)) input.files.push_back(std::move(file));
    input.counted = fmt::format("the .gltf, {} buffer file(s), {} image file(s)", buffers, images);
  }
  for (const std::string& file : input.files) input.bytes += fs::file_size(file);
  return input;
}

double LoadMeasurement::load_mb_per_second() const { return mb_per_second(input.bytes, load); }
double LoadMeasurement::read_mb_per_second() const { return mb_per_second(input.bytes, read); }

LoadMeasurement measure_load(const std::string& path, int runs) {
  LoadMeasurement m;
  m.path = path;
  m.input = scene_input_files(path);
  std::vector<std::vector<char>> contents(m.input.files.size());
  for (std::size_t f = 0; f < m.input.files.size(); ++f) read_whole_file(m.input.files[f], contents[f]);
  for (int run = 0; run < runs; ++run) {
    const Clock::time_point start = Clock::now();
    for (std::size_t f = 0; f < m.input.files.size(); ++f) read_whole_file(m.input.files[f], contents[f]);
    m.read.seconds.push_back(seconds_since(start));
  }
  for (int run = 0; run < runs; ++run) {
    LoadReport report;
    const Clock::time_point start = Clock::now();
    const Scene scene = load_scene(path, {}, &report);
    m.load.seconds.push_back(seconds_since(start));
  }
  return m;
}

nlohmann::json to_json(const LoadMeasurement& m) {
  return {{"file", m.path},
          {"bytes", m.input.bytes},
          {"bytes_counted", m.input.counted},
          {"files", m.input.files},
          {"runs", m.load.seconds.size()},
          {"load_median_s", m.load.median_seconds()},
          {"load_min_s", m.load.min_seconds()},
          {"load_mb_per_s", m.load_mb_per_second()},
          {"read_median_s", m.read.median_seconds()},
          {"read_min_s", m.read.min_seconds()},
          {"read_mb_per_s", m.read_mb_per_second()}};
}

std::function<int()> add_load_command(CLI::App& app) {
  CLI::App* command =
      app.add_subcommand("load", "Scene load time per file (parse + in-memory Scene) against a raw read of its bytes");
  auto options = std::make_shared<Options>();
  command->add_option("scenes", options->scenes, "Scene files (.json, .test, .gltf, .glb, .obj)")->required();
  command->add_option("--runs", options->runs,
                      "Timed loads and reads per file; median and min are reported (default 5)");
  command->add_flag("--json", options->json, "Print one JSON object per file instead of the table");
  return [options] { return run_load(*options); };
}

}  // namespace rt::perf
