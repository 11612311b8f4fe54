#pragma once
// Progress on stderr: a bar drawn only when stderr is a terminal, and the adapter that turns the
// library's progress callbacks into bars and step lines.

#include <chrono>
#include <cstddef>
#include <string>

#include "chronomap/pipeline/progress.h"

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

/// Progress for a command: each step's message as a line on stderr (none when `quiet`, as with
/// --json) and a bar for each piece of work with a label.
Progress terminalProgress(bool quiet);

}  // namespace chronomap::cli
