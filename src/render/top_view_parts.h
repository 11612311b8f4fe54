#pragma once
// The parts every top-view picture is made of (top_view.cpp, frame.cpp, change_view.cpp): the
// map's columns as pixels, the names of areas on them, the labels of objects, and the frame
// around them (axes, scale bar, legend).

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/image.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/render/labels.h"
#include "chronomap/render/top_view.h"

namespace chronomap::render_detail {

/// The map's columns, one block of pixels each, and where they lie in metres (the frame's
/// margins are zero: the raster's own pixels).
struct Raster {
  ImageRgb image;
  TopViewFrame frame;
};

/// The columns of `map` inside `window_m` (all of them when the window is empty), as
/// drawTopView describes. @throw DataError when the map (or the part in the window) is empty or
/// too large.
Raster rasterOf(const SessionMap& map, const TopViewSettings& settings, const Eigen::AlignedBox2d& window_m = {});

/// A background colour faded so that the changes drawn over it stand out.
Rgb faded(Rgb c);

/// Draws each area's name inside it (see TopViewSettings::areas) and returns the boxes the names
/// took, for the labels to avoid.
std::vector<PixelBox> drawAreaNames(ImageRgb& raster, const TopViewFrame& frame, const std::vector<MapArea>& areas,
                                    Rgb colour);

/// Draws `text` with a one-pixel light halo, so that it reads on any background.
void drawHaloText(ImageRgb& image, int x, int y, const std::string& text, Rgb colour, int scale);

/// One label to draw: its text and colour and the box (raster pixels) of what it names.
struct Label {
  std::string text;
  Rgb colour;
  PixelBox target;
};

/// Draws the labels where placeLabels puts them, avoiding `obstacles`, with a leader line from
/// each label moved away to its target.
void drawLabels(ImageRgb& raster, const std::vector<Label>& labels, const std::vector<PixelBox>& obstacles, int scale);

/// One entry of a picture's legend: a swatch of `colour` (an arrow when `arrow`) and its text.
struct LegendEntry {
  std::string text;
  Rgb colour;
  bool arrow = false;
};

/// The legend entries of a top view's background: floor seen with nothing hit, and not seen,
/// each through `tone` (the change views fade them).
std::vector<LegendEntry> backgroundLegend(const TopViewSettings& settings, Rgb (*tone)(Rgb));

/// The raster in its picture: with settings.axes, framed by axes in metres, a scale bar and the
/// legend; without, the raster alone.
TopView framed(Raster raster, const TopViewSettings& settings, const std::vector<LegendEntry>& legend);

}  // namespace chronomap::render_detail
