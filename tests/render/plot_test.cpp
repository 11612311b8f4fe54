#include <gtest/gtest.h>

#include <algorithm>

#include "chronomap/core/error.h"
#include "chronomap/render/draw.h"
#include "chronomap/render/plot.h"
#include "builders.h"

namespace chronomap {
namespace {

size_t countColour(const ImageRgb& img, Rgb c) { return static_cast<size_t>(std::count(img.pixels.begin(), img.pixels.end(), c)); }

TEST(LinePlot, DrawsEachSeriesInItsColourAndRefusesBadInput) {
  PlotSettings s;
  s.width = 400;
  s.height = 300;
  const Rgb red{200, 60, 50}, blue{40, 90, 200};
  const ImageRgb img = renderLinePlot({{"a", red, {0, 1, 2}, {0, 5, 10}}, {"b", blue, {0, 1, 2}, {1, 1, 1}}}, s);
  EXPECT_EQ(img.width, 400u);
  EXPECT_EQ(img.height, 300u);
  EXPECT_GT(countColour(img, red), 50u);
  EXPECT_GT(countColour(img, blue), 50u);
  EXPECT_THROW(renderLinePlot({{"a", red, {0, 1}, {0}}}, s), UsageError);
  s.width = 10;
  EXPECT_THROW(renderLinePlot({{"a", red, {0, 1}, {0, 1}}}, s), UsageError);
}

TEST(StoragePlot, SumsTheSessionsInTimeOrder) {
  TemporalMap map(0.05);
  EXPECT_THROW(renderStoragePlot(map), DataError);
  map.add(1.0, test::wallSession(10));
  map.add(2.0, test::wallSession(11));
  const ImageRgb img = renderStoragePlot(map);
  EXPECT_EQ(img.width, PlotSettings{}.width);
  EXPECT_GT(countColour(img, Rgb{200, 60, 50}), 0u);  // the session maps stored separately
  EXPECT_GT(countColour(img, Rgb{40, 90, 200}), 0u);  // the 4D map
}

TEST(DrawText, WidthFollowsTheCharactersAndScale) {
  EXPECT_EQ(textWidth("A", 1), 5);  // a 5x7 glyph
  EXPECT_EQ(textWidth("AB", 1), 11);  // and one column of space between glyphs
  EXPECT_EQ(textWidth("", 2), 0);
  EXPECT_EQ(textWidth("AB", 3), 3 * textWidth("AB", 1));
  ImageRgb img;
  img.width = 40;
  img.height = 10;
  img.pixels.assign(400, Rgb{255, 255, 255});
  drawText(img, 1, 1, "HI", Rgb{0, 0, 0});
  EXPECT_GT(countColour(img, Rgb{0, 0, 0}), 10u);
  drawText(img, -100, -100, "CLIPPED", Rgb{9, 9, 9});  // fully outside: nothing drawn, no crash
  EXPECT_EQ(countColour(img, Rgb{9, 9, 9}), 0u);
}

}  // namespace
}  // namespace chronomap
