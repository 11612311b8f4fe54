#pragma once
/// @file
/// Placing labels on a picture so that none covers another: each next to what it names when
/// there is room, else moved away (and joined to it by a leader line).

#include <vector>

namespace chronomap {

/// A rectangle of pixels: x0 <= x < x1, y0 <= y < y1.
struct PixelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;

  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  /// Whether the two share a pixel.
  bool overlaps(const PixelBox& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
  /// Whether `o` lies wholly inside this box.
  bool contains(const PixelBox& o) const { return o.x0 >= x0 && o.y0 >= y0 && o.x1 <= x1 && o.y1 <= y1; }
};

/// One label to place: the size of its text and the box of what it names.
struct LabelRequest {
  int width_px = 0;
  int height_px = 0;
  PixelBox target;
};

/// Where a label went.
struct LabelPlace {
  PixelBox box;
  /// False when it sits right beside its target; true when it was moved away and needs a leader
  /// line back to it.
  bool leader = false;
};

/// Settings of the placement.
struct LabelSettings {
  /// Pixels between a label beside its target and the target.
  int gap_px = 3;
  /// Rings of places tried around a target when the four beside it are taken.
  int rings = 16;
};

/// Places the labels in order, each at the first free place: beside its target (right, left,
/// above, below), else on rings of growing radius around the target's centre. A free place lies
/// inside `bounds`, overlaps no label placed before and no `obstacle` (room names), and, while
/// one can be found, no other label's target either. A label that finds no free place goes to
/// the first place inside `bounds` that overlaps no label (or, failing that, beside its target).
std::vector<LabelPlace> placeLabels(const std::vector<LabelRequest>& labels, const std::vector<PixelBox>& obstacles,
                                    const PixelBox& bounds, const LabelSettings& settings = {});

}  // namespace chronomap
