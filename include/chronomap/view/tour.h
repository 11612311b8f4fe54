#pragma once
/// @file
/// The tour: one self-contained HTML file with the viewer's page, its script and a 4D map's
/// data inside, that opens from disk with no server (`chronomap export MAP.cmap -o tour.html`).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/temporal/temporal_map.h"
#include "chronomap/view/scene.h"

namespace chronomap::view {

/// Bounds of a tour, so that the file stays small enough to send.
struct TourSettings {
  /// Cells drawn: every voxel ever occupied, coarsened to the finest level of detail that fits.
  size_t max_voxels = 400000;
  /// Sessions a tour holds; a map with more is refused (use `chronomap view`).
  size_t max_sessions = 64;
  /// Changed cells per diff (the objects are always kept whole).
  size_t max_diff_cells = 100000;
  /// How diffs are computed and segmented (view::changeSettings() by default).
  DiffSettings diff = changeSettings().diff;
  SegmentSettings segment = changeSettings().segment;
};

/// What a tour holds.
struct TourReport {
  size_t cells = 0;   ///< cells of the voxel timeline
  int level = 0;      ///< their level of detail (0 = unit voxels)
  size_t diffs = 0;   ///< session pairs with their objects (consecutive ones, and first to last)
  size_t bytes = 0;   ///< size of the HTML file
  /// Occupied unit voxels per session (as `chronomap snapshot` counts them).
  std::vector<uint64_t> occupied_voxels;
};

/// The tour's data as a packet (packet.h): header {"map": mapInfoJson, "level", "cells",
/// "occupied_voxels": [per session], "diffs": [{"from", "to", "first", "count", "cells",
/// "components": [...], "dropped"}]}, arrays "keys" (u16 x, y, z), "levels", "colors",
/// "changes" (stored changes of the cell's busiest voxel), "states" (per cell, 2 bits per
/// session in session order, 4 sessions a byte, lowest bits first: 0 unknown, 1 free,
/// 2 occupied; the cell's most occupied state), then the diffs' cells one diff after another:
/// "diff_keys", "diff_levels", "diff_kinds", "diff_component".
/// @throw UsageError when the map holds no session or more than max_sessions.
std::string tourData(const TemporalMap& map, const std::string& name, const TourSettings& settings,
                     TourReport* report = nullptr);

/// Writes the tour to `path` atomically. @throw IoError when it cannot be written.
TourReport writeTour(const std::filesystem::path& path, const TemporalMap& map, const std::string& name,
                     const TourSettings& settings = {});

}  // namespace chronomap::view
