#include <gtest/gtest.h>

#include "chronomap/render/colour.h"

namespace chronomap {
namespace {

TEST(HeatColour, RunsFromBlueThroughGreenToRed) {
  EXPECT_EQ(heatColour(0.0), (Rgb{0, 0, 255}));
  EXPECT_EQ(heatColour(0.5), (Rgb{191, 255, 191}));
  EXPECT_EQ(heatColour(1.0), (Rgb{255, 0, 0}));
  EXPECT_EQ(heatColour(-3.0), heatColour(0.0));  // clamped
  EXPECT_EQ(heatColour(7.0), heatColour(1.0));
}

TEST(ColourizeDepth, BlackWithoutDepthBlueNearRedFar) {
  ImageU16 depth;
  depth.width = 3;
  depth.height = 1;
  depth.pixels = {0, 1, 5000};  // none, 1 mm, 5 m at 1000 units per metre
  const ImageRgb img = colourizeDepth(depth, 1000.0);
  ASSERT_EQ(img.width, 3u);
  ASSERT_EQ(img.pixels.size(), 3u);
  EXPECT_EQ(img.pixels[0], (Rgb{0, 0, 0}));
  EXPECT_EQ(img.pixels[1].r, 0);  // near: blue
  EXPECT_GT(img.pixels[1].b, 100);
  EXPECT_EQ(img.pixels[2].b, 0);  // far: red
  EXPECT_GT(img.pixels[2].r, 100);
}

}  // namespace
}  // namespace chronomap
