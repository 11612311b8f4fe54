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

namespace chronomap {

/// Bounds of a tour, so that the file stays small enough to send.
struct TourSettings {
  /// Cells drawn: every voxel ever occupied, coarsened to the finest level of detail that fits.
  size_t max_voxels = 400000;
  /// Bytes of map data a tour may hold (before base64, which adds a third): the voxel timeline
  /// (11 bytes a cell, and 2 bits a session) and the diffs' cells (12 bytes each). A map whose
  /// tour would be larger is refused (use `chronomap view`, or a smaller max_voxels or
  /// max_diff_cells). Any number of sessions fits.
  size_t max_bytes = size_t{48} << 20;
  /// Changed cells per diff (the objects are always kept whole).
  size_t max_diff_cells = 100000;
  /// How diffs are computed and segmented (changeSettings() by default).
  DiffSettings diff = changeSettings().diff;
  SegmentSettings segment = changeSettings().segment;
};

/// What a tour holds.
struct TourReport {
  size_t cells = 0;   ///< cells of the voxel timeline
  int level = 0;      ///< their level of detail (0 = unit voxels)
  size_t diffs = 0;   ///< session pairs with their objects (consecutive ones, and first to last)
  size_t diff_cells = 0;  ///< changed cells of those diffs held (at most max_diff_cells each)
  size_t bytes = 0;   ///< size of the HTML file
  /// Occupied unit voxels per session (as `chronomap snapshot` counts them).
  std::vector<uint64_t> occupied_voxels;
};

/// The tour's data as a packet (packet.h): header {"map": mapInfoJson, "level", "cells",
/// "occupied_voxels": [per session], "diffs": [{"from", "to", "first", "count", "cells",
/// "components": [...], "objects": [changedObjectsJson of findChanges, as /api/diff?format=json],
/// "appeared_voxels", "vanished_voxels", "dropped"}]}, arrays "keys" (u16 x, y, z), "levels", "colors",
/// "changes" (stored changes of the cell's busiest voxel), "states" (per cell, 2 bits per
/// session in session order, 4 sessions a byte, lowest bits first: 0 unknown, 1 free,
/// 2 occupied; the cell's most occupied state), then the diffs' cells one diff after another:
/// "diff_keys", "diff_levels", "diff_kinds", "diff_component".
/// @throw UsageError when the map holds no session or its data would exceed max_bytes.
std::string tourData(const TemporalMap& map, const std::string& name, const TourSettings& settings,
                     TourReport* report = nullptr);

/// Writes the tour to `path` atomically. @throw IoError when it cannot be written.
TourReport writeTour(const std::filesystem::path& path, const TemporalMap& map, const std::string& name,
                     const TourSettings& settings = {});

}  // namespace chronomap
