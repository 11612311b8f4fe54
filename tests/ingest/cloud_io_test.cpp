#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/core/file.h"
#include "test_support.h"

namespace chronomap {
namespace {

using namespace std::string_literals;

void expectSameCloud(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  for (size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const float x = a.points[i][k], y = b.points[i][k];
      if (std::isnan(x) || std::isnan(y)) {
        ASSERT_TRUE(std::isnan(x) && std::isnan(y)) << "point " << i;
      } else {
        ASSERT_EQ(x, y) << "point " << i;
      }
    }
  }
  EXPECT_EQ(a.colours, b.colours);
  EXPECT_EQ(a.labels, b.labels);
}

using test::writeBytes;

TEST(Pcd, ReadsRealKinectFrameInAllThreeEncodings) {
  CHRONOMAP_REQUIRE_DATA(path, "pcl-kinect/grabber_sequences/pcd/frame_20121214T142255.814212.pcd");
  const PointCloud cloud = readPcd(path);  // binary_compressed (LZF)
  ASSERT_EQ(cloud.width, 640u);
  ASSERT_EQ(cloud.height, 480u);
  ASSERT_TRUE(cloud.hasColours());
  size_t valid = 0;
  for (const auto& p : cloud.points) {
    if (p.allFinite()) {
      ++valid;
      EXPECT_GT(p.z(), 0.3f);
      EXPECT_LT(p.z(), 10.0f);
    }
  }
  EXPECT_GT(valid, cloud.size() / 2);
  test::TempDir tmp;
  for (auto enc : {PcdEncoding::Ascii, PcdEncoding::Binary, PcdEncoding::BinaryCompressed}) {
    writePcd(tmp / "c.pcd", cloud, enc);
    expectSameCloud(readPcd(tmp / "c.pcd"), cloud);
  }
}

TEST(Pcd, ReadsLabelsOfMosd) {
  CHRONOMAP_REQUIRE_DATA(path, "mosd-a/test/test0.pcd");
  const PointCloud cloud = readPcd(path);
  ASSERT_TRUE(cloud.hasLabels());
  ASSERT_EQ(cloud.size(), 640u * 480u);
  size_t objects = 0;
  for (uint32_t l : cloud.labels) objects += l >= 10;
  EXPECT_GT(objects, 1000u);
}

TEST(Pcd, ReadsHandWrittenAsciiWithFloatRgbAndPadding) {
  test::TempDir tmp;
  float rgb_float;
  const uint32_t packed = (10u << 16) | (20u << 8) | 30u;
  std::memcpy(&rgb_float, &packed, 4);
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.9g", rgb_float);
  writeBytes(tmp / "a.pcd", std::string("# comment\nVERSION .7\nFIELDS x y z _ rgb\nSIZE 4 4 4 1 4\nTYPE F F F U F\n"
                                        "COUNT 1 1 1 4 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
                                        "1 2 3 0 0 0 0 ") + buf + "\nnan nan nan 0 0 0 0 " + buf + "\n");
  const PointCloud c = readPcd(tmp / "a.pcd");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_TRUE(std::isnan(c.points[1].x()));
  EXPECT_EQ(c.colours[0], (Rgb{10, 20, 30}));
}

TEST(Pcd, RejectsMalformedFilesNamingThem) {
  test::TempDir tmp;
  const std::string header = "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 4\nHEIGHT 1\nPOINTS 4\n";
  auto expectFormatError = [&](const std::string& content, const std::string& fragment) {
    writeBytes(tmp / "bad.pcd", content);
    try {
      readPcd(tmp / "bad.pcd");
      FAIL() << "accepted: " << fragment;
    } catch (const FormatError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("bad.pcd"), std::string::npos) << msg;
      EXPECT_NE(msg.find(fragment), std::string::npos) << msg;
    }
  };
  expectFormatError(header + "DATA binary\n" + std::string(20, '\0'), "truncated");
  expectFormatError(header + "DATA ascii\n1 2 3\n4 5 6\n", "truncated");
  expectFormatError(header + "DATA ascii\n1 2 3\n4 5\n1 1 1\n1 1 1\n", "values");
  expectFormatError(header + "DATA ascii\n1 2 x\n", "not a number");
  expectFormatError(header + "DATA binary_compressed\n\x10\0\0\0\x30\0\0\0garbagegarbage!!"s, "corrupt");
  expectFormatError(header + "DATA binary_compressed\n\x10\0\0\0\x31\0\0\0"s, "does not match");
  expectFormatError(header + "DATA lzma\n", "DATA");
  expectFormatError("VERSION .7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n", "x, y and z");
  expectFormatError("VERSION .7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n", "differ");
  expectFormatError("VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 3\nDATA ascii\n", "POINTS");
  expectFormatError("VERSION .7\nFIELDS x y z\n", "DATA");
  expectFormatError("", "DATA");
  // A header that declares two billion points over a few bytes is refused before the points
  // are allocated (24 GB), in every encoding.
  const std::string huge = "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2000000000\n"
                           "HEIGHT 1\nPOINTS 2000000000\n";
  expectFormatError(huge + "DATA ascii\n1 2 3\n", "1 of 2000000000 points");
  expectFormatError(huge + "DATA binary\n" + std::string(24, '\0'), "truncated");
  expectFormatError(huge + "DATA binary_compressed\n\x10\0\0\0\0\x5a\x62\x02garbagegarbage!!"s, "cannot expand");
  expectFormatError(huge + "DATA zip\n", "'zip' is not ascii, binary or binary_compressed");
}

