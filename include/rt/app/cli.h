#pragma once
// The `rt` command line: `rt render`, `rt view`, `rt merge`, `rt info`.

namespace rt {

// Runs the command line and returns the process exit status: 0 success, 1 bad input or a
// failure while rendering or writing, 2 a usage error. Never throws.
int run_cli(int argc, char** argv);

}  // namespace rt
