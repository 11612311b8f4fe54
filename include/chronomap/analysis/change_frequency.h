#pragma once
/// @file
/// How often each part of the place changed: per-voxel counts of state changes between two
/// times of a 4D map (the thesis' Figure 6b).

#include <cstdint>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// A unit voxel and how many times its stored state changed.
struct VoxelChangeCount {
  VoxelKey key;
  uint32_t count = 0;
};

/// The change counts of a 4D map over a time interval.
struct ChangeFrequency {
  /// Unit voxels that changed at least the asked number of times (uniform cubes expanded into
  /// their voxels), in the map's traversal order.
  std::vector<VoxelChangeCount> voxels;
  /// histogram[n]: how many unit voxels changed exactly n times (n >= 1; index 0 stays 0), over
  /// every voxel, whatever the least count asked for.
  std::vector<uint64_t> histogram;
  /// The most changes of any voxel in `voxels` (0 when empty).
  uint32_t max_count = 0;

  /// Unit voxels that changed at least once.
  uint64_t changedVoxels() const;
};

/// The histogram of change counts of every unit voxel in (from_s, to_s] (as
/// ChangeFrequency::histogram), without listing the voxels.
std::vector<uint64_t> changeHistogram(const TemporalMap& map, double from_s, double to_s);

/// Every unit voxel whose state changed at least `min_changes` times in (from_s, to_s], with
/// the histogram of all counts. A change is a stored entry after a voxel's first observation.
/// @throw UsageError when min_changes is 0 or to_s lies before from_s.
ChangeFrequency changeFrequency(const TemporalMap& map, double from_s, double to_s, uint32_t min_changes);

}  // namespace chronomap