// Found by fuzz_pcd: an ASCII value beyond uint32 in a U field was converted without a check.
TEST(Pcd, RejectsOutOfRangeIntegersAndSaturatesHugeCoordinates) {
  test::TempDir tmp;
  writeBytes(tmp / "u.pcd", "VERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nWIDTH 1\nPOINTS 1\nDATA ascii\n"
                            "0 0 1 9991312712\n");
  EXPECT_THROW(readPcd(tmp / "u.pcd"), FormatError);
  writeBytes(tmp / "l.pcd", "VERSION .7\nFIELDS x y z label\nSIZE 4 4 4 4\nTYPE F F F I\nWIDTH 1\nPOINTS 1\nDATA ascii\n"
                            "0 0 1 -3\n");
  EXPECT_THROW(readPcd(tmp / "l.pcd"), FormatError);
  // A double coordinate beyond float's range becomes infinite: an invalid point, not UB.
  std::string bin = "VERSION .7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA binary\n";
  for (double v : {1e300, 0.0, 1.0}) bin.append(reinterpret_cast<const char*>(&v), 8);
  writeBytes(tmp / "b.pcd", bin);
  const PointCloud c = readPcd(tmp / "b.pcd");
  EXPECT_TRUE(std::isinf(c.points[0].x()));
  writeBytes(tmp / "h.xyz", "1e300 0 0\n-1e300 0 0 300 -5 nan\n");
  EXPECT_THROW(readXyz(tmp / "h.xyz"), FormatError);  // mixed colour / no colour
  writeBytes(tmp / "h.xyz", "1e300 0 0 300 -5 nan\n");
  const PointCloud x = readXyz(tmp / "h.xyz");
  EXPECT_TRUE(std::isinf(x.points[0].x()));
  EXPECT_EQ(x.colours[0], (Rgb{255, 0, 0}));
}

