#pragma once
/// @file
/// Scoring detected changes against the simulator's ground truth (scene.json's events).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/analysis/segment.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/sim/scene.h"

namespace chronomap {

/// Reads the change events simulate() wrote into a simulation's scene.json.
/// @throw IoError, FormatError naming the file (unknown object or event kinds included).
std::vector<ChangeEvent> readTruthEvents(const std::filesystem::path& scene_json);

/// The events between sessions `from_session` and `from_session + 1`.
std::vector<ChangeEvent> eventsFrom(const std::vector<ChangeEvent>& events, uint32_t from_session);

/// Settings of the scoring.
struct ChangeScoreSettings {
  /// An event counts as observable when at least this many of its voxels are known (observed)
  /// in both session maps; the others could not have been seen and do not count.
  size_t min_observed_voxels = 20;
  /// A detected voxel matches an event voxel within this many voxels (Chebyshev distance): the
  /// estimated poses are off by a few centimetres, about a voxel.
  int match_tolerance_voxels = 1;
};

/// How detected changes between two sessions compare with the truth.
struct ChangeScore {
  size_t events = 0;             ///< events between the two sessions
  size_t events_observable = 0;  ///< events with enough voxels observed in both sessions
  size_t events_found = 0;       ///< observable events that a component overlaps
  size_t components = 0;
  size_t false_components = 0;   ///< components that overlap no event
  uint64_t changed_voxels = 0;       ///< appeared + vanished voxels of the diff
  uint64_t true_changed_voxels = 0;  ///< of those, voxels that match an event voxel
  uint64_t truth_voxels = 0;         ///< event voxels known in both sessions
  uint64_t truth_voxels_found = 0;   ///< of those, voxels matched by a changed voxel
  /// For each component (in order), the index into `events` it overlaps most, or -1.
  std::vector<int> component_event;
  /// The observable events no component overlaps, e.g. "chair 18 moved (session 0 -> 1, 312
  /// voxels observed)".
  std::vector<std::string> missed_events;

  double precision() const { return changed_voxels ? double(true_changed_voxels) / double(changed_voxels) : 1.0; }
  double recall() const { return truth_voxels ? double(truth_voxels_found) / double(truth_voxels) : 1.0; }
  ChangeScore& operator+=(const ChangeScore& o);
};

/// Scores a diff between sessions `before` and `after` and its segmentation against the events
/// between them.
ChangeScore scoreChanges(const DiffMap& diff, const Segmentation& segmentation, const std::vector<ChangeEvent>& events,
                         const SessionMap& before, const SessionMap& after, const ChangeScoreSettings& settings = {});

}  // namespace chronomap
