#pragma once
// Command-line usage errors as rt words them: flag-value validators whose messages name what is
// wrong with the value, "did you mean" suggestions for mistyped commands and flags, and one-line
// messages for CLI11's parse errors. Internal to the app module.

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace rt {

// Accepts a whole number (decimal, optional sign) in [lo, hi]: "'abc' is not a whole number",
// "70000 is outside 1..65536".
CLI::Validator whole_number_in(long long lo, long long hi);

// Accepts a finite decimal number in [lo, hi].
CLI::Validator number_in(double lo, double hi);

// Accepts exactly one of `values`, suggesting the nearest on a typo.
CLI::Validator one_of(const std::vector<std::string>& values);

// Accepts --ray-offset's values: robust or fixed:EPS with a finite EPS > 0.
extern const CLI::Validator kRayOffset;

// The name in `names` closest to `typed` by edit distance (insertions, deletions, substitutions
// and swaps of neighbours each count 1), if it is close enough to be a likely typo: at most 1 edit
// for names up to 4 characters, else at most 2 and less than half the length. Empty otherwise.
std::string nearest_name(const std::string& typed, const std::vector<std::string>& names);

// The one-line message for a command line that does not parse (`error` from app.parse(argc, argv)),
// without the "rt: error: " prefix: the problem, a suggestion for a mistyped command or flag, and
// where to find the options. Help and version requests (exit code 0) are not errors and are not
// passed here.
std::string usage_message(const CLI::App& app, const CLI::ParseError& error, int argc, const char* const* argv);

}  // namespace rt
