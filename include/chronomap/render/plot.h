#pragma once
/// @file
/// Small raster drawings for reports: line plots with axes and a legend, and text, with a
/// built-in 5x7 pixel font (upper case, digits and common punctuation).

#include <string>
#include <vector>

#include "chronomap/io/png.h"

namespace chronomap::io {

/// One line of a plot.
struct PlotSeries {
  std::string label;
  Rgb color;
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

/// Draws `text` with the built-in font at pixel (x, y) (top left), scaled by `scale`.
/// Lower-case letters are drawn as capitals; characters without a glyph as a box.
void drawText(ImageRgb& image, int x, int y, const std::string& text, Rgb color, int scale = 1);
/// Width in pixels of `text` drawn at `scale`.
int textWidth(const std::string& text, int scale = 1);
/// Fills a rectangle, clipped to the image.
void fillRect(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb color);
/// Draws a line (Bresenham), clipped to the image, `thickness` pixels wide.
void drawLine(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb color, int thickness = 1);

}  // namespace chronomap::io
