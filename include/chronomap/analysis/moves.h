#pragma once
/// @file
/// Which vanished and appeared objects of one diff are one object moved: the halves look alike
/// (size, height, colour). The one rule for it: findChanges() (analysis/changes.h) reports such
/// pairs as moves, and findAlerts() (analysis/alerts.h) scores them as one.

#include <cstddef>
#include <vector>

#include "chronomap/analysis/segment.h"

namespace chronomap {

/// When a vanished and an appeared object of one diff are one object moved.
struct MoveSettings {
  bool pair = true;  ///< look for moves at all
  /// The larger object holds at most this many times the voxels of the smaller one (the two
  /// halves are seen from different places, so rarely in full both times); with
  /// alike_footprints, their footprints' longer sides, and shorter sides, lie within this ratio
  /// too (each side with 0.1 m added: a thin side is thin whatever its exact width).
  double max_size_ratio = 2.0;
  /// Their heights (bounding boxes' z extents) differ by at most this, metres.
  double max_height_difference_m = 0.15;
  /// Their mean colours differ by at most this (8-bit RGB distance; the light of the two
  /// sessions differs, so a chair's two halves are not quite the same colour).
  double max_colour_distance = 60.0;
  /// The footprints must be alike too (max_size_ratio on their sides, above). Off by default:
  /// chosen on the office's seed 1 it removed a false move (a door leaf paired with a robot) and
  /// lost no true one, but on seed 2 it lost both true moves and made a false one
  /// (bench/change_eval, docs/changes.md): a half seen from another side has another footprint.
  bool alike_footprints = false;
  /// @throw UsageError for a ratio below 1 or a distance that is negative or not finite.
  void validate() const;
};

/// A vanished object and the appeared object that is the same one moved: indices into the
/// component list given to pairMoves().
struct MovePair {
  size_t vanished = 0;
  size_t appeared = 0;
};

/// The moves among `components`: each vanished component paired with the appeared one most
/// alike (each difference as a share of what MoveSettings allows, summed), the likeliest pairs
/// first, each component in one move at most. In the order they were matched; empty when
/// settings.pair is false.
/// @throw UsageError for bad settings.
std::vector<MovePair> pairMoves(const std::vector<Component>& components, const MoveSettings& settings = {});

}  // namespace chronomap
