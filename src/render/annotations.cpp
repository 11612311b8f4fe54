// What is written on a top view's map: the names of areas and the labels of objects.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "chronomap/render/draw.h"
#include "top_view_parts.h"

namespace chronomap::render_detail {

namespace {

constexpr Rgb kHalo{250, 250, 248};
constexpr int kAreaPad_px = 4;        // between an area's name and its edges

std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](char c) { return c >= 'a' && c <= 'z' ? char(c - 'a' + 'A') : c; });
  return s;
}

/// The point of `b` nearest to (x, y).
std::pair<int, int> nearestIn(const PixelBox& b, int x, int y) {
  return {std::clamp(x, b.x0, b.x1 - 1), std::clamp(y, b.y0, b.y1 - 1)};
}

}  // namespace

void drawHaloText(ImageRgb& image, int x, int y, const std::string& text, Rgb colour, int scale) {
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      if (dx != 0 || dy != 0) drawText(image, x + dx, y + dy, text, kHalo, scale);
    }
  }
  drawText(image, x, y, text, colour, scale);
}

std::vector<PixelBox> drawAreaNames(ImageRgb& raster, const TopViewFrame& frame, const std::vector<MapArea>& areas,
                                    Rgb colour) {
  std::vector<PixelBox> taken;
  for (const MapArea& a : areas) {
    if (a.area_m.isEmpty() || a.name.empty()) continue;
    // Upper case: the font has capitals only, and a name must not read "m" as metres.
    const std::string name = upper(a.name);
    const Eigen::Vector2d lo = frame.pixelOf({a.area_m.min().x(), a.area_m.max().y()});
    const Eigen::Vector2d hi = frame.pixelOf({a.area_m.max().x(), a.area_m.min().y()});
    // The part of the area in the picture (a close-up shows part of a room).
    const PixelBox box{std::max(0, static_cast<int>(std::ceil(lo.x()))), std::max(0, static_cast<int>(std::ceil(lo.y()))),
                       std::min(static_cast<int>(raster.width), static_cast<int>(std::floor(hi.x()))),
                       std::min(static_cast<int>(raster.height), static_cast<int>(std::floor(hi.y())))};
    for (int scale : {2, 1}) {
      const int w = textWidth(name, scale) + 2, h = 7 * scale + 2;  // with the halo
      if (w + 2 * kAreaPad_px > box.width() || h + 2 * kAreaPad_px > box.height()) continue;
      const PixelBox text{box.x0 + (box.width() - w) / 2, box.y0 + kAreaPad_px, 0, 0};
      const PixelBox at{text.x0, text.y0, text.x0 + w, text.y0 + h};
      drawHaloText(raster, at.x0 + 1, at.y0 + 1, name, colour, scale);
      taken.push_back(at);
      break;
    }
  }
  return taken;
}

void drawLabels(ImageRgb& raster, const std::vector<Label>& labels, const std::vector<PixelBox>& obstacles, int scale) {
  std::vector<LabelRequest> requests;
  for (const Label& l : labels) requests.push_back({textWidth(l.text, scale) + 2, 7 * scale + 2, l.target});
  const PixelBox bounds{0, 0, static_cast<int>(raster.width), static_cast<int>(raster.height)};
  const std::vector<LabelPlace> places = placeLabels(requests, obstacles, bounds);
  // Leader lines first, so that no line crosses a label's text.
  for (size_t i = 0; i < labels.size(); ++i) {
    if (!places[i].leader) continue;
    const PixelBox& b = places[i].box;
    const PixelBox& t = labels[i].target;
    const auto [tx, ty] = nearestIn(t, (b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2);
    const auto [lx, ly] = nearestIn(b, tx, ty);
    drawLine(raster, lx, ly, tx, ty, labels[i].colour);
  }
  for (size_t i = 0; i < labels.size(); ++i) {
    drawHaloText(raster, places[i].box.x0 + 1, places[i].box.y0 + 1, labels[i].text, labels[i].colour, scale);
  }
}

}  // namespace chronomap::render_detail
