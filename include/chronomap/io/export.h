#pragma once
/// @file
/// Exports of session maps to formats other tools open.

#include <filesystem>

#include "chronomap/analysis/segment.h"
#include "chronomap/io/png.h"
#include "chronomap/octree/session_map.h"

namespace chronomap::io {

/// Writes the centres of occupied unit voxels with their mean colour as a binary PLY.
/// @return the number of points written.
size_t exportOccupiedPly(const std::filesystem::path& path, const SessionMap& map);

/// Writes an OctoMap ColorOcTree (.ot) that octovis opens: every known voxel with the log-odds
/// of its probability (clamped to OctoMap's default thresholds) and its mean colour; compressed
/// free nodes are written at their own size.
/// @return the number of OctoMap leaf nodes after pruning.
size_t exportOctomap(const std::filesystem::path& path, const SessionMap& map);

/// Settings of a top-view picture.
struct TopViewSettings {
  /// Pixels per unit voxel edge.
  int pixels_per_voxel = 2;
  /// Colour of columns with free voxels but no occupied one.
  Rgb free_color{225, 232, 240};
  /// Colour of columns never observed.
  Rgb unknown_color{40, 40, 48};
};

/// Renders the map seen from above (+z down onto the x-y plane, x to the right, y up): each
/// column shows its highest occupied voxel in its mean colour, shaded by height; columns with
/// only free voxels are light, unobserved ones dark.
/// @throw DataError when the map is empty or the picture would exceed 8192 pixels a side.
ImageRgb renderTopView(const SessionMap& map, const TopViewSettings& settings = {});

/// The top view of `background`, faded, with the changed cells of `diff` drawn over it from above
/// (appeared green, vanished red) and each component of `segmentation` framed and labelled with
/// its id. @throw DataError as renderTopView.
ImageRgb renderChangeView(const SessionMap& background, const DiffMap& diff, const Segmentation& segmentation,
                          const TopViewSettings& settings = {});

}  // namespace chronomap::io
