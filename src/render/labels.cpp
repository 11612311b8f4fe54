#include "chronomap/render/labels.h"

#include <algorithm>
#include <cmath>
#include <functional>

namespace chronomap {

namespace {

// Directions tried on each ring, as many as keep neighbouring places about a label apart.
constexpr int kDirections = 16;
constexpr double kPi = 3.14159265358979323846;

PixelBox at(int x, int y, int w, int h) { return PixelBox{x, y, x + w, y + h}; }

/// The places to try for one label, nearest first.
std::vector<LabelPlace> candidates(const LabelRequest& l, const LabelSettings& s) {
  const PixelBox& t = l.target;
  const int w = l.width_px, h = l.height_px, g = s.gap_px;
  std::vector<LabelPlace> out = {{at(t.x1 + g, t.y0, w, h), false},
                                 {at(t.x0 - g - w, t.y0, w, h), false},
                                 {at(t.x0, t.y0 - g - h, w, h), false},
                                 {at(t.x0, t.y1 + g, w, h), false}};
  const double cx = (t.x0 + t.x1) / 2.0, cy = (t.y0 + t.y1) / 2.0;
  const double start = std::hypot(t.width() + w, t.height() + h) / 2 + g;
  const double step = std::max(h, 6);
  for (int r = 1; r <= s.rings; ++r) {
    const double radius = start + r * step;
    for (int d = 0; d < kDirections; ++d) {
      const double a = 2 * kPi * d / kDirections;
      const int x = static_cast<int>(std::lround(cx + radius * std::cos(a) - w / 2.0));
      const int y = static_cast<int>(std::lround(cy - radius * std::sin(a) - h / 2.0));
      out.push_back({at(x, y, w, h), true});
    }
  }
  return out;
}

bool overlapsAny(const PixelBox& b, const std::vector<PixelBox>& boxes) {
  return std::any_of(boxes.begin(), boxes.end(), [&](const PixelBox& o) { return b.overlaps(o); });
}

}  // namespace

std::vector<LabelPlace> placeLabels(const std::vector<LabelRequest>& labels, const std::vector<PixelBox>& obstacles,
                                    const PixelBox& bounds, const LabelSettings& settings) {
  std::vector<PixelBox> targets;
  for (const LabelRequest& l : labels) targets.push_back(l.target);
  std::vector<PixelBox> placed;
  std::vector<LabelPlace> out;
  for (size_t i = 0; i < labels.size(); ++i) {
    const std::vector<LabelPlace> tries = candidates(labels[i], settings);
    std::vector<PixelBox> others;  // the other labels' targets
    for (size_t k = 0; k < targets.size(); ++k) {
      if (k != i) others.push_back(targets[k]);
    }
    // From strict to lenient: the first rule some place meets decides.
    const std::vector<std::function<bool(const PixelBox&)>> rules = {
        [&](const PixelBox& b) { return !overlapsAny(b, placed) && !overlapsAny(b, obstacles) && !overlapsAny(b, others); },
        [&](const PixelBox& b) { return !overlapsAny(b, placed) && !overlapsAny(b, obstacles); },
        [&](const PixelBox& b) { return !overlapsAny(b, placed); },
    };
    LabelPlace chosen = tries.front();
    bool found = false;
    for (const auto& free : rules) {
      for (const LabelPlace& c : tries) {
        if (bounds.contains(c.box) && free(c.box)) {
          chosen = c;
          found = true;
          break;
        }
      }
      if (found) break;
    }
    placed.push_back(chosen.box);
    out.push_back(chosen);
  }
  return out;
}

}  // namespace chronomap
