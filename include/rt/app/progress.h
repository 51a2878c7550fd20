#pragma once
// A throttled one-line progress bar on stderr.

#include <chrono>
#include <string>

namespace rt {

// Draws "label [#####.....]  45%  1.2 s, ~1 s left" on stderr, redrawn at most every 100 ms, only when stderr
// is a terminal and `enabled`. finish() clears the line. Not thread-safe: callers serialise.
class ProgressBar {
 public:
  ProgressBar(std::string label, bool enabled);
  void update(double fraction);
  void finish();

 private:
  std::string label_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace rt
