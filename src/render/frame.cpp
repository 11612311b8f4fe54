// The frame around a top view: axes in metres, a scale bar and a legend.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/render/draw.h"
#include "top_view_parts.h"

namespace chronomap::render_detail {

namespace {

constexpr Rgb kPaper{255, 255, 255};    // the frame's background
constexpr int kMinTickSpacing_px = 50;  // ticks at least this far apart
constexpr int kMinScaleBar_px = 40;     // the scale bar at least this long when the map allows
constexpr int kTick_px = 4;
constexpr int kPad_px = 6;

/// The smallest of 1, 2 and 5 times a power of ten that is at least `v` (> 0).
double niceAtLeast(double v) {
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= v * (1 - 1e-9)) return m * p;
  }
  return 10 * p;
}

/// The largest of 1, 2 and 5 times a power of ten that is at most `v` (> 0).
double niceAtMost(double v) {
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (double m : {5.0, 2.0, 1.0}) {
    if (m * p <= v * (1 + 1e-9)) return m * p;
  }
  return p;
}

/// A tick value as text: as many decimals as the step needs, no "-0".
std::string tickText(double v, double step) {
  const int decimals = step >= 1 ? 0 : step >= 0.1 ? 1 : 2;
  if (std::abs(v) < step * 1e-6) v = 0.0;
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", decimals, v);
  return text;
}

/// The tick values of [lo, hi] at `step`.
std::vector<double> ticks(double lo, double hi, double step) {
  std::vector<double> out;
  for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9; k += 1) out.push_back(k * step);
  return out;
}

/// Lays the legend's entries out in rows no wider than `width`; returns each entry's position
/// (relative to the legend's top left) and the legend's height.
std::pair<std::vector<std::pair<int, int>>, int> legendLayout(const std::vector<LegendEntry>& legend, int width,
                                                              int scale) {
  const int ch = 7 * scale, row = ch + 5, spacing = 14;
  std::vector<std::pair<int, int>> at;
  int x = 0, y = 0;
  for (const LegendEntry& e : legend) {
    const int w = (e.arrow ? 3 * ch : ch) + 4 + textWidth(e.text, scale);
    if (x > 0 && x + w > width) {
      x = 0;
      y += row;
    }
    at.emplace_back(x, y);
    x += w + spacing;
  }
  return {at, legend.empty() ? 0 : y + row};
}

void drawLegend(ImageRgb& img, int x0, int y0, const std::vector<LegendEntry>& legend,
                const std::vector<std::pair<int, int>>& at, int scale, Rgb ink) {
  const int ch = 7 * scale;
  for (size_t i = 0; i < legend.size(); ++i) {
    const int x = x0 + at[i].first, y = y0 + at[i].second;
    const LegendEntry& e = legend[i];
    int text_x = x + ch + 4;
    if (e.arrow) {
      drawArrow(img, x, y + ch / 2, x + 3 * ch, y + ch / 2, e.colour, 2, ch);
      text_x = x + 3 * ch + 4;
    } else {
      fillRect(img, x, y, x + ch, y + ch, ink);
      fillRect(img, x + 1, y + 1, x + ch - 1, y + ch - 1, e.colour);
    }
    drawText(img, text_x, y, e.text, ink, scale);
  }
}

/// The axes' ticks and numbers on the left and bottom edges of the map, and their titles.
void drawAxes(ImageRgb& img, const TopViewFrame& f, double step, int scale, Rgb ink) {
  const int ch = 7 * scale;
  const int left = f.left_px, top = f.top_px, right = left + f.width_px, bottom = top + f.height_px;
  // The map's outline.
  drawLine(img, left - 1, top - 1, right, top - 1, ink);
  drawLine(img, left - 1, bottom, right, bottom, ink);
  drawLine(img, left - 1, top - 1, left - 1, bottom, ink);
  drawLine(img, right, top - 1, right, bottom, ink);
  const double x_max = f.x_min_m + f.width_px * f.metres_per_pixel;
  for (double v : ticks(f.x_min_m, x_max, step)) {
    const int x = static_cast<int>(std::lround(f.pixelOf({v, 0.0}).x()));
    drawLine(img, x, bottom, x, bottom + kTick_px, ink);
    const std::string t = tickText(v, step);
    drawText(img, x - textWidth(t, scale) / 2, bottom + kTick_px + 2, t, ink, scale);
  }
  const double y_min = f.y_max_m - f.height_px * f.metres_per_pixel;
  for (double v : ticks(y_min, f.y_max_m, step)) {
    const int y = static_cast<int>(std::lround(f.pixelOf({0.0, v}).y()));
    drawLine(img, left - 1 - kTick_px, y, left - 1, y, ink);
    const std::string t = tickText(v, step);
    drawText(img, left - 3 - kTick_px - textWidth(t, scale), y - ch / 2, t, ink, scale);
  }
  drawText(img, 2, 2, "y (m)", ink, scale);
  drawText(img, right - textWidth("x (m)", scale), bottom + kTick_px + 2 + ch + kPad_px, "x (m)", ink, scale);
}

}  // namespace

