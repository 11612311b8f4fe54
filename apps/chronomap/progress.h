#pragma once
// A progress bar on stderr, drawn only when stderr is a terminal.

#include <chrono>
#include <cstddef>
#include <string>

namespace chronomap::cli {

class ProgressBar {
 public:
  ProgressBar(std::string label, size_t total);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  /// Redraws with `done` of `total` units finished (at most ten times a second). A bar without
  /// a label never draws (work running in parallel, where bars would overwrite each other).
  void update(size_t done);
  /// Clears the bar.
  void finish();

 private:
  std::string label_;
  size_t total_;
  bool enabled_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace chronomap::cli
