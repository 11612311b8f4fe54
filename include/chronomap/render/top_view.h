#pragma once
/// @file
/// Maps seen from above: a session map's top view, and the changes of a diff drawn over one.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/core/image.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// A named area of the map, drawn with its name inside it (a room of the simulator's scene).
struct MapArea {
  std::string name;
  Eigen::AlignedBox2d area_m;  ///< x, y in metres
};

/// Settings of a top-view picture.
struct TopViewSettings {
  /// Pixels per unit voxel edge.
  int pixels_per_voxel = 2;
  /// Colour of columns seen free where nothing was hit: floor the sensor looked across but whose
  /// surface it never measured (too flat, too far, too dark). A quiet floor tone, so that it does
  /// not look like a hole in the floor; the legend names it.
  Rgb free_colour{122, 118, 110};
  /// Colour of columns never observed.
  Rgb unknown_colour{40, 40, 48};
  /// Frame the map: axes in metres on its left and bottom edges, a scale bar and a legend below.
  /// Off, the picture is the map alone, one pixel block per voxel column.
  bool axes = true;
  /// Colour of the axes, their numbers, the scale bar and the legend's text, on white.
  Rgb axes_colour{30, 30, 30};
  /// Scale of the text of the axes, the scale bar and the legend (the 5x7 font).
  int text_scale = 1;
  /// Named areas (rooms): each name is drawn inside its area, at its top, in the largest text
  /// (scale 2 or 1) that fits the area's width; a name that fits at neither is left out.
  std::vector<MapArea> areas;
  /// Colour of the areas' names (a quiet blue-grey none of the change colours uses), drawn with a
  /// one-pixel light halo.
  Rgb area_name_colour{60, 60, 110};
};

/// Where the map lies in a top-view picture: the metres of its top left corner, the scale, and
/// the pixel where that corner is drawn (the frame's left and top margins).
struct TopViewFrame {
  double x_min_m = 0.0;  ///< x of the map's left edge
  double y_max_m = 0.0;  ///< y of the map's top edge (y points up)
  double metres_per_pixel = 0.05;
  int left_px = 0;   ///< the map's left edge in the picture
  int top_px = 0;    ///< the map's top edge in the picture
  int width_px = 0;  ///< the map's width in the picture
  int height_px = 0;

  /// The picture position (x right, y down; not rounded) of the point (x, y) in metres.
  Eigen::Vector2d pixelOf(const Eigen::Vector2d& p_m) const {
    return {left_px + (p_m.x() - x_min_m) / metres_per_pixel, top_px + (y_max_m - p_m.y()) / metres_per_pixel};
  }
};

/// A picture of a map from above and where the map lies in it.
struct TopView {
  ImageRgb image;
  TopViewFrame frame;
  /// The scale bar's length in metres (0 without axes): the longest of 1, 2 and 5 times a power
  /// of ten that fits in a quarter of the map's width (at least 40 pixels).
  double scale_bar_m = 0.0;
  /// The scale bar's pixels (its top row is the bar, drawn from the map's left edge).
  int scale_bar_y_px = 0;
};

/// The map seen from above (+z down onto the x-y plane, x to the right, y up): each column shows
/// its highest occupied voxel in its mean colour, shaded by height; columns seen free where
/// nothing was hit are drawn in `free_colour`, unobserved ones dark. With `axes`: framed with
/// axes in metres (ticks at 1, 2 or 5 times a power of ten, at least 50 pixels apart), a scale bar
/// and a legend; the areas' names are drawn inside them.
/// @throw DataError when the map is empty or the map would exceed 8192 pixels a side.
TopView drawTopView(const SessionMap& map, const TopViewSettings& settings = {});

/// drawTopView(map, settings).image.
ImageRgb renderTopView(const SessionMap& map, const TopViewSettings& settings = {});

/// A costmap as a picture, one pixel a cell, the highest y at the top: unknown grey, free white
/// through red with the cost, inscribed dark red, lethal black.
ImageRgb renderCostmap(const Costmap& costmap);

/// The top view of `background`, faded, with the changed cells of `diff` drawn over it from above
/// (appeared green, vanished red) and each component of `segmentation` framed and labelled with
/// its id, the labels placed so that none covers another (placeLabels). drawChanges
/// (render/change_view.h) draws the objects of findChanges instead. @throw DataError as drawTopView.
ImageRgb renderChangeView(const SessionMap& background, const DiffMap& diff, const Segmentation& segmentation,
                          const TopViewSettings& settings = {});

/// Points seen from above: each pixel of `metres_per_pixel` shows the highest point that falls
/// in it, in its colour, on white; at most 4000 pixels a side (points beyond are left out).
/// `colors` is as long as `points`. @throw DataError when there is no point.
ImageRgb renderPointsTopView(const std::vector<Eigen::Vector3f>& points, const std::vector<Rgb>& colours,
                             double metres_per_pixel);

}  // namespace chronomap
