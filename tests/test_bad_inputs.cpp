// The bad-input catalogue (tests/bad_inputs/): every file is rendered with the real `rt` as a user
// would, and must fail cleanly (exit 1 or 2, never a signal; one short line on stderr naming the file and
// the expected reason; no output file) or, for the variants that should work (BOM, CRLF), render.
// catalogue.tsv lists every file with its expected outcome; a file missing from it fails the test.

#include "catch.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "test_util.h"

namespace fs = std::filesystem;

namespace {

struct Case {
  std::string expect;   // "error", "ok", or "aux" (read by another case, not rendered itself)
  std::string message;  // for "error": a substring of the message
};

const fs::path kCatalogueDir = fs::path(RT_SOURCE_DIR) / "tests" / "bad_inputs";

std::map<std::string, Case> read_catalogue() {
  std::ifstream in(kCatalogueDir / "catalogue.tsv");
  REQUIRE(in);
  std::map<std::string, Case> cases;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line.starts_with('#')) continue;
    std::istringstream fields(line);
    std::string file;
    Case c;
    std::getline(fields, file, '\t');
    std::getline(fields, c.expect, '\t');
    std::getline(fields, c.message, '\t');
    INFO("catalogue line: " << line);
    REQUIRE((c.expect == "error" || c.expect == "ok" || c.expect == "aux"));
    REQUIRE((c.expect != "error" || !c.message.empty()));
    REQUIRE(cases.emplace(file, c).second);
  }
  return cases;
}

std::vector<std::string> directory_listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace

TEST_CASE("bad-input catalogue: every file fails cleanly or, if meant to, renders", "[cli][bad_inputs]") {
  const std::map<std::string, Case> cases = read_catalogue();
  const std::vector<std::string> files = directory_listing(kCatalogueDir);
  std::size_t errors = 0;
  for (const std::string& file : files) {
    if (file == "catalogue.tsv") continue;
    INFO("file not listed in catalogue.tsv: " << file);
    REQUIRE(cases.contains(file));
  }
  for (const auto& [file, c] : cases) {
    INFO("listed in catalogue.tsv but missing: " << file);
    REQUIRE(fs::exists(kCatalogueDir / file));
  }
  for (const auto& [file, c] : cases) {
    if (c.expect == "aux") continue;
    DYNAMIC_SECTION(file) {
      rt_test::TempDir cwd;
      // A memory cap makes the resource-limit cases independent of the machine's memory.
      const rt_test::RtRun run =
          rt_test::run_rt_in(cwd, "render --memory-limit 4G '" + (kCatalogueDir / file).string() + "'");
      INFO("stderr: " << run.err);
      if (c.expect == "ok") {
        CHECK(run.status == 0);
        CHECK(cwd.entries() == std::vector<std::string>{fs::path(file).stem().string() + ".png"});
      } else {
        ++errors;
        CHECK((run.status == 1 || run.status == 2));
        CHECK(std::count(run.err.begin(), run.err.end(), '\n') == 1);
        CHECK(run.err.size() < 1024);  // quotes of the input are cut (InputError), the line stays readable
        CHECK_THAT(run.err, Catch::Matchers::StartsWith("rt: error: ") && Catch::Matchers::EndsWith("\n"));
        CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring(fs::path(file).stem().string()));
        CHECK_THAT(run.err, Catch::Matchers::ContainsSubstring(c.message));
        CHECK(cwd.entries().empty());
      }
    }
  }
  // Nothing was written next to the inputs either (no temporary or partial files).
  CHECK(directory_listing(kCatalogueDir) == files);
}

TEST_CASE("bad-input catalogue holds at least 40 failing cases across the four formats", "[bad_inputs]") {
  std::map<std::string, int> per_format;
  for (const auto& [file, c] : read_catalogue())
    if (c.expect == "error") ++per_format[fs::path(file).extension().string()];
  int total = 0;
  for (const auto& [extension, n] : per_format) total += n;
  CHECK(total >= 40);
  for (const char* extension : {".json", ".test", ".obj", ".gltf", ".glb"}) {
    INFO(extension);
    CHECK(per_format[extension] >= 5);
  }
}
