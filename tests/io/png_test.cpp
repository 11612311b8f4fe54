#include <gtest/gtest.h>

#include <fstream>

#include "chronomap/core/error.h"
#include "chronomap/io/file.h"
#include "chronomap/io/png.h"
#include "test_support.h"

namespace chronomap::io {
namespace {

TEST(Png, RoundTripsColourAndDepth) {
  test::TempDir tmp;
  ImageRgb rgb{3, 2, {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {10, 11, 12}, {13, 14, 15}, {255, 0, 128}}};
  writePng(tmp / "c.png", rgb);
  const ImageRgb back = readPngRgb(tmp / "c.png");
  EXPECT_EQ(back.width, 3u);
  EXPECT_EQ(back.height, 2u);
  EXPECT_EQ(back.pixels, rgb.pixels);
  ImageU16 depth{2, 2, {0, 1, 5000, 65535}};
  writePng(tmp / "d.png", depth);
  EXPECT_EQ(readPngU16(tmp / "d.png").pixels, depth.pixels);
}

TEST(Png, ReadsRealTumDepth) {
  CHRONOMAP_REQUIRE_DATA(path, "rgbd-formats/TUM_depth.png");
  const ImageU16 d = readPngU16(path);
  ASSERT_EQ(d.width, 640u);
  ASSERT_EQ(d.height, 480u);
  size_t valid = 0;
  double sum_m = 0;
  for (uint16_t v : d.pixels) {
    if (v) {
      ++valid;
      sum_m += v / 5000.0;
    }
  }
  // A desk scene: most pixels valid, mean depth of a room-scale scene.
  EXPECT_GT(valid, d.pixels.size() / 2);
  EXPECT_GT(sum_m / valid, 0.5);
  EXPECT_LT(sum_m / valid, 5.0);
}

TEST(Png, RejectsColourAsDepthAndBadFiles) {
  CHRONOMAP_REQUIRE_DATA(color, "rgbd-formats/TUM_color.png");
  EXPECT_THROW(readPngU16(color), FormatError);
  const ImageRgb c = readPngRgb(color);
  EXPECT_EQ(c.width, 640u);

  test::TempDir tmp;
  const auto bytes = readFileBytes(color);
  for (size_t cut : {size_t{0}, size_t{7}, size_t{40}, bytes.size() / 2, bytes.size() - 13}) {
    std::ofstream(tmp / "t.png", std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                                        static_cast<std::streamsize>(cut));
    EXPECT_THROW(readPngRgb(tmp / "t.png"), FormatError) << "cut at " << cut;
  }
  auto flipped = bytes;
  flipped[100] ^= 0xff;  // inside the first chunk: CRC mismatch
  std::ofstream(tmp / "f.png", std::ios::binary).write(reinterpret_cast<const char*>(flipped.data()),
                                                      static_cast<std::streamsize>(flipped.size()));
  EXPECT_THROW(readPngRgb(tmp / "f.png"), FormatError);
  try {
    readPngRgb(tmp / "missing.png");
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos);
  }
}

}  // namespace
}  // namespace chronomap::io
