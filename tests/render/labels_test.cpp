// Labels that do not cover each other (render/labels.h).
#include <gtest/gtest.h>

#include "chronomap/render/labels.h"

namespace chronomap {
namespace {

TEST(Labels, LabelsOfObjectsAtTheSamePlaceDoNotOverlap) {
  const PixelBox bounds{0, 0, 300, 200};
  const PixelBox object{140, 90, 160, 110};
  // Two objects at the same place: the first label beside it, the second moved away.
  std::vector<LabelPlace> two = placeLabels({{12, 16, object}, {12, 16, object}}, {}, bounds);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_FALSE(two[0].box.overlaps(two[1].box));
  EXPECT_EQ(two[0].box.x0, object.x1 + LabelSettings{}.gap_px);  // right of the object, at its top
  EXPECT_EQ(two[0].box.y0, object.y0);
  EXPECT_FALSE(two[0].leader);
  EXPECT_TRUE(bounds.contains(two[1].box));
  // Twelve at one place: no two share a pixel, none covers the object or leaves the picture.
  std::vector<LabelRequest> many(12, LabelRequest{24, 16, object});
  const std::vector<LabelPlace> placed = placeLabels(many, {}, bounds);
  for (size_t i = 0; i < placed.size(); ++i) {
    EXPECT_TRUE(bounds.contains(placed[i].box)) << i;
    EXPECT_FALSE(placed[i].box.overlaps(object)) << i;
    for (size_t k = i + 1; k < placed.size(); ++k) EXPECT_FALSE(placed[i].box.overlaps(placed[k].box)) << i << " " << k;
  }
}

TEST(Labels, ALabelAvoidsObstaclesAndTheEdge) {
  const PixelBox bounds{0, 0, 100, 100};
  // The object at the right edge: no room to its right, and a room name above-left of it.
  const PixelBox object{80, 10, 100, 30};
  const PixelBox name{40, 0, 80, 30};
  const std::vector<LabelPlace> p = placeLabels({{12, 16, object}}, {name}, bounds);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_TRUE(bounds.contains(p[0].box));
  EXPECT_FALSE(p[0].box.overlaps(name));
  EXPECT_FALSE(p[0].box.overlaps(object));
  EXPECT_EQ(p[0].box.y0, object.y1 + LabelSettings{}.gap_px);  // below it: right and left are taken
  EXPECT_FALSE(p[0].leader);
}

}  // namespace
}  // namespace chronomap
