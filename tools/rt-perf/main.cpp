// rt-perf: measures what accuracy costs in time. `intersect` compares Embree with the reference
// intersector (build time and memory, Mrays/s, agreement); `accuracy` renders a ground truth and
// sweeps one knob at a time (spp, depth, tessellation, Embree options, ray offsets, approximations);
// `retrace` compares a render phase with Embree re-tracing the same rays;
// `load` times the scene loaders against a raw read of the files; `export-mitsuba` writes a scene
// as rt render loads it for tools/check-mitsuba, the Mitsuba 3 oracle.

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "accuracy.h"
#include "export.h"
#include "intersect.h"
#include "retrace.h"
#include "load.h"
#include "rt/app/scene_options.h"

int main(int argc, char** argv) {
  CLI::App app{"rt-perf: what accuracy costs in time, Embree against the reference intersector, render against re-trace, load times, scene export for Mitsuba"};
  app.require_subcommand(1);
  const std::function<int()> run_intersect = rt::perf::add_intersect_command(app);
  const std::function<int()> run_accuracy = rt::perf::add_accuracy_command(app);
  const std::function<int()> run_retrace = rt::perf::add_retrace_command(app);
  const std::function<int()> run_load = rt::perf::add_load_command(app);
  const std::function<int()> run_export = rt::perf::add_export_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const int code = app.exit(error);
    return code == 0 ? 0 : 2;
  }
  try {
    if (app.got_subcommand("intersect")) return run_intersect();
    if (app.got_subcommand("accuracy")) return run_accuracy();
    if (app.got_subcommand("retrace")) return run_retrace();
    if (app.got_subcommand("load")) return run_load();
    if (app.got_subcommand("export-mitsuba")) return run_export();
  } catch (const rt::UsageError& error) {
    fmt::print(stderr, "rt-perf: error: {}\n", error.what());
    return 2;
  } catch (const std::exception& error) {
    fmt::print(stderr, "rt-perf: error: {}\n", error.what());
  }
  return 1;
}
