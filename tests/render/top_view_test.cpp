#include <gtest/gtest.h>

#include "chronomap/core/error.h"
#include "chronomap/render/top_view.h"

#include <algorithm>

#include "builders.h"

namespace chronomap {
namespace {

TEST(TopView, DrawsHighestOccupiedVoxelFreeAndUnknownColumns) {
  SessionMap m(0.1);
  VoxelCounters free;
  free.length_m = 0.1f;
  for (uint16_t x = 100; x < 104; ++x) m.add({x, 200, 50}, free);
  VoxelCounters hit;
  hit.length_m = 0.05f;
  hit.hits = 2;
  hit.red = 2 * 200;
  m.add({102, 201, 50}, hit);  // low, red
  hit.red = 0;
  hit.green = 2 * 250;
  m.add({101, 201, 54}, hit);  // high, green
  TopViewSettings s;
  s.pixels_per_voxel = 1;
  s.axes = false;  // the map alone: one pixel a column
  const ImageRgb img = renderTopView(m, s);
  ASSERT_EQ(img.width, 4u);
  ASSERT_EQ(img.height, 2u);
  // Row 0 is the larger y (y points up in the picture).
  auto px = [&](uint32_t x, uint32_t row) { return img.pixels[row * img.width + x]; };
  EXPECT_EQ(px(0, 1), s.free_colour);
  EXPECT_EQ(px(3, 1), s.free_colour);
  EXPECT_EQ(px(0, 0), s.unknown_colour);
  EXPECT_EQ(px(2, 0), (Rgb{110, 0, 0}));  // lowest occupied: 0.55 of its colour
  EXPECT_EQ(px(1, 0), (Rgb{0, 250, 0}));  // highest occupied: full brightness
  s.pixels_per_voxel = 3;
  EXPECT_EQ(renderTopView(m, s).width, 12u);
  EXPECT_THROW(renderTopView(SessionMap(0.1)), DataError);
}

/// A floor of free voxels over x 0..nx-1, y 0..ny-1 (test::at: x * resolution metres).
SessionMap floorMap(int nx, int ny, double resolution_m) {
  SessionMap m(resolution_m);
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) m.add(test::at(x, y, 1), test::freeVoxel(static_cast<float>(resolution_m)));
  }
  return m;
}

using test::pixel;

int brightness(Rgb c) { return (c.r + c.g + c.b) / 3; }

TEST(TopView, AxesAndTheScaleBarAreInMetres) {
  // 4 m x 2 m at 0.1 m, 10 pixels a voxel: 100 pixels a metre, the map 400 x 200 pixels.
  SessionMap m = floorMap(40, 20, 0.1);
  m.add(test::at(15, 5, 1), test::occupiedVoxel(Rgb{200, 40, 40}));  // x 1.5..1.6 m, y 0.5..0.6 m
  TopViewSettings s;
  s.pixels_per_voxel = 10;
  const TopView v = drawTopView(m, s);
  const TopViewFrame& f = v.frame;
  EXPECT_NEAR(f.x_min_m, 0.0, 1e-9);
  EXPECT_NEAR(f.y_max_m, 2.0, 1e-9);
  EXPECT_NEAR(f.metres_per_pixel, 0.01, 1e-12);
  ASSERT_EQ(f.width_px, 400);
  ASSERT_EQ(f.height_px, 200);
  EXPECT_GT(f.left_px, 0);  // room for the y axis' numbers
  // The voxel is drawn where its metres say (at 0.55 of its colour: the lowest occupied level).
  const Eigen::Vector2d p = f.pixelOf({1.55, 0.55});
  EXPECT_EQ(pixel(v.image, static_cast<int>(p.x()), static_cast<int>(p.y())), (Rgb{110, 22, 22}));
  EXPECT_EQ(pixel(v.image, static_cast<int>(p.x()) + 10, static_cast<int>(p.y())), s.free_colour);
  // Ticks every 0.5 m (the first of 1, 2, 5 x 10^k at least 50 pixels apart) below the map.
  const int below = f.top_px + f.height_px + 2;
  for (double x_m : {0.0, 0.5, 1.0, 3.5}) {
    EXPECT_EQ(pixel(v.image, static_cast<int>(f.pixelOf({x_m, 0.0}).x()), below), s.axes_colour) << x_m;
  }
  EXPECT_NE(pixel(v.image, static_cast<int>(f.pixelOf({0.25, 0.0}).x()), below), s.axes_colour);
  // The scale bar: 1 m (the longest 1, 2, 5 x 10^k within a quarter of the map), 100 pixels
  // from the map's left edge, below the numbers.
  EXPECT_DOUBLE_EQ(v.scale_bar_m, 1.0);
  EXPECT_GT(v.scale_bar_y_px, below);
  for (int x = f.left_px; x <= f.left_px + 100; ++x) EXPECT_EQ(pixel(v.image, x, v.scale_bar_y_px), s.axes_colour) << x;
  EXPECT_NE(pixel(v.image, f.left_px - 1, v.scale_bar_y_px), s.axes_colour);
  EXPECT_NE(pixel(v.image, f.left_px + 101, v.scale_bar_y_px), s.axes_colour);
}

