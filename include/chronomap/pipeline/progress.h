#pragma once
/// @file
/// How pipeline calls report what they are doing: to a callback, never to a terminal. The
/// command line draws bars from it; bindings forward it to their language; tests ignore it.

#include <cstddef>
#include <functional>
#include <string>

namespace chronomap {

/// Callbacks for long work; either may be empty. Either may throw to stop the work (the Python
/// bindings do on Ctrl-C): the exception leaves the pipeline call as an error would, and nothing
/// is written.
struct Progress {
  /// A step begins: one line for a person ("registering 6 session(s), 3 round(s)").
  std::function<void(const std::string& message)> step;
  /// Work within a step advanced: `done` of `total` units of the work named `label`. Work with
  /// an empty label runs in parallel with other work and is not reported.
  std::function<void(const std::string& label, size_t done, size_t total)> work;

  void say(const std::string& message) const {
    if (step) step(message);
  }
  void advance(const std::string& label, size_t done, size_t total) const {
    if (work && !label.empty()) work(label, done, total);
  }
};

}  // namespace chronomap
