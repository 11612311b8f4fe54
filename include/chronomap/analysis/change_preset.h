#pragma once
/// @file
/// The recommended settings for "what changed between two visits, and which objects": the one
/// place that says them. The demo and its report, the viewer, alerts and the benchmarks start
/// from these (docs/changes.md explains each rule and how its constant was chosen).

#include <cstdint>
#include <string>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/moves.h"
#include "chronomap/analysis/segment.h"

namespace chronomap {

/// The smallest component that counts as an object: 20 voxels (2.5 litres at 0.05 m).
inline constexpr uint64_t kRecommendedMinObjectVoxels = 20;

/// A diff, the segmentation of its changes into objects, and which objects are one moved.
struct ChangeSettings {
  DiffSettings diff;
  SegmentSettings segment;
  MoveSettings moves;
  /// @throw UsageError for bad diff, segment or move settings.
  void validate() const;
};

/// The recommended settings for registered sessions: band mode; the neighbourhood rule at one
/// voxel with the shift test at half a voxel (DiffSettings::kRecommendedMinShift); the kept-surface
/// rule at DiffSettings::kRecommendedKeptSurfaceRadius; the dark-surface rule at
/// DiffSettings::kDarkSurfaceRadius; objects of vertex-connected changes of at least
/// kRecommendedMinObjectVoxels voxels. The same as `chronomap diff --mode band --neighbourhood 1
/// --min-shift 0.5 --kept-surface 3 --dark-surface 2` and `segment --connectivity vertex
/// --min-voxels 20`; a vanished and an appeared object that look alike are one moved
/// (MoveSettings' defaults, as alerts pairs them). The defaults of findChanges() and of
/// `chronomap diff`.
ChangeSettings recommendedChangeSettings();

/// The plain thesis diff: hard mode with every real-data rule off (DiffSettings{}), every
/// face-connected component an object (SegmentSettings{}), no moves. `chronomap diff --preset raw`.
ChangeSettings rawChangeSettings();

/// The settings a preset's name gives: "recommended" or "raw" (`chronomap diff --preset`, the
/// Python package's `preset`).
/// @throw UsageError naming `preset` and the presets for any other name.
ChangeSettings changeSettingsNamed(const std::string& preset);

}  // namespace chronomap
