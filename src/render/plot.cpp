#include "chronomap/io/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "chronomap/core/error.h"

namespace chronomap::io {

namespace {

// 5x7 glyphs: seven rows, the five low bits of each row from left (bit 4) to right (bit 0).
struct Glyph {
  char c;
  uint8_t rows[7];
};

constexpr Glyph kFont[] = {
    {'0', {14, 17, 19, 21, 25, 17, 14}}, {'1', {4, 12, 4, 4, 4, 4, 14}},    {'2', {14, 17, 1, 2, 4, 8, 31}},
    {'3', {31, 2, 4, 2, 1, 17, 14}},     {'4', {2, 6, 10, 18, 31, 2, 2}},   {'5', {31, 16, 30, 1, 1, 17, 14}},
    {'6', {6, 8, 16, 30, 17, 17, 14}},   {'7', {31, 1, 2, 4, 8, 8, 8}},     {'8', {14, 17, 17, 14, 17, 17, 14}},
    {'9', {14, 17, 17, 15, 1, 2, 12}},   {'A', {14, 17, 17, 31, 17, 17, 17}}, {'B', {30, 17, 17, 30, 17, 17, 30}},
    {'C', {14, 17, 16, 16, 16, 17, 14}}, {'D', {28, 18, 17, 17, 17, 18, 28}}, {'E', {31, 16, 16, 30, 16, 16, 31}},
    {'F', {31, 16, 16, 30, 16, 16, 16}}, {'G', {14, 17, 16, 23, 17, 17, 15}}, {'H', {17, 17, 17, 31, 17, 17, 17}},
    {'I', {14, 4, 4, 4, 4, 4, 14}},      {'J', {7, 2, 2, 2, 2, 18, 12}},    {'K', {17, 18, 20, 24, 20, 18, 17}},
    {'L', {16, 16, 16, 16, 16, 16, 31}}, {'M', {17, 27, 21, 21, 17, 17, 17}}, {'N', {17, 17, 25, 21, 19, 17, 17}},
    {'O', {14, 17, 17, 17, 17, 17, 14}}, {'P', {30, 17, 17, 30, 16, 16, 16}}, {'Q', {14, 17, 17, 17, 21, 18, 13}},
    {'R', {30, 17, 17, 30, 20, 18, 17}}, {'S', {15, 16, 16, 14, 1, 1, 30}}, {'T', {31, 4, 4, 4, 4, 4, 4}},
    {'U', {17, 17, 17, 17, 17, 17, 14}}, {'V', {17, 17, 17, 17, 17, 10, 4}}, {'W', {17, 17, 17, 21, 21, 21, 10}},
    {'X', {17, 17, 10, 4, 10, 17, 17}},  {'Y', {17, 17, 17, 10, 4, 4, 4}},  {'Z', {31, 1, 2, 4, 8, 16, 31}},
    {' ', {0, 0, 0, 0, 0, 0, 0}},        {'.', {0, 0, 0, 0, 0, 12, 12}},    {',', {0, 0, 0, 0, 12, 4, 8}},
    {'-', {0, 0, 0, 31, 0, 0, 0}},       {'+', {0, 4, 4, 31, 4, 4, 0}},     {':', {0, 12, 12, 0, 12, 12, 0}},
    {'(', {2, 4, 8, 8, 8, 4, 2}},        {')', {8, 4, 2, 2, 2, 4, 8}},      {'/', {0, 1, 2, 4, 8, 16, 0}},
    {'%', {24, 25, 2, 4, 8, 19, 3}},     {'=', {0, 0, 31, 0, 31, 0, 0}},    {'_', {0, 0, 0, 0, 0, 0, 31}},
    {'x', {0, 17, 10, 4, 10, 17, 0}},    {'#', {10, 10, 31, 10, 31, 10, 10}}, {'\'', {4, 4, 8, 0, 0, 0, 0}},
    {'>', {8, 4, 2, 1, 2, 4, 8}},        {'<', {2, 4, 8, 16, 8, 4, 2}},     {'^', {4, 10, 17, 0, 0, 0, 0}},
};
constexpr uint8_t kBox[7] = {31, 17, 17, 17, 17, 17, 31};
constexpr int kAdvance = 6;  // glyph width 5 plus one column of space

const uint8_t* glyphOf(char c) {
  // 'x' has its own glyph (a multiplication sign); other lower case letters are capitals.
  if (c != 'x' && c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  for (const Glyph& g : kFont) {
    if (g.c == c) return g.rows;
  }
  return kBox;
}

void setPixel(ImageRgb& image, int x, int y, Rgb color) {
  if (x < 0 || y < 0 || x >= static_cast<int>(image.width) || y >= static_cast<int>(image.height)) return;
  image.pixels[static_cast<size_t>(y) * image.width + static_cast<size_t>(x)] = color;
}

// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `target` ticks over `range`.
double niceStep(double range, int target) {
  const double raw = range / std::max(1, target);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * magnitude >= raw) return m * magnitude;
  }
  return 10.0 * magnitude;
}

std::string tickLabel(double v) {
  char buf[32];
  const double a = std::abs(v);
  if (a >= 1e9) {
    std::snprintf(buf, sizeof buf, "%gG", v / 1e9);
  } else if (a >= 1e6) {
    std::snprintf(buf, sizeof buf, "%gM", v / 1e6);
  } else if (a >= 1e4) {
    std::snprintf(buf, sizeof buf, "%gK", v / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%g", v);
  }
  return buf;
}

}  // namespace

int textWidth(const std::string& text, int scale) {
  return text.empty() ? 0 : (static_cast<int>(text.size()) * kAdvance - 1) * scale;
}

void drawText(ImageRgb& image, int x, int y, const std::string& text, Rgb color, int scale) {
  for (size_t i = 0; i < text.size(); ++i) {
    const uint8_t* rows = glyphOf(text[i]);
    const int gx = x + static_cast<int>(i) * kAdvance * scale;
    for (int r = 0; r < 7; ++r) {
      for (int c = 0; c < 5; ++c) {
        if (((rows[r] >> (4 - c)) & 1) == 0) continue;
        fillRect(image, gx + c * scale, y + r * scale, gx + (c + 1) * scale, y + (r + 1) * scale, color);
      }
    }
  }
}

void fillRect(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb color) {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, static_cast<int>(image.width));
  y1 = std::min(y1, static_cast<int>(image.height));
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) image.pixels[static_cast<size_t>(y) * image.width + static_cast<size_t>(x)] = color;
  }
}