Rgb faded(Rgb p) {
  return Rgb{static_cast<uint8_t>(160 + p.r * 3 / 8), static_cast<uint8_t>(160 + p.g * 3 / 8),
             static_cast<uint8_t>(160 + p.b * 3 / 8)};
}

std::vector<LegendEntry> backgroundLegend(const TopViewSettings& settings, Rgb (*tone)(Rgb)) {
  return {{"floor seen, nothing hit", tone(settings.free_colour), false},
          {"not seen", tone(settings.unknown_colour), false}};
}

TopView framed(Raster raster, const TopViewSettings& settings, const std::vector<LegendEntry>& legend) {
  TopView out;
  out.frame = raster.frame;
  if (!settings.axes) {
    out.image = std::move(raster.image);
    return out;
  }
  const int scale = std::max(1, settings.text_scale), ch = 7 * scale;
  TopViewFrame& f = out.frame;
  const double step = niceAtLeast(kMinTickSpacing_px * f.metres_per_pixel);
  const double y_min = f.y_max_m - f.height_px * f.metres_per_pixel;
  int label_width = 0;
  for (double v : ticks(y_min, f.y_max_m, step)) label_width = std::max(label_width, textWidth(tickText(v, step), scale));
  f.left_px = std::max(label_width + kTick_px + 3 + kPad_px, textWidth("y (m)", scale) / 2);
  f.top_px = ch + kPad_px + 2;
  // The scale bar's row, below the numbers of the x axis; the legend below it.
  const int bar_y = f.top_px + f.height_px + kTick_px + 2 + ch + kPad_px;
  out.scale_bar_m = niceAtMost(std::max<double>(kMinScaleBar_px, f.width_px / 4.0) * f.metres_per_pixel);
  out.scale_bar_y_px = bar_y + ch / 2 - 1;
  const int bar_px = static_cast<int>(std::lround(out.scale_bar_m / f.metres_per_pixel));
  const std::string bar_text = tickText(out.scale_bar_m, out.scale_bar_m) + " m";
  const int width =
      std::max(f.left_px + f.width_px + kPad_px + 2 * ch, f.left_px + bar_px + 8 + textWidth(bar_text, scale) + kPad_px);
  const auto [at, legend_height] = legendLayout(legend, width - f.left_px - kPad_px, scale);
  const int height = bar_y + ch + kPad_px + legend_height + kPad_px;
  ImageRgb& img = out.image;
  img.width = static_cast<uint32_t>(width);
  img.height = static_cast<uint32_t>(height);
  img.pixels.assign(size_t{img.width} * img.height, kPaper);
  for (int y = 0; y < f.height_px; ++y) {
    std::copy_n(raster.image.pixels.begin() + static_cast<ptrdiff_t>(y) * f.width_px, f.width_px,
                img.pixels.begin() + static_cast<ptrdiff_t>(f.top_px + y) * width + f.left_px);
  }
  const Rgb ink = settings.axes_colour;
  drawAxes(img, f, step, scale, ink);
  fillRect(img, f.left_px, out.scale_bar_y_px, f.left_px + bar_px + 1, out.scale_bar_y_px + 3, ink);
  fillRect(img, f.left_px, bar_y, f.left_px + 1, bar_y + ch, ink);  // end marks
  fillRect(img, f.left_px + bar_px, bar_y, f.left_px + bar_px + 1, bar_y + ch, ink);
  drawText(img, f.left_px + bar_px + 8, bar_y, bar_text, ink, scale);
  drawLegend(img, f.left_px, bar_y + ch + kPad_px, legend, at, scale, ink);
  return out;
}

}  // namespace chronomap::render_detail
