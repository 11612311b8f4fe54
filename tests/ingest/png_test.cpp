#include <gtest/gtest.h>
#include <sys/resource.h>
#include <zlib.h>

#include <fstream>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "test_support.h"

namespace chronomap {
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
  CHRONOMAP_REQUIRE_DATA(colour, "rgbd-formats/TUM_color.png");
  EXPECT_THROW(readPngU16(colour), FormatError);
  const ImageRgb c = readPngRgb(colour);
  EXPECT_EQ(c.width, 640u);

  test::TempDir tmp;
  const auto bytes = readFileBytes(colour);
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

void putBigEndian32(std::vector<uint8_t>& out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<uint8_t>(v >> shift));
}

void putChunk(std::vector<uint8_t>& png, const char* type, const std::vector<uint8_t>& data) {
  putBigEndian32(png, static_cast<uint32_t>(data.size()));
  const size_t start = png.size();
  png.insert(png.end(), type, type + 4);
  png.insert(png.end(), data.begin(), data.end());
  putBigEndian32(png, static_cast<uint32_t>(crc32(0, png.data() + start, static_cast<uInt>(png.size() - start))));
}

/// A PNG whose header declares `side` x `side` pixels over `data_bytes` zeros of image data,
/// deflated as far as zlib can (level 9). With a few KiB of data for a large side, it is what a
/// decompression bomb's header looks like; with the side's true size, a valid black image.
std::vector<uint8_t> pngDeclaring(uint32_t side, uint8_t bit_depth, uint8_t colour_type, size_t data_bytes = 4096) {
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> ihdr;
  putBigEndian32(ihdr, side);
  putBigEndian32(ihdr, side);
  ihdr.insert(ihdr.end(), {bit_depth, colour_type, 0, 0, 0});
  putChunk(png, "IHDR", ihdr);
  const std::vector<uint8_t> zeros(data_bytes, 0);
  std::vector<uint8_t> idat(compressBound(zeros.size()));
  uLongf n = idat.size();
  EXPECT_EQ(compress2(idat.data(), &n, zeros.data(), zeros.size(), 9), Z_OK);
  idat.resize(n);
  putChunk(png, "IDAT", idat);
  putChunk(png, "IEND", {});
  return png;
}

/// Decodes `png` in a child process allowed 1 GiB more address space than it holds.
/// @return 0 when it is refused with a FormatError saying what the header declares, 1 when it
/// decodes, 2 for another message, 99 for another exception (std::bad_alloc).
int decodeUnderMemoryLimit(const std::vector<uint8_t>& png, bool depth) {
  return test::exitCodeUnderMemoryLimit(uint64_t{1} << 30, [&] {
    try {
      if (depth) {
        decodePngU16(png, "bomb.png");
      } else {
        decodePngRgb(png, "bomb.png");
      }
      return 1;
    } catch (const FormatError& e) {
      const std::string m = e.what();
      const bool named = m.find("bomb.png: declares a 32768 x 32768 image") != std::string::npos;
      return named && m.find("holds only " + std::to_string(png.size()) + " bytes") != std::string::npos ? 0 : 2;
    }
  });
}

TEST(Png, RefusesHeadersDeclaringMoreThanTheFileCanHold) {
  // 3 GiB of RGB and 2 GiB of 16-bit depth claimed by files of about 80 bytes: refused after the
  // header, before the pixels are allocated (before, the reader allocated them and then failed).
  EXPECT_EQ(decodeUnderMemoryLimit(pngDeclaring(32768, 8, 2), false), 0);
  EXPECT_EQ(decodeUnderMemoryLimit(pngDeclaring(32768, 16, 0), true), 0);
  // A valid image that deflate packs as far as it can (all black, 2048 x 2048, each row a
  // filter byte and 6144 zeros) is still read: the bound is deflate's own limit, 1032:1.
  const std::vector<uint8_t> black = pngDeclaring(2048, 8, 2, size_t{2048} * (1 + 2048 * 3));
  EXPECT_GT(size_t{2048} * 2048 * 3 / black.size(), 1000u) << "expected deflate near its limit";
  const ImageRgb image = decodePngRgb(black, "black.png");
  EXPECT_EQ(image.width, 2048u);
  EXPECT_EQ(image.pixels, std::vector<Rgb>(size_t{2048} * 2048));
}

TEST(Png, SkipsTextAndProfileChunksUnread) {
  // A valid 2 x 2 image behind 300 zTXt chunks of 4 MiB each deflated to 4 KiB (1.2 GB of text
  // in 1.2 MB): libpng decompressed and kept them all. Read in a child, which must decode the
  // image and grow by less than 64 MiB.
  std::vector<uint8_t> full = pngDeclaring(2, 8, 2, 2 * (1 + 2 * 3));
  const size_t idat_at = 8 + 12 + 13;  // after the signature and IHDR
  std::vector<uint8_t> text = {'C', 'o', 'm', 'm', 'e', 'n', 't', 0, 0};
  const std::vector<uint8_t> zeros(size_t{4} << 20, ' ');
  std::vector<uint8_t> packed(compressBound(zeros.size()));
  uLongf n = packed.size();
  ASSERT_EQ(compress2(packed.data(), &n, zeros.data(), zeros.size(), 9), Z_OK);
  text.insert(text.end(), packed.begin(), packed.begin() + static_cast<std::ptrdiff_t>(n));
  std::vector<uint8_t> chunks;
  for (int i = 0; i < 300; ++i) putChunk(chunks, "zTXt", text);
  full.insert(full.begin() + idat_at, chunks.begin(), chunks.end());
  const int code = test::exitCodeUnderMemoryLimit(uint64_t{1} << 30, [&] {
    rusage before{}, after{};
    ::getrusage(RUSAGE_SELF, &before);
    const ImageRgb image = decodePngRgb(full, "text.png");
    ::getrusage(RUSAGE_SELF, &after);
    if (image.width != 2) return 2;
    return after.ru_maxrss - before.ru_maxrss < 64 * 1024 ? 0 : 3;  // kilobytes
  });
  EXPECT_EQ(code, 0) << "0: read within 64 MiB, 2: wrong image, 3: took more, 99: threw";
}

TEST(Png, RunningOutOfMemoryNamesTheFile) {
  // A valid 6144 x 6144 depth image (72 MiB of samples) read with 32 MiB to spare: the reader
  // says which file it could not hold (before: std::bad_alloc, "out of memory" without a file).
  test::TempDir tmp;
  test::writeBytes(tmp / "big.png", pngDeclaring(6144, 16, 0, size_t{6144} * (1 + 6144 * 2)));
  const int code = test::exitCodeUnderMemoryLimit(uint64_t{32} << 20, [&] {
    try {
      return readPngU16(tmp / "big.png").width == 6144 ? 1 : 3;
    } catch (const IoError& e) {
      const std::string m = e.what();
      return m.find("big.png: not enough memory to read it") != std::string::npos ? 0 : 2;
    }
  });
  EXPECT_EQ(code, test::memoryLimitsApply() ? 0 : 1) << "0: IoError naming the file, 1: read, 99: bad_alloc";
}

}  // namespace
}  // namespace chronomap
