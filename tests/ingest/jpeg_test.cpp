// JPEG colour frames: decoding against known images (encoded by libjpeg through encodeJpeg), refusing what is corrupt or a bomb,
// telling PNG from JPEG by content, and a real 3DMatch sequence with its colour as JPEG.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "chronomap/core/error.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

std::vector<uint8_t> encodeJpeg(const ImageRgb& image, int quality, bool grey = false, bool progressive = false) {
  return encodeJpeg(image, {quality, grey, progressive});
}

/// A smooth colour gradient (JPEG keeps smooth images close).
ImageRgb gradient(uint32_t w, uint32_t h) {
  ImageRgb img{w, h, std::vector<Rgb>(size_t{w} * h)};
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      img.pixels[size_t{y} * w + x] = Rgb{static_cast<uint8_t>(x * 255 / (w - 1)), static_cast<uint8_t>(y * 255 / (h - 1)),
                                          static_cast<uint8_t>(128)};
    }
  }
  return img;
}

double meanAbsoluteError(const ImageRgb& a, const ImageRgb& b) {
  double sum = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    sum += std::abs(a.pixels[i].r - b.pixels[i].r) + std::abs(a.pixels[i].g - b.pixels[i].g) +
           std::abs(a.pixels[i].b - b.pixels[i].b);
  }
  return sum / (3.0 * static_cast<double>(a.pixels.size()));
}

TEST(Jpeg, DecodesColourGreyAndProgressiveImages) {
  const ImageRgb img = gradient(64, 48);
  for (bool progressive : {false, true}) {
    const ImageRgb back = decodeJpegRgb(encodeJpeg(img, 95, false, progressive), "g.jpg");
    ASSERT_EQ(back.width, 64u);
    ASSERT_EQ(back.height, 48u);
    EXPECT_LT(meanAbsoluteError(img, back), 2.0) << "progressive=" << progressive;
  }
  // A solid colour survives exactly at quality 100.
  const ImageRgb solid{16, 16, std::vector<Rgb>(256, Rgb{200, 40, 90})};
  const ImageRgb back = decodeJpegRgb(encodeJpeg(solid, 100), "s.jpg");
  EXPECT_LT(meanAbsoluteError(solid, back), 1.5);
  // Grey becomes three equal channels.
  const ImageRgb grey = decodeJpegRgb(encodeJpeg(img, 95, true), "grey.jpg");
  for (const Rgb& p : grey.pixels) {
    EXPECT_EQ(p.r, p.g);
    EXPECT_EQ(p.g, p.b);
  }
}

TEST(Jpeg, RefusesCorruptTruncatedAndBombFilesNamingThem) {
  const std::vector<uint8_t> good = encodeJpeg(gradient(64, 48), 90);
  // Cut: libjpeg would fill the rest with grey and warn on stderr; chronomap refuses.
  const std::vector<uint8_t> cut(good.begin(), good.begin() + static_cast<long>(good.size() / 2));
  EXPECT_THROW(decodeJpegRgb(cut, "cut.jpg"), FormatError);
  for (size_t n : {size_t{0}, size_t{2}, size_t{3}, size_t{20}}) {
    EXPECT_THROW(decodeJpegRgb(std::vector<uint8_t>(good.begin(), good.begin() + static_cast<long>(n)), "short.jpg"),
                 FormatError)
        << n;
  }
  // A header declaring 30000 x 30000 pixels (2.7 GB decoded) in a few kilobytes: refused before
  // decoding. The frame header (SOF0, FF C0) holds height and width after length and precision.
  std::vector<uint8_t> bomb = good;
  bool patched = false;
  for (size_t i = 2; i + 8 < bomb.size() && !patched; ++i) {
    if (bomb[i] == 0xFF && bomb[i + 1] == 0xC0) {
      bomb[i + 5] = 30000 >> 8, bomb[i + 6] = 30000 & 0xFF, bomb[i + 7] = 30000 >> 8, bomb[i + 8] = 30000 & 0xFF;
      patched = true;
    }
  }
  ASSERT_TRUE(patched);
  try {
    decodeJpegRgb(bomb, "bomb.jpg");
    FAIL() << "a bomb was decoded";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("bomb.jpg: declares 30000 x 30000"), std::string::npos) << e.what();
  }
  // Random bytes after a JPEG signature never crash.
  std::srand(7);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> noise = good;
    for (int k = 0; k < 8; ++k) noise[2 + static_cast<size_t>(std::rand()) % (noise.size() - 2)] ^= 0x5A;
    try {
      decodeJpegRgb(noise, "noise.jpg");
    } catch (const FormatError&) {
    }
  }
}

TEST(Jpeg, ColourFramesAreToldApartByContentNotName) {
  test::TempDir tmp;
  const ImageRgb img = gradient(32, 24);
  writeFileAtomic(tmp / "really_jpeg.png", encodeJpeg(img, 95));
  writePng(tmp / "really_png.jpg", img);
  EXPECT_LT(meanAbsoluteError(readColourImage(tmp / "really_jpeg.png"), img), 2.0);
  EXPECT_EQ(meanAbsoluteError(readColourImage(tmp / "really_png.jpg"), img), 0.0);
  writeFileAtomic(tmp / "text.jpg", std::vector<uint8_t>{'h', 'e', 'l', 'l', 'o'});
  try {
    readColourImage(tmp / "text.jpg");
    FAIL();
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("text.jpg: a colour frame must be PNG or JPEG"), std::string::npos);
  }
}

TEST(Jpeg, A3DMatchSequenceWithJpegColourKeepsItsColours) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  // The real sequence copied with every colour frame as JPEG (quality 95), as 7-Scenes and
  // ScanNet store them: the points must carry the same colours, up to JPEG's loss.
  test::TempDir tmp;
  fs::copy(root / "camera-intrinsics.txt", tmp / "camera-intrinsics.txt");
  fs::create_directories(tmp / "seq-01");
  for (const auto& entry : fs::directory_iterator(root / "seq-01")) {
    const std::string name = entry.path().filename().string();
    const size_t png = name.find(".color.png");
    if (png == std::string::npos) {
      fs::copy(entry.path(), tmp / "seq-01" / name);
    } else {
      writeFileAtomic(tmp / "seq-01" / (name.substr(0, png) + ".color.jpg"), encodeJpeg(readPngRgb(entry.path()), 95));
    }
  }
  const auto png_frames = openDataset(root);
  const auto jpeg_frames = openDataset(tmp.path());
  ASSERT_EQ(jpeg_frames->size(), png_frames->size());
  const Frame a = png_frames->load(0), b = jpeg_frames->load(0);
  ASSERT_TRUE(b.cloud.hasColours()) << "JPEG colour frames were ignored";
  ASSERT_EQ(a.cloud.colours.size(), b.cloud.colours.size());
  double sum = 0, brightness = 0;
  for (size_t i = 0; i < a.cloud.colours.size(); ++i) {
    sum += std::abs(a.cloud.colours[i].r - b.cloud.colours[i].r) + std::abs(a.cloud.colours[i].g - b.cloud.colours[i].g) +
           std::abs(a.cloud.colours[i].b - b.cloud.colours[i].b);
    brightness += b.cloud.colours[i].r + b.cloud.colours[i].g + b.cloud.colours[i].b;
  }
  const double n = 3.0 * static_cast<double>(a.cloud.colours.size());
  EXPECT_LT(sum / n, 4.0);
  EXPECT_GT(brightness / n, 20.0) << "the colours came out black";
}

}  // namespace
}  // namespace chronomap
