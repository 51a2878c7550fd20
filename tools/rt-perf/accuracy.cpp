#include "accuracy.h"

#include <fmt/format.h>

namespace rt::perf {

std::function<int()> add_accuracy_command(CLI::App& app) {
  app.add_subcommand("accuracy", "Ground truth, then one knob at a time: time, rays and error");
  return [] {
    fmt::print(stderr, "rt-perf: accuracy is not implemented yet\n");
    return 1;
  };
}

}  // namespace rt::perf
