#include "chronomap/render/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/render/draw.h"

namespace chronomap {

namespace {

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
      drawLine(img, px(p.x[i - 1]), py(p.y[i - 1]), px(p.x[i]), py(p.y[i]), p.colour, 2);
    }
    if (p.x.size() == 1) fillRect(img, px(p.x[0]) - 2, py(p.y[0]) - 2, px(p.x[0]) + 3, py(p.y[0]) + 3, p.colour);
    fillRect(img, left + 12, legend_y, left + 30, legend_y + 4, p.colour);
    drawText(img, left + 36, legend_y - 2, p.label, ink);
    legend_y += 14;
  }
  return img;
}

ImageRgb renderStoragePlot(const std::vector<double>& separate, const std::vector<double>& four_d,
                           const std::string& title) {
  std::vector<double> x;
  for (size_t i = 0; i < separate.size(); ++i) x.push_back(static_cast<double>(i + 1));
  PlotSettings s;
  s.title = title;
  s.x_label = "sessions";
  s.y_label = "nodes";
  return renderLinePlot(
      {{"session maps stored separately", Rgb{200, 60, 50}, x, separate}, {"4D map", Rgb{40, 90, 200}, x, four_d}}, s);
}

ImageRgb renderStoragePlot(const TemporalMap& map) {
  if (map.sessionCount() == 0) throw DataError("the 4D map holds no session: no storage to plot");
  std::vector<double> separate, four_d;
  double a = 0.0, b = 0.0;
  for (const auto& s : map.sessions()) {
    a += static_cast<double>(s.nodes_separate);
    b += static_cast<double>(s.nodes_added);
    separate.push_back(a);
    four_d.push_back(b);
  }
  return renderStoragePlot(separate, four_d);
}

}  // namespace chronomap
