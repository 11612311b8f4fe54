#pragma once
/// @file
/// Maps seen from above: a session map's top view, and the changes of a diff drawn over one.

#include <vector>

#include <Eigen/Core>

#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/core/image.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Settings of a top-view picture.
struct TopViewSettings {
  /// Pixels per unit voxel edge.
  int pixels_per_voxel = 2;
  /// Colour of columns with free voxels but no occupied one.
  Rgb free_colour{225, 232, 240};
  /// Colour of columns never observed.
  Rgb unknown_colour{40, 40, 48};
};

/// Renders the map seen from above (+z down onto the x-y plane, x to the right, y up): each
/// column shows its highest occupied voxel in its mean colour, shaded by height; columns with
/// only free voxels are light, unobserved ones dark.
/// @throw DataError when the map is empty or the picture would exceed 8192 pixels a side.
ImageRgb renderTopView(const SessionMap& map, const TopViewSettings& settings = {});

/// A costmap as a picture, one pixel a cell, the highest y at the top: unknown grey, free white
/// through red with the cost, inscribed dark red, lethal black.
ImageRgb renderCostmap(const Costmap& costmap);

/// The top view of `background`, faded, with the changed cells of `diff` drawn over it from above
/// (appeared green, vanished red) and each component of `segmentation` framed and labelled with
/// its id. @throw DataError as renderTopView.
ImageRgb renderChangeView(const SessionMap& background, const DiffMap& diff, const Segmentation& segmentation,
                          const TopViewSettings& settings = {});

/// Points seen from above: each pixel of `metres_per_pixel` shows the highest point that falls
/// in it, in its colour, on white; at most 4000 pixels a side (points beyond are left out).
/// `colors` is as long as `points`. @throw DataError when there is no point.
ImageRgb renderPointsTopView(const std::vector<Eigen::Vector3f>& points, const std::vector<Rgb>& colours,
                             double metres_per_pixel);

}  // namespace chronomap
