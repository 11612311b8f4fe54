#pragma once
/// @file
/// Drawing on raster images: text with a built-in 5x7 pixel font (upper case, digits and common
/// punctuation), rectangles and lines.

#include <string>

#include "chronomap/core/image.h"

namespace chronomap {

/// Draws `text` with the built-in font at pixel (x, y) (top left), scaled by `scale`.
/// Lower-case letters are drawn as capitals, but for 'x' and an 'm' that stands alone between
/// non-letters (the unit metre: "1 m", "x (m)"), which keep lower-case glyphs; characters without
/// a glyph are drawn as a box.
void drawText(ImageRgb& image, int x, int y, const std::string& text, Rgb colour, int scale = 1);
/// Width in pixels of `text` drawn at `scale`.
int textWidth(const std::string& text, int scale = 1);
/// Fills a rectangle, clipped to the image.
void fillRect(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb colour);
/// Draws a line (Bresenham), clipped to the image, `thickness` pixels wide.
void drawLine(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb colour, int thickness = 1);
/// Draws an arrow from (x0, y0) to (x1, y1): a line `thickness` wide and a filled head whose
/// length is `head_px` (at most half the arrow's length), its tip at (x1, y1). Clipped.
void drawArrow(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb colour, int thickness = 2, int head_px = 10);

}  // namespace chronomap