TEST(Ply, RoundTripsAndReadsAsciiAndBigEndian) {
  test::TempDir tmp;
  PointCloud c = test::cloudOf({{1, 2, 3}, {-4, 5.5f, 6}});
  c.colours = {{1, 2, 3}, {250, 128, 0}};
  writePly(tmp / "c.ply", c);
  expectSameCloud(readPly(tmp / "c.ply"), c);

  writeBytes(tmp / "a.ply",
             "ply\nformat ascii 1.0\ncomment hi\nelement vertex 2\nproperty float x\nproperty float y\n"
             "property float z\nproperty float red\nproperty float green\nproperty float blue\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
             "1 2 3 1 0 0.5\n4 5 6 0 1 0\n3 0 1 1\n");
  const PointCloud a = readPly(tmp / "a.ply");
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(a.colours[0], (Rgb{255, 0, 128}));

  std::string be = "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty double x\nproperty double y\n"
                   "property double z\nend_header\n";
  for (double v : {1.5, -2.0, 3.25}) {
    uint8_t b[8];
    std::memcpy(b, &v, 8);
    for (int i = 7; i >= 0; --i) be.push_back(static_cast<char>(b[i]));
  }
  writeBytes(tmp / "be.ply", be);
  EXPECT_EQ(readPly(tmp / "be.ply").points[0], Eigen::Vector3f(1.5f, -2.0f, 3.25f));
}

TEST(Ply, RejectsMalformedFiles) {
  test::TempDir tmp;
  const std::string hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                          "property float y\nproperty float z\nend_header\n";
  writeBytes(tmp / "t.ply", hdr + std::string(20, '\0'));
  EXPECT_THROW(readPly(tmp / "t.ply"), FormatError);
  writeBytes(tmp / "h.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\n");
  EXPECT_THROW(readPly(tmp / "h.ply"), FormatError);
  writeBytes(tmp / "m.ply", "plx\n");
  EXPECT_THROW(readPly(tmp / "m.ply"), FormatError);
  writeBytes(tmp / "f.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n");
  EXPECT_THROW(readPly(tmp / "f.ply"), FormatError);
  writeBytes(tmp / "n.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n");
  EXPECT_THROW(readPly(tmp / "n.ply"), FormatError);
  // Found by fuzz_ply: a huge element count before the vertices made the reader spin forever
  // (ASCII) or overflow its size check (binary).
  const std::string huge = "element face 18446744073709551615\nproperty uchar a\nelement vertex 1\n"
                           "property float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
  writeBytes(tmp / "ha.ply", "ply\nformat ascii 1.0\n" + huge);
  EXPECT_THROW(readPly(tmp / "ha.ply"), FormatError);
  writeBytes(tmp / "hb.ply", "ply\nformat binary_little_endian 1.0\n" + huge);
  EXPECT_THROW(readPly(tmp / "hb.ply"), FormatError);
  // Found by fuzz_ply: 1.6 billion vertices declared over 35 bytes of data were allocated (19
  // GB) before the data ran out. The count is checked against the data first.
  const std::string many = "element vertex 1607814711\nproperty float x\nproperty float y\nproperty float z\n"
                           "end_header\n";
  for (const char* format : {"binary_little_endian", "ascii"}) {
    writeBytes(tmp / "v.ply", std::string("ply\nformat ") + format + " 1.0\n" + many + std::string(35, '1'));
    try {
      readPly(tmp / "v.ply");
      ADD_FAILURE() << format << ": no error";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("declares 1607814711 vertices"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("v.ply"), std::string::npos) << e.what();
    }
  }
  // The check leaves the shortest valid text alone: one-digit values, no final newline.
  writeBytes(tmp / "short.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                "property float z\nend_header\n1 2 3\n4 5 6");
  EXPECT_EQ(readPly(tmp / "short.ply").points[1], Eigen::Vector3f(4, 5, 6));
}

TEST(Xyz, ReadsPlainAndBzip2Text) {
  test::TempDir tmp;
  writeBytes(tmp / "s.xyz", "# scan\n1 2 3\n\n4 5 6\n");
  const PointCloud c = readXyz(tmp / "s.xyz");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(4, 5, 6));
  writeBytes(tmp / "bad.xyz", "1 2\n");
  EXPECT_THROW(readXyz(tmp / "bad.xyz"), FormatError);
  writeBytes(tmp / "bad.xyz.bz2", "BZh9 not really bzip2");
  EXPECT_THROW(readCloud(tmp / "bad.xyz.bz2"), FormatError);
  EXPECT_THROW(readCloud(tmp / "cloud.obj"), UsageError);
}

}  // namespace
}  // namespace chronomap
