#pragma once
// rt-perf intersect: per scene, Embree build time and memory (per build quality, robust on/off),
// throughput of Embree and of the reference on camera, shadow and random rays, and agreement;
// a scaling mode over procedural meshes.

#include <functional>

#include <CLI/CLI.hpp>

namespace rt::perf {

// Registers the `intersect` subcommand on `app`; the returned function runs it once parsed and
// returns the exit status.
std::function<int()> add_intersect_command(CLI::App& app);

}  // namespace rt::perf