void drawLine(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb color, int thickness) {
  const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
  const int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  const int h = thickness / 2;
  while (true) {
    for (int oy = -h; oy < thickness - h; ++oy) {
      for (int ox = -h; ox < thickness - h; ++ox) setPixel(image, x0 + ox, y0 + oy, color);
    }
    if (x0 == x1 && y0 == y1) break;
    const int e2 = 2 * err;
    if (e2 >= dy) {
      err += dy;
      x0 += sx;
    }
    if (e2 <= dx) {
      err += dx;
      y0 += sy;
    }
  }
}

ImageRgb renderLinePlot(const std::vector<PlotSeries>& series, const PlotSettings& s) {
  if (s.width < 200 || s.height < 150 || s.width > 8192 || s.height > 8192) {
    throw UsageError("plot size must lie between 200x150 and 8192x8192 pixels");
  }
  double x_max = 0.0, y_max = 0.0;
  bool any = false, integral_x = true;
  for (const PlotSeries& p : series) {
    if (p.x.size() != p.y.size()) throw UsageError("plot series '" + p.label + "' has x and y of different lengths");
    for (size_t i = 0; i < p.x.size(); ++i) {
      if (!std::isfinite(p.x[i]) || !std::isfinite(p.y[i])) continue;
      x_max = std::max(x_max, p.x[i]);
      integral_x = integral_x && p.x[i] == std::floor(p.x[i]);
      y_max = std::max(y_max, p.y[i]);
      any = true;
    }
  }
  if (!any) throw UsageError("nothing to plot: no series holds a finite point");
  if (x_max <= 0.0) x_max = 1.0;
  if (y_max <= 0.0) y_max = 1.0;
  double x_step = niceStep(x_max, 8);
  if (integral_x) x_step = std::max(1.0, x_step);  // no ticks between whole-numbered samples
  const double y_step = niceStep(y_max, 6);
  x_max = std::ceil(x_max / x_step) * x_step;
  y_max = std::ceil(y_max / y_step) * y_step;

  ImageRgb img;
  img.width = s.width;
  img.height = s.height;
  img.pixels.assign(size_t{s.width} * s.height, Rgb{255, 255, 255});
  const Rgb ink{30, 30, 30}, grid{225, 225, 225};
  const int left = 80, right = static_cast<int>(s.width) - 20, top = 40, bottom = static_cast<int>(s.height) - 50;
  auto px = [&](double x) { return left + static_cast<int>(std::lround(x / x_max * (right - left))); };
  auto py = [&](double y) { return bottom - static_cast<int>(std::lround(y / y_max * (bottom - top))); };

  // Ticks counted in integers (a floating-point loop counter can gain or lose the last tick).
  const int x_ticks = static_cast<int>(std::floor(x_max / x_step + 1e-9));
  const int y_ticks = static_cast<int>(std::floor(y_max / y_step + 1e-9));
  for (int i = 0; i <= x_ticks; ++i) {
    const double t = i * x_step;
    drawLine(img, px(t), top, px(t), bottom, grid);
    const std::string label = tickLabel(t);
    drawText(img, px(t) - textWidth(label) / 2, bottom + 6, label, ink);
  }
  for (int i = 0; i <= y_ticks; ++i) {
    const double t = i * y_step;
    drawLine(img, left, py(t), right, py(t), grid);
    const std::string label = tickLabel(t);
    drawText(img, left - 6 - textWidth(label), py(t) - 3, label, ink);
  }
  drawLine(img, left, bottom, right, bottom, ink);
  drawLine(img, left, top, left, bottom, ink);
  drawText(img, (left + right - textWidth(s.title, 2)) / 2, 10, s.title, ink, 2);
  drawText(img, (left + right - textWidth(s.x_label)) / 2, bottom + 24, s.x_label, ink);
  drawText(img, 8, top - 14, s.y_label, ink);

  int legend_y = top + 8;
  for (const PlotSeries& p : series) {
    for (size_t i = 1; i < p.x.size(); ++i) {
      if (!std::isfinite(p.x[i - 1] + p.y[i - 1] + p.x[i] + p.y[i])) continue;
      drawLine(img, px(p.x[i - 1]), py(p.y[i - 1]), px(p.x[i]), py(p.y[i]), p.color, 2);
    }
    if (p.x.size() == 1) fillRect(img, px(p.x[0]) - 2, py(p.y[0]) - 2, px(p.x[0]) + 3, py(p.y[0]) + 3, p.color);
    fillRect(img, left + 12, legend_y, left + 30, legend_y + 4, p.color);
    drawText(img, left + 36, legend_y - 2, p.label, ink);
    legend_y += 14;
  }
  return img;
}

}  // namespace chronomap::io
