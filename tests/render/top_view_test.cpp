#include <gtest/gtest.h>

#include "chronomap/core/error.h"
#include "chronomap/render/top_view.h"

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

}  // namespace
}  // namespace chronomap