TEST(TopView, FloorSeenFreeWithNothingHitLooksLikeFloorNotAHole) {
  // Half the columns have their floor hit (grey, the lowest occupied level), half were only
  // seen free: the sensor looked across that floor without measuring it.
  SessionMap m(0.1);
  for (int x = 0; x < 8; ++x) {
    if (x < 4) m.add(test::at(x, 0, 0), test::occupiedVoxel(Rgb{128, 128, 128}));
    m.add(test::at(x, 0, 1), test::freeVoxel(0.1f));
    m.add(test::at(x, 1, 1), test::freeVoxel(0.1f));
  }
  m.add(test::at(0, 2, 8), test::occupiedVoxel(Rgb{128, 128, 128}));  // something higher
  TopViewSettings s;
  s.pixels_per_voxel = 1;
  s.axes = false;
  const ImageRgb img = renderTopView(m, s);
  const Rgb floor = pixel(img, 1, 2), seen = pixel(img, 6, 2), unseen = pixel(img, 6, 0);
  ASSERT_EQ(seen, s.free_colour);
  ASSERT_EQ(unseen, s.unknown_colour);
  // Not the near-white of before (a hole against the darker floor): within 60 of the floor's
  // brightness, and still told apart from it and from the unobserved.
  EXPECT_LT(std::abs(brightness(seen) - brightness(floor)), 60) << brightness(seen) << " " << brightness(floor);
  EXPECT_NE(seen, floor);
  EXPECT_GT(brightness(seen) - brightness(unseen), 40);
  // The legend, below the map, names it: its swatch is there.
  s.axes = true;
  const TopView framed = drawTopView(m, s);
  const auto below = static_cast<std::ptrdiff_t>(framed.image.width) * (framed.frame.top_px + framed.frame.height_px + 1);
  EXPECT_NE(std::find(framed.image.pixels.begin() + below, framed.image.pixels.end(), s.free_colour),
            framed.image.pixels.end());
}

TEST(TopView, AreaNamesAreDrawnInsideTheirAreas) {
  const SessionMap m = floorMap(36, 16, 0.05);  // 1.8 m x 0.8 m
  TopViewSettings s;
  s.pixels_per_voxel = 8;
  const Eigen::AlignedBox2d kitchen(Eigen::Vector2d(0.2, 0.1), Eigen::Vector2d(1.6, 0.7));
  s.areas = {{"kitchen", kitchen}};
  const TopView v = drawTopView(m, s);
  const Eigen::Vector2d lo = v.frame.pixelOf({kitchen.min().x(), kitchen.max().y()});
  const Eigen::Vector2d hi = v.frame.pixelOf({kitchen.max().x(), kitchen.min().y()});
  size_t inside = 0, outside = 0;
  for (uint32_t y = 0; y < v.image.height; ++y) {
    for (uint32_t x = 0; x < v.image.width; ++x) {
      if (pixel(v.image, int(x), int(y)) != s.area_name_colour) continue;
      (x >= lo.x() && x < hi.x() && y >= lo.y() && y < hi.y() ? inside : outside) += 1;
    }
  }
  EXPECT_GT(inside, 100u);  // "KITCHEN" at scale 2
  EXPECT_EQ(outside, 0u);
  // An area too small for its name at any scale gets none.
  s.areas = {{"meeting room", Eigen::AlignedBox2d(Eigen::Vector2d(0.2, 0.1), Eigen::Vector2d(0.4, 0.3))}};
  const ImageRgb small = drawTopView(m, s).image;
  EXPECT_EQ(std::count(small.pixels.begin(), small.pixels.end(), s.area_name_colour), 0);
}

}  // namespace
}  // namespace chronomap
