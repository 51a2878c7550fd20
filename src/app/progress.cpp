#include "rt/app/progress.h"

#include <unistd.h>

#include <cstdio>

#include <fmt/format.h>

namespace rt {

ProgressBar::ProgressBar(std::string label, bool enabled)
    : label_(std::move(label)),
      enabled_(enabled && isatty(STDERR_FILENO)),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_ - std::chrono::seconds(1)) {}

void ProgressBar::update(double fraction) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (fraction < 1.0 && now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(fraction * kWidth);
  const double seconds = std::chrono::duration<double>(now - start_).count();
  // Remaining time by linear extrapolation, once enough is done for it to mean something.
  const std::string left = fraction >= 0.02 && fraction < 1.0
                               ? fmt::format(", ~{:.0f} s left", seconds * (1.0 - fraction) / fraction)
                               : "";
  fmt::print(stderr, "\r{} [{}{}] {:3.0f}%  {:.1f} s{}\033[K", label_, std::string(filled, '#'),
             std::string(kWidth - filled, '.'), 100.0 * fraction, seconds, left);
  std::fflush(stderr);
}

void ProgressBar::finish() {
  if (!enabled_) return;
  fmt::print(stderr, "\r\033[K");
  std::fflush(stderr);
}

}  // namespace rt
