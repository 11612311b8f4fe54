#pragma once
/// @file
/// Line plots with axes and a legend, for reports.

#include <string>
#include <vector>

#include "chronomap/core/image.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// One line of a plot.
struct PlotSeries {
  std::string label;
  Rgb colour;
  std::vector<double> x, y;
};

/// Settings of a line plot.
struct PlotSettings {
  std::string title;
  std::string x_label;
  std::string y_label;
  uint32_t width = 800;
  uint32_t height = 500;
};

/// Draws the series on common axes that start at zero, with ticks, labels and a legend.
/// @throw UsageError when a series has x and y of different lengths or no finite point.
ImageRgb renderLinePlot(const std::vector<PlotSeries>& series, const PlotSettings& settings);

/// Nodes against sessions: two cumulative series, one point per session (`separate`: the
/// session maps stored on their own, `four_d`: the 4D map), as a line plot titled `title`.
ImageRgb renderStoragePlot(const std::vector<double>& separate, const std::vector<double>& four_d,
                           const std::string& title = "Storage: nodes after each session");

/// The storage plot of a 4D map: the nodes each session holds on its own, and the nodes it
/// added to the map, summed in time order. @throw DataError when the map holds no session.
ImageRgb renderStoragePlot(const TemporalMap& map);

}  // namespace chronomap
