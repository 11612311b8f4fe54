#pragma once
/// @file
/// The simulator's ground-truth occupancy: the scene's parts voxelised as solid, and how well a
/// map's occupied voxels match it.

#include <cstddef>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/sim/scene.h"

namespace chronomap {

/// Unit voxels that overlap a present part, parts being solid (the ground-truth occupancy),
/// sorted in Morton order.
std::vector<VoxelKey> truthOccupancy(const SceneState& state, const KeyGrid& grid);
/// The same for one object.
std::vector<VoxelKey> objectVoxels(const Object& object, const KeyGrid& grid);

/// How well a map's occupied voxels match the ground truth.
struct OccupancyScore {
  size_t predicted = 0;      ///< occupied unit voxels of the map
  size_t truth_known = 0;    ///< truth voxels the map observed (free or occupied)
  size_t true_positive = 0;  ///< occupied in both
  double precision = 0.0;    ///< true_positive / predicted
  double recall = 0.0;       ///< true_positive / truth_known
};
/// Scores `map` against truth voxels sorted in Morton order (truthOccupancy's order).
OccupancyScore scoreOccupancy(const SessionMap& map, const std::vector<VoxelKey>& truth);

}  // namespace chronomap
