#pragma once
/// @file
/// The demo: the simulated office recorded six times, integrated, registered, built into a 4D
/// map, its changes found and scored against the simulator's truth, and a report with pictures.

#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "chronomap/pipeline/progress.h"

namespace chronomap {

/// What runDemo() does.
struct DemoSettings {
  std::filesystem::path output = "chronomap-demo";  ///< folder to write
  uint64_t seed = 1;                                ///< of the simulation
  double resolution_scale = 0.5;                    ///< image size relative to 640 x 480
  bool fast = true;                                 ///< fast mode, else exact ray casting
  Progress progress;
};

/// What runDemo() found.
struct DemoResult {
  std::filesystem::path report;  ///< report.md
  std::filesystem::path images;  ///< the pictures' folder
  std::filesystem::path map;     ///< the 4D map
  std::filesystem::path tour;    ///< tour.html: the 4D map in the browser (view/tour.h)
  size_t sessions = 0, frames = 0, events = 0;
  size_t nodes_4d = 0;
  uint64_t nodes_separate = 0;       ///< the session maps' nodes on their own
  double precision = 0.0, recall = 0.0;  ///< occupied voxels against the truth, registered, mean over sessions
  double precision_as_recorded = 0.0, recall_as_recorded = 0.0;
  uint64_t changed_voxels = 0;       ///< voxels of the 4D map that changed at least once
  size_t events_observable = 0, events_found = 0, false_components = 0;
  double seconds = 0.0;
};

/// Simulates the office preset into `output/data`, integrates every session with its estimated
/// poses, registers them to their consensus (x, y, heading and drift fitted on points, as
/// `chronomap build --register --register-drift 20 --register-planar --register-points`), builds
/// the 4D map, diffs and segments consecutive sessions, scores everything against the truth and
/// writes report.md with pictures and tour.html, the map in the viewer as one file.
DemoResult runDemo(const DemoSettings& settings);

}  // namespace chronomap
