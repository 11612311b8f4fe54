#include "progress.h"

#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <memory>

namespace chronomap::cli {

ProgressBar::ProgressBar(std::string label, size_t total)
    : label_(std::move(label)), total_(total), enabled_(!label_.empty() && ::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()), last_() {}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(size_t done) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (done < total_ && now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  constexpr int kWidth = 30;
  const double frac = total_ ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const int filled = static_cast<int>(frac * kWidth);
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double eta = frac > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
  std::fprintf(stderr, "\r%s [%.*s%*s] %zu/%zu  %.1fs elapsed, %.1fs left ", label_.c_str(), filled,
               "##############################", kWidth - filled, "", done, total_, elapsed, eta);
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  if (enabled_ && drawn_) {
    std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
  }
  drawn_ = false;
}

Progress terminalProgress(bool quiet) {
  // One bar at a time: a new label starts a new bar, the last unit of the work clears it.
  struct Current {
    std::string label;
    std::unique_ptr<ProgressBar> bar;
  };
  auto current = std::make_shared<Current>();
  Progress p;
  if (!quiet) p.step = [](const std::string& message) { std::cerr << message << "\n"; };
  p.work = [current](const std::string& label, size_t done, size_t total) {
    if (!current->bar || current->label != label) {
      current->bar = std::make_unique<ProgressBar>(label, total);
      current->label = label;
    }
    current->bar->update(done);
    if (done >= total) current->bar.reset();
  };
  return p;
}

}  // namespace chronomap::cli
