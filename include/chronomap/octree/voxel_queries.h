#pragma once
/// @file
/// Whole-map questions of a session map as flat arrays: where its occupied voxels are, and the
/// box of everything it knows. Exports and the Python bindings read maps through these.

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "chronomap/core/counters.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Centres of voxels and their mean colours, one per voxel, in Morton order.
struct VoxelCentres {
  std::vector<Eigen::Vector3d> centers_m;
  std::vector<Rgb> colours;
};

/// The occupied unit voxels of `map` (compressed nodes are free, so never among them).
VoxelCentres occupiedCentres(const SessionMap& map);

/// Known-free leaves: unit voxels and compressed cubes, each once, with its edge length.
struct FreeLeaves {
  std::vector<Eigen::Vector3d> centers_m;  ///< centre of each leaf's cube
  std::vector<double> sizes_m;             ///< edge length of each leaf's cube (resolution × 2^level)
};
/// The free leaves of `map`, in Morton order (a compressed cube is one entry, not its voxels).
FreeLeaves freeLeaves(const SessionMap& map);

/// The box of every known leaf (lower corner of the lowest, upper corner of the highest), in
/// metres; nothing for an empty map.
struct Bounds {
  Eigen::Vector3d min_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_m = Eigen::Vector3d::Zero();
};
std::optional<Bounds> knownBounds(const SessionMap& map);

}  // namespace chronomap
