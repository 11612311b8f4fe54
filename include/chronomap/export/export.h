#pragma once
/// @file
/// Exports of session maps to formats other tools open.

#include <filesystem>
#include <span>

#include "chronomap/analysis/diff.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Writes the centres of occupied unit voxels with their mean colour as a binary PLY.
/// @return the number of points written.
size_t exportOccupiedPly(const std::filesystem::path& path, const SessionMap& map);

/// Writes an OctoMap ColorOcTree (.ot) that octovis opens: every known voxel with the log-odds
/// of its probability (clamped to OctoMap's default thresholds) and its mean colour; compressed
/// free nodes are written at their own size.
/// @return the number of OctoMap leaf nodes after pruning.
size_t exportOctomap(const std::filesystem::path& path, const SessionMap& map);

/// Writes the centre of every unit voxel of `cells` (cells above unit level expanded) with the
/// cell's colour as a binary PLY. @return the number of points written.
size_t exportDiffPly(const std::filesystem::path& path, const DiffMap& diff, std::span<const ChangeCell> cells);

}  // namespace chronomap
