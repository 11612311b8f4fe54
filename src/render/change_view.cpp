#include "chronomap/render/change_view.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>
#include <vector>

#include "chronomap/render/draw.h"
#include "top_view_parts.h"

namespace chronomap {

namespace {

using render_detail::Label;
using render_detail::LegendEntry;
using render_detail::Raster;

constexpr int kFrameMargin_px = 2;  // between an object's cells and its frame
constexpr int kArrowThickness_px = 2;
constexpr int kArrowHead_px = 10;

/// A colour darkened, for frames and numbers beside cells of that colour.
Rgb darker(Rgb c) {
  return Rgb{static_cast<uint8_t>(c.r * 2 / 3), static_cast<uint8_t>(c.g * 2 / 3), static_cast<uint8_t>(c.b * 2 / 3)};
}

int px(double v) { return static_cast<int>(std::lround(v)); }

void fadeAll(ImageRgb& img) {
  for (Rgb& p : img.pixels) p = render_detail::faded(p);
}

/// Fills the pixels of a component's cells.
void drawCells(ImageRgb& img, const TopViewFrame& f, const DiffMap& diff, const Component& c, Rgb colour) {
  const double res = diff.resolution_m();
  for (uint32_t idx : c.cells) {
    const ChangeCell& cell = diff.cells()[idx];
    const Eigen::Vector3d lo = diff.grid().cornerOf(cell.key);
    const double side_m = res * static_cast<double>(1 << cell.level);
    const Eigen::Vector2d a = f.pixelOf({lo.x(), lo.y() + side_m}), b = f.pixelOf({lo.x() + side_m, lo.y()});
    fillRect(img, px(a.x()), px(a.y()), px(b.x()), px(b.y()), colour);
  }
}

/// Frames a box of metres; returns its pixels (with the margin).
PixelBox drawBox(ImageRgb& img, const TopViewFrame& f, const Eigen::Vector3d& lo_m, const Eigen::Vector3d& hi_m,
                 Rgb colour) {
  const Eigen::Vector2d a = f.pixelOf({lo_m.x(), hi_m.y()}), b = f.pixelOf({hi_m.x(), lo_m.y()});
  const int m = kFrameMargin_px;
  const PixelBox box{px(a.x()) - m, px(a.y()) - m, px(b.x()) + m, px(b.y()) + m};
  drawLine(img, box.x0, box.y0, box.x1, box.y0, colour);
  drawLine(img, box.x0, box.y1, box.x1, box.y1, colour);
  drawLine(img, box.x0, box.y0, box.x0, box.y1, colour);
  drawLine(img, box.x1, box.y0, box.x1, box.y1, colour);
  return PixelBox{box.x0, box.y0, box.x1 + 1, box.y1 + 1};
}

std::unordered_map<uint32_t, const Component*> componentsById(const Segmentation& s) {
  std::unordered_map<uint32_t, const Component*> out;
  for (const Component& c : s.components) out[c.id] = &c;
  return out;
}

/// Draws every object over the (faded) raster; returns the labels to place.
std::vector<Label> drawObjects(Raster& r, const Changes& changes, const ChangeViewSettings& s) {
  const auto byId = componentsById(changes.segmentation);
  const PixelBox bounds{0, 0, r.frame.width_px, r.frame.height_px};
  std::vector<Label> labels;
  for (const ChangedObject& o : changes.objects) {
    PixelBox target{};
    Rgb ink{};
    for (size_t k = 0; k < o.components.size(); ++k) {
      const auto it = byId.find(o.components[k]);
      if (it == byId.end()) continue;
      const Component& c = *it->second;
      const bool old_place = o.kind == ObjectChange::Moved && k == 0;
      const Rgb colour = o.kind == ObjectChange::Moved ? (old_place ? s.moved_from : s.moved_to)
                         : o.kind == ObjectChange::Appeared ? s.appeared
                                                            : s.vanished;
      drawCells(r.image, r.frame, changes.diff, c, colour);
      const PixelBox box = drawBox(r.image, r.frame, c.bbox_min_m, c.bbox_max_m, darker(colour));
      if (!old_place) {
        target = box;
        ink = darker(colour);
      }
    }
    if (o.kind == ObjectChange::Moved) {
      const Eigen::Vector2d a = r.frame.pixelOf(o.from.centroid_m.head<2>());
      const Eigen::Vector2d b = r.frame.pixelOf(o.to.centroid_m.head<2>());
      drawArrow(r.image, px(a.x()), px(a.y()), px(b.x()), px(b.y()), s.arrow, kArrowThickness_px, kArrowHead_px);
    }
    if (target.width() > 0 && target.overlaps(bounds)) labels.push_back({std::to_string(o.id), ink, target});
  }
  return labels;
}

std::vector<LegendEntry> changeLegend(const ChangeViewSettings& s) {
  std::vector<LegendEntry> legend = {{"appeared", s.appeared, false},
                                     {"vanished", s.vanished, false},
                                     {"moved from", s.moved_from, false},
                                     {"moved to", s.moved_to, false},
                                     {"move", s.arrow, true}};
  for (const LegendEntry& e : render_detail::backgroundLegend(s.view, render_detail::faded)) legend.push_back(e);
  return legend;
}

TopView drawOver(Raster r, const Changes& changes, const ChangeViewSettings& s) {
  fadeAll(r.image);
  const std::vector<Label> labels = drawObjects(r, changes, s);
  const std::vector<PixelBox> names = render_detail::drawAreaNames(r.image, r.frame, s.view.areas, s.view.area_name_colour);
  render_detail::drawLabels(r.image, labels, names, s.label_scale);
  return render_detail::framed(std::move(r), s.view, changeLegend(s));
}

}  // namespace

TopView drawChanges(const SessionMap& background, const Changes& changes, const ChangeViewSettings& settings) {
  return drawOver(render_detail::rasterOf(background, settings.view), changes, settings);
}

TopView drawObjectCloseUp(const SessionMap& background, const Changes& changes, const ChangedObject& object,
                          const ChangeViewSettings& settings) {
  Eigen::AlignedBox2d window(object.bbox_min_m.head<2>(), object.bbox_max_m.head<2>());
  const auto byId = componentsById(changes.segmentation);
  for (uint32_t id : object.components) {
    const auto it = byId.find(id);
    if (it == byId.end()) continue;
    window.extend(it->second->bbox_min_m.head<2>());
    window.extend(it->second->bbox_max_m.head<2>());
  }
  window.min().array() -= settings.close_up_margin_m;
  window.max().array() += settings.close_up_margin_m;
  return drawOver(render_detail::rasterOf(background, settings.view, window), changes, settings);
}

ImageRgb renderChangeView(const SessionMap& background, const DiffMap& diff, const Segmentation& segmentation,
                          const TopViewSettings& settings) {
  ChangeViewSettings s;
  s.view = settings;
  Raster r = render_detail::rasterOf(background, settings);
  fadeAll(r.image);
  std::vector<Label> labels;
  for (const Component& c : segmentation.components) {
    const Rgb colour = c.kind == ChangeKind::Appeared ? s.appeared : s.vanished;
    drawCells(r.image, r.frame, diff, c, colour);
    labels.push_back({std::to_string(c.id), darker(colour), drawBox(r.image, r.frame, c.bbox_min_m, c.bbox_max_m, darker(colour))});
  }
  const std::vector<PixelBox> names = render_detail::drawAreaNames(r.image, r.frame, settings.areas, settings.area_name_colour);
  render_detail::drawLabels(r.image, labels, names, s.label_scale);
  std::vector<LegendEntry> legend = {{"appeared", s.appeared, false}, {"vanished", s.vanished, false}};
  for (const LegendEntry& e : render_detail::backgroundLegend(settings, render_detail::faded)) legend.push_back(e);
  return render_detail::framed(std::move(r), settings, legend).image;
}

}  // namespace chronomap
