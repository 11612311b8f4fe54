#pragma once
/// @file
/// What the 4D viewer draws, computed from a 4D map: the occupied voxels at a time with a level
/// of detail that keeps their number under a budget, the objects that changed between two times,
/// and one voxel's history. The server (server.h) and the tour file (tour.h) encode these.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// The coarsest level of detail the viewer uses: cubes of 2^8 voxels per axis.
inline constexpr int kMaxLevel = 8;
/// The largest cube whose voxels a history request searches (2^6 voxels per axis).
inline constexpr int kMaxHistoryLevel = 6;

/// What snapshotVoxels() returns.
struct SnapshotRequest {
  double time_s = 0.0;
  /// At most this many cells are returned: the finest level of detail whose occupied cells fit.
  size_t max_voxels = 200000;
  /// Never finer than this level (0 = unit voxels): a page may ask for a coarse picture first.
  int min_level = 0;
  /// Only voxels whose key lies in [lower, upper] (inclusive, per axis); every voxel if unset.
  std::optional<std::array<VoxelKey, 2>> region;
};

/// Occupied cells of a snapshot: cubes of 2^level voxels per axis in Morton order of their
/// corners. A cell is occupied when one of its unit voxels is.
struct VoxelSet {
  int level = 0;                 ///< the level of detail chosen
  std::vector<VoxelKey> keys;    ///< lower corners
  std::vector<uint8_t> levels;   ///< per cell (a level above `level` only for an occupied uniform cube)
  std::vector<Rgb> colours;       ///< mean colour of the occupied voxels in the cell
  std::vector<uint8_t> changes;  ///< most state changes of a voxel in the cell up to the time (saturates at 255)
  std::vector<uint16_t> since;   ///< latest session (rank) that set an occupied voxel's state
  std::vector<uint32_t> members; ///< occupied unit voxels in the cell
  uint64_t occupied_voxels = 0;  ///< occupied unit voxels in the region before level of detail
  std::optional<uint32_t> rank;  ///< session valid at the time (none before the first)
};

/// The occupied voxels of `map` at request.time_s, coarsened to the finest level (not below
/// min_level, at most kMaxLevel) at which they fit in request.max_voxels cells; at kMaxLevel
/// the cells are returned even when more.
/// @throw UsageError for a max_voxels of 0 or a min_level outside 0..kMaxLevel.
VoxelSet snapshotVoxels(const TemporalMap& map, const SnapshotRequest& request);

/// What diffObjects() compares and how it groups.
struct DiffRequest {
  double t0_s = 0.0;
  double t1_s = 0.0;
  DiffSettings diff;
  SegmentSettings segment;
};

/// The changes between two times of a 4D map and the objects they form.
struct DiffObjects {
  DiffMap diff;
  Segmentation segmentation;
  /// Per cell of diff.cells(): the id of its component, 0 when it belongs to none (dropped).
  std::vector<uint32_t> component_of_cell;
};

/// The diff and segmentation settings the viewer uses unless told otherwise: those of `chronomap
/// demo`, which find the simulated office's changes as objects (band mode, a neighbourhood of
/// one voxel with the recommended minimum shift, vertex connectivity, at least 20 voxels); the
/// same as `chronomap diff --mode band --neighbourhood 1 --min-shift 0.5` and `chronomap segment
/// --connectivity vertex --min-voxels 20`.
DiffRequest changeSettings();

/// The diff of `map` between the two times and its segmentation (the same calls as
/// `chronomap diff` and `chronomap segment`).
DiffObjects diffObjects(const TemporalMap& map, const DiffRequest& request);

/// One component as JSON: id, kind, voxels, volume, box, centroid (metres) and colour.
nlohmann::json componentJson(const Component& component);

/// The history of a voxel for the page: the key asked for when `level` is 0; otherwise, of
/// the cube of 2^level voxels per axis at `corner`, the unit voxel with the most stored entries
/// among those ever occupied (the first in Morton order on ties), or the corner.
/// @throw UsageError for a level outside 0..kMaxHistoryLevel or a corner not aligned to it.
nlohmann::json historyJson(const TemporalMap& map, const VoxelKey& corner, int level);

/// The map's metadata for the page: resolution, the sessions (rank, time, ISO time, name) and
/// node counts.
nlohmann::json mapInfoJson(const TemporalMap& map, const std::string& name);

}  // namespace chronomap
