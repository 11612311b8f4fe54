// Drawing primitives (render/draw.h): arrows, and the unit metre in text.
#include <gtest/gtest.h>

#include <algorithm>

#include "chronomap/render/draw.h"

namespace chronomap {
namespace {

ImageRgb blank(uint32_t w, uint32_t h) { return ImageRgb{w, h, std::vector<Rgb>(size_t{w} * h, Rgb{255, 255, 255})}; }

TEST(Draw, AnArrowRunsFromItsStartToItsTip) {
  ImageRgb img = blank(100, 60);
  const Rgb ink{20, 30, 140};
  drawArrow(img, 10, 30, 90, 30, ink, 2, 10);
  for (uint32_t y = 0; y < img.height; ++y) {
    for (uint32_t x = 0; x < img.width; ++x) {
      if (img.pixels[y * img.width + x] != ink) continue;
      EXPECT_GE(x, 9u);  // the shaft's half thickness before the start
      EXPECT_LE(x, 90u);
      EXPECT_LE(std::abs(int(y) - 30), x >= 80 ? 5 : 1) << x << " " << y;  // the head is 10 wide
    }
  }
  auto at = [&](int x, int y) { return img.pixels[static_cast<size_t>(y) * img.width + static_cast<size_t>(x)]; };
  EXPECT_EQ(at(10, 30), ink);
  EXPECT_EQ(at(50, 30), ink);
  EXPECT_EQ(at(90, 30), ink);  // the tip
  EXPECT_EQ(at(81, 34), ink);  // the head's base is wider than the shaft
  EXPECT_NE(at(60, 34), ink);
}

TEST(Draw, ALoneMIsTheUnitMetreNotMega) {
  auto drawn = [](const std::string& text) {
    ImageRgb img = blank(60, 10);
    drawText(img, 0, 0, text, Rgb{0, 0, 0});
    return img.pixels;
  };
  EXPECT_NE(drawn("1 m"), drawn("1 M"));
  EXPECT_NE(drawn("x (m)"), drawn("x (M)"));
  EXPECT_EQ(drawn("room"), drawn("ROOM"));  // inside a word: a capital, as every letter
  EXPECT_EQ(drawn("mm"), drawn("MM"));
}

}  // namespace
}  // namespace chronomap
