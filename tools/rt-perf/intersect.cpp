#include "intersect.h"

#include <fmt/format.h>

namespace rt::perf {

std::function<int()> add_intersect_command(CLI::App& app) {
  CLI::App* command = app.add_subcommand("intersect", "Embree against the reference: build, memory, Mrays/s, agreement");
  (void)command;
  return [] {
    fmt::print(stderr, "rt-perf: intersect is not implemented yet\n");
    return 1;
  };
}

}  // namespace rt::perf
