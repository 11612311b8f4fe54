// The objects of findChanges drawn from above (render/change_view.h), on the analytic scene of
// builders.h: a box that appeared, one that vanished, one moved 0.9 m in x.
#include <gtest/gtest.h>

#include <algorithm>

#include "builders.h"
#include "chronomap/core/error.h"
#include "chronomap/render/change_view.h"

namespace chronomap {
namespace {

using test::pixel;

/// The pixels of `colour` on the map (the frame's legend left out).
std::vector<Eigen::Vector2i> pixelsOf(const TopView& v, Rgb colour) {
  std::vector<Eigen::Vector2i> out;
  for (int y = v.frame.top_px; y < v.frame.top_px + v.frame.height_px; ++y) {
    for (int x = v.frame.left_px; x < v.frame.left_px + v.frame.width_px; ++x) {
      if (pixel(v.image, x, y) == colour) out.emplace_back(x, y);
    }
  }
  return out;
}

TEST(ChangeView, AMoveIsAnArrowFromTheOldPlaceToTheNew) {
  const SessionMap before = test::changesScene(false), after = test::changesScene(true);
  const Changes c = findChanges(before, after);
  const auto moved = std::find_if(c.objects.begin(), c.objects.end(),
                                  [](const ChangedObject& o) { return o.kind == ObjectChange::Moved; });
  ASSERT_NE(moved, c.objects.end());
  ChangeViewSettings s;
  s.view.pixels_per_voxel = 8;  // 160 pixels a metre: the move is 144 pixels long
  const TopView v = drawChanges(after, c, s);
  const Eigen::Vector2d from = v.frame.pixelOf(moved->from.centroid_m.head<2>());
  const Eigen::Vector2d to = v.frame.pixelOf(moved->to.centroid_m.head<2>());
  ASSERT_NEAR(to.x() - from.x(), 144.0, 1.0);
  const std::vector<Eigen::Vector2i> arrow = pixelsOf(v, s.arrow);
  EXPECT_GE(arrow.size(), 140u);  // at least the shaft's length
  bool tip = false;
  for (const Eigen::Vector2i& p : arrow) {
    // Between the old place and the new (the move runs along x), no wider than the head.
    EXPECT_GE(p.x(), from.x() - 2) << p.transpose();
    EXPECT_LE(p.x(), to.x() + 1) << p.transpose();
    EXPECT_LE(std::abs(p.y() - from.y()), 6.0) << p.transpose();
    tip = tip || (std::abs(p.x() - to.x()) <= 1.0 && std::abs(p.y() - to.y()) <= 1.0);
  }
  EXPECT_TRUE(tip);
  // The old place in its colour, the new in its own; the appeared and vanished boxes in theirs.
  EXPECT_GE(pixelsOf(v, s.moved_from).size(), 9u * 64u - 100u);
  EXPECT_GE(pixelsOf(v, s.moved_to).size(), 9u * 64u - 150u);  // less the arrow's head
  EXPECT_EQ(pixelsOf(v, s.appeared).size(), 9u * 64u);
  EXPECT_EQ(pixelsOf(v, s.vanished).size(), 16u * 64u);
}

TEST(ChangeView, ACloseUpShowsTheObjectAndTheMarginAroundIt) {
  const SessionMap before = test::changesScene(false), after = test::changesScene(true);
  const Changes c = findChanges(before, after);
  const ChangedObject& appeared = c.objects[0];  // voxels x 12..14, y 2..4: x 0.60..0.75 m, y 0.10..0.25 m
  ASSERT_EQ(appeared.kind, ObjectChange::Appeared);
  ChangeViewSettings s;
  s.view.pixels_per_voxel = 6;
  s.close_up_margin_m = 0.225;  // to x 0.375..0.975 m: voxels 7..19; y to 0.475 m: voxels 0..9
  const TopView v = drawObjectCloseUp(after, c, appeared, s);
  EXPECT_NEAR(v.frame.x_min_m, 0.35, 1e-9);
  EXPECT_NEAR(v.frame.y_max_m, 0.50, 1e-9);
  EXPECT_EQ(v.frame.width_px, 13 * 6);
  EXPECT_EQ(v.frame.height_px, 10 * 6);
  EXPECT_EQ(pixelsOf(v, s.appeared).size(), 9u * 36u);
  EXPECT_TRUE(pixelsOf(v, s.moved_to).empty());  // the moved box is outside
  // The whole picture at the same scale is larger.
  EXPECT_GT(drawChanges(after, c, s).frame.width_px, v.frame.width_px);
}

TEST(ChangeView, TheOldChangeViewStillDrawsASegmentation) {
  const SessionMap before = test::changesScene(false), after = test::changesScene(true);
  const Changes c = findChanges(before, after);
  TopViewSettings view;
  view.pixels_per_voxel = 2;
  view.axes = false;
  const ImageRgb img = renderChangeView(after, c.diff, c.segmentation, view);
  EXPECT_EQ(img.width, 36u * 2);
  EXPECT_EQ(img.height, 16u * 2);
  const ChangeViewSettings s;
  // The appeared box B (x 12..14, y 2..4; y up: rows 11..13) is green.
  EXPECT_EQ(pixel(img, 13 * 2, (15 - 3) * 2), s.appeared);
  EXPECT_EQ(pixel(img, 3 * 2, (15 - 3) * 2), s.vanished);  // A, vanished
  EXPECT_THROW(renderChangeView(SessionMap(0.05), c.diff, c.segmentation), DataError);
}

}  // namespace
}  // namespace chronomap
