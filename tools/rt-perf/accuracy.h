#pragma once
// rt-perf accuracy: renders a ground truth with the most accurate settings, then sweeps one knob at
// a time and reports render time, rays and error against the ground truth (CSV, Markdown, plots).

#include <functional>

#include <CLI/CLI.hpp>

namespace rt::perf {

// Registers the `accuracy` subcommand on `app`; the returned function runs it once parsed and
// returns the exit status.
std::function<int()> add_accuracy_command(CLI::App& app);

}  // namespace rt::perf
