#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/depth_image.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

void writeText(const fs::path& p, const std::string& s) { std::ofstream(p) << s; }

/// A 4x3 TUM dataset: depth 1 m everywhere (5000 units), colour per frame, poses at 100 Hz.
void makeTum(const fs::path& dir, int frames) {
  fs::create_directories(dir / "rgb");
  fs::create_directories(dir / "depth");
  std::string rgb_list = "# colour images\n", depth_list = "# depth images\n", gt = "# timestamp tx ty tz qx qy qz qw\n";
  for (int i = 0; i < frames; ++i) {
    const double t = 100.0 + i * 0.1;
    ImageU16 d{4, 3, std::vector<uint16_t>(12, 5000)};
    d.pixels[0] = 0;  // one invalid pixel
    ImageRgb c{4, 3, std::vector<Rgb>(12, Rgb{static_cast<uint8_t>(10 * i), 0, 0})};
    writePng(dir / ("depth/" + std::to_string(i) + ".png"), d);
    writePng(dir / ("rgb/" + std::to_string(i) + ".png"), c);
    depth_list += std::to_string(t) + " depth/" + std::to_string(i) + ".png\n";
    rgb_list += std::to_string(t + 0.005) + " rgb/" + std::to_string(i) + ".png\n";
  }
  for (int k = 0; k < frames * 10 + 5; ++k) {
    gt += std::to_string(100.0 + k * 0.01) + " " + std::to_string(k * 0.01) + " 0 0 0 0 0 1\n";
  }
  writeText(dir / "rgb.txt", rgb_list);
  writeText(dir / "depth.txt", depth_list);
  writeText(dir / "groundtruth.txt", gt);
  writeText(dir / "camera-intrinsics.txt", "2 2 1.5 1\n");
}

TEST(DepthToCloud, BackProjectsWithThePinholeModel) {
  ImageU16 d{3, 2, {0, 1000, 2000, 3000, 4000, 5000}};
  CameraIntrinsics k{500, 400, 1, 0.5};
  const PointCloud c = depthToCloud(d, nullptr, k, 1000.0, "t");
  EXPECT_TRUE(std::isnan(c.points[0].x()));
  EXPECT_NEAR(c.points[2].x(), (2 - 1) * 2.0 / 500, 1e-6);
  EXPECT_NEAR(c.points[2].y(), (0 - 0.5) * 2.0 / 400, 1e-6);
  EXPECT_NEAR(c.points[5].z(), 5.0, 1e-6);
  EXPECT_NEAR(c.points[5].y(), 0.5 * 5.0 / 400, 1e-6);
  ImageRgb wrong{2, 2, std::vector<Rgb>(4)};
  EXPECT_THROW(depthToCloud(d, &wrong, k, 1000.0, "t"), DataError);
  EXPECT_THROW(depthToCloud(d, nullptr, k, 0.0, "t"), DataError);
}

TEST(DepthToCloud, MetresAsFloatsGiveTheSamePointsAsMillimetres) {
  const ImageU16 mm{3, 2, {0, 1000, 2000, 3000, 4000, 5000}};
  const std::vector<float> m{0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f};
  const CameraIntrinsics k{500, 400, 1, 0.5};
  const ImageRgb rgb{3, 2, std::vector<Rgb>(6, Rgb{1, 2, 3})};
  const PointCloud a = depthToCloud(mm, &rgb, k, 1000.0, "t");
  const PointCloud b = depthMetresToCloud(m, 3, 2, &rgb, k, "t");
  ASSERT_EQ(b.points.size(), 6u);
  EXPECT_EQ(b.width, 3u);
  EXPECT_EQ(b.height, 2u);
  EXPECT_TRUE(std::isnan(b.points[0].x()));
  for (size_t i = 1; i < 6; ++i) EXPECT_EQ(a.points[i], b.points[i]) << i;  // whole metres: exact
  EXPECT_EQ(b.colours, rgb.pixels);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const PointCloud c = depthMetresToCloud(std::vector<float>{nan, -1.0f, inf, 0.5f}, 2, 2, nullptr, k, "t");
  for (size_t i = 0; i < 3; ++i) EXPECT_TRUE(std::isnan(c.points[i].z())) << i;
  EXPECT_FLOAT_EQ(c.points[3].z(), 0.5f);
  EXPECT_THROW(depthMetresToCloud(m, 2, 2, nullptr, k, "t"), DataError);
  const ImageRgb wrong{2, 3, std::vector<Rgb>(6)};
  EXPECT_THROW(depthMetresToCloud(m, 3, 2, &wrong, k, "t"), DataError);
}

TEST(Dataset, Reads3DMatchFramesWithPoses) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  auto ds = openDataset(root);
  EXPECT_EQ(ds->format(), "3dmatch");
  ASSERT_EQ(ds->size(), 5u);
  const Frame f = ds->load(0);
  EXPECT_EQ(f.cloud.width, 640u);
  EXPECT_TRUE(f.cloud.hasColours());
  // frame-000000.pose.txt, first row: 0.313181 0.309473 -0.897856 1.973046
  EXPECT_NEAR(f.T_world_sensor.translation().x(), 1.973046, 1e-6);
  EXPECT_NEAR(f.T_world_sensor.linear()(0, 0), 0.313181, 1e-3);
  size_t valid = 0;
  for (const auto& p : f.cloud.points) valid += p.allFinite();
  EXPECT_GT(valid, 200000u);
}

TEST(Dataset, ReadsTumWithAssociationAndIntrinsics) {
  test::TempDir tmp;
  makeTum(tmp.path(), 3);
  auto ds = openDataset(tmp.path());
  EXPECT_EQ(ds->format(), "tum");
  ASSERT_EQ(ds->size(), 3u);
  const Frame f = ds->load(2);
  EXPECT_NEAR(f.T_world_sensor.translation().x(), 0.20, 1e-9);  // pose at t = 100.2
  EXPECT_EQ(f.cloud.colours[5].r, 20);
  EXPECT_NEAR(f.cloud.points[5].z(), 1.0, 1e-6);                    // 5000 units = 1 m
  EXPECT_NEAR(f.cloud.points[5].x(), (1 - 1.5) * 1.0 / 2.0, 1e-6);  // intrinsics file used
  EXPECT_TRUE(std::isnan(f.cloud.points[0].z()));
}

TEST(Dataset, WithoutColourGivesTheSamePointsAndPosesWithoutColours) {
  test::TempDir tmp;
  makeTum(tmp.path(), 3);
  DatasetSettings geometry;
  geometry.colour = false;
  auto with = openDataset(tmp.path()), without = openDataset(tmp.path(), geometry);
  ASSERT_EQ(without->size(), with->size());
  for (size_t i = 0; i < with->size(); ++i) {
    const Frame a = with->load(i), b = without->load(i);
    EXPECT_TRUE(a.cloud.hasColours());
    EXPECT_FALSE(b.cloud.hasColours());
    ASSERT_EQ(b.cloud.points.size(), a.cloud.points.size());
    for (size_t j = 0; j < a.cloud.points.size(); ++j) {
      // Bitwise (NaN for the invalid pixel in both).
      EXPECT_EQ(std::memcmp(a.cloud.points[j].data(), b.cloud.points[j].data(), sizeof(float) * 3), 0) << i << j;
    }
    EXPECT_TRUE(a.T_world_sensor.matrix() == b.T_world_sensor.matrix());
  }
  // The colour images are not even opened: a missing one does not matter.
  fs::remove(tmp.path() / "rgb/1.png");
  EXPECT_FALSE(openDataset(tmp.path(), geometry)->load(1).cloud.hasColours());
  EXPECT_THROW(openDataset(tmp.path())->load(1), Error);
}

TEST(Dataset, DepthToCloudEqualsThePerPixelFormula) {
  // The reference: every pixel computed on its own, beyond float's range infinite.
  const auto toFloatRef = [](double x) {
    constexpr double kMax = std::numeric_limits<float>::max();
    if (x > kMax) return std::numeric_limits<float>::infinity();
    if (x < -kMax) return -std::numeric_limits<float>::infinity();
    return static_cast<float>(x);
  };
  std::mt19937 rng(7);
  ImageU16 depth{37, 23, std::vector<uint16_t>(37 * 23)};
  for (uint16_t& d : depth.pixels) d = rng() % 4 == 0 ? 0 : static_cast<uint16_t>(rng());
  const CameraIntrinsics k{523.7, 517.3, 18.3, 11.9};
  // An ordinary scale, and one that puts far pixels beyond float's range.
  for (const double scale : {5000.0, 1000.0, 3e-36}) {
    const PointCloud cloud = depthToCloud(depth, nullptr, k, scale, "test");
    ASSERT_EQ(cloud.points.size(), depth.pixels.size());
    size_t infinite = 0;
    for (uint32_t v = 0; v < depth.height; ++v) {
      for (uint32_t u = 0; u < depth.width; ++u) {
        const size_t i = size_t{v} * depth.width + u;
        const uint16_t d = depth.pixels[i];
        const float nan = std::numeric_limits<float>::quiet_NaN();
        const double z = d * (1.0 / scale);
        const Eigen::Vector3f want = d == 0 ? Eigen::Vector3f(nan, nan, nan)
                                            : Eigen::Vector3f(toFloatRef((u - k.cx) * z / k.fx),
                                                              toFloatRef((v - k.cy) * z / k.fy), toFloatRef(z));
        EXPECT_EQ(std::memcmp(want.data(), cloud.points[i].data(), sizeof(float) * 3), 0) << scale << " " << i;
        infinite += std::isinf(want.z());
      }
    }
    EXPECT_EQ(infinite > 0, scale < 1.0) << scale;
  }
}

TEST(Dataset, DepthCacheGivesTheSameFramesWithinItsBudget) {
  test::TempDir tmp;
  makeTum(tmp.path(), 5);
  const ImageU16 image = readPngU16(tmp.path() / "depth/0.png");
  // Room for two images, not three.
  const size_t one = DepthImageCache::bytesOf(tmp.path() / "depth/0.png", image);
  auto cache = std::make_shared<DepthImageCache>(2 * one + one / 2);
  DatasetSettings cached;
  cached.depth_cache = cache;
  const auto plain = openDataset(tmp.path());
  for (int pass = 0; pass < 3; ++pass) {
    // A new dataset each pass, as each re-integration opens the recording again; every other
    // pass without colour, as registration's drift passes.
    cached.colour = pass % 2 == 0;
    const auto ds = openDataset(tmp.path(), cached);
    ASSERT_EQ(ds->size(), plain->size());
    for (size_t i = 0; i < ds->size(); ++i) {
      const Frame a = plain->load(i), b = ds->load(i);
      EXPECT_EQ(b.cloud.hasColours(), cached.colour);
      if (cached.colour) {
        EXPECT_TRUE(b.cloud.colours == a.cloud.colours);
      }
      ASSERT_EQ(b.cloud.points.size(), a.cloud.points.size());
      for (size_t j = 0; j < a.cloud.points.size(); ++j) {
        EXPECT_EQ(std::memcmp(a.cloud.points[j].data(), b.cloud.points[j].data(), sizeof(float) * 3), 0) << i << j;
      }
      EXPECT_TRUE(a.T_world_sensor.matrix() == b.T_world_sensor.matrix());
      EXPECT_LE(cache->bytes(), cache->budget_bytes());
    }
    // The first two images are kept (and found from the second pass on), the rest read each time.
    EXPECT_EQ(cache->images(), 2u);
    EXPECT_EQ(cache->bytes(), 2 * one);
    EXPECT_EQ(cache->hits(), 2u * static_cast<size_t>(pass));
  }
  // Kept images are not read again: their files may go; the others may not.
  fs::remove(tmp.path() / "depth/1.png");
  fs::remove(tmp.path() / "depth/2.png");
  const auto ds = openDataset(tmp.path(), cached);
  EXPECT_NEAR(ds->load(1).cloud.points[5].z(), 1.0, 1e-6);
  EXPECT_THROW(ds->load(2), Error);
  EXPECT_FALSE(cache->keep(tmp.path() / "depth/0.png", std::make_shared<ImageU16>(image)));  // already kept
  cache->clear();
  EXPECT_EQ(cache->images(), 0u);
  EXPECT_EQ(cache->bytes(), 0u);
  EXPECT_THROW(ds->load(1), Error);  // its file is gone, and now its image too
  EXPECT_FALSE(DepthImageCache(one - 1).keep(tmp.path() / "depth/0.png", std::make_shared<ImageU16>(image)));
  EXPECT_TRUE(DepthImageCache(one).keep(tmp.path() / "depth/0.png", std::make_shared<ImageU16>(image)));
}

TEST(Dataset, TumDropsFramesWithoutPoseAndFailsWithNone) {
  test::TempDir tmp;
  makeTum(tmp.path(), 3);
  writeText(tmp / "trajectory.txt", "100.0 0 0 0 0 0 0 1\n");  // preferred over groundtruth.txt
  auto ds = openDataset(tmp.path());
  EXPECT_EQ(ds->size(), 1u);
  EXPECT_EQ(ds->framesDropped(), 2u);
  writeText(tmp / "trajectory.txt", "50.0 0 0 0 0 0 0 1\n");
  EXPECT_THROW(openDataset(tmp.path()), DataError);
}

TEST(Dataset, RejectsBadTumInputNamingTheFileAndLine) {
  test::TempDir tmp;
  makeTum(tmp.path(), 2);
  auto expectError = [&](const std::string& fragment) {
    try {
      openDataset(tmp.path());
      FAIL() << "accepted input expected to fail with " << fragment;
    } catch (const DataError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  writeText(tmp / "trajectory.txt", "100.0 0 0 0 0 0 0 0\n");
  expectError("trajectory.txt:1: pose quaternion is zero");
  writeText(tmp / "trajectory.txt", "100.0 0 0 0 0 0 0 3\n");
  expectError("not a unit quaternion");
  writeText(tmp / "trajectory.txt", "100.0 0 0 nan 0 0 0 1\n");
  expectError("trajectory.txt:1");
  writeText(tmp / "trajectory.txt", "100.0 0 0 0 0 1\n");
  expectError("expected 'timestamp tx ty tz qx qy qz qw'");
  fs::remove(tmp / "trajectory.txt");
  writeText(tmp / "depth.txt", "100.0\n");
  expectError("depth.txt:1");
  writeText(tmp / "depth.txt", "# nothing\n");
  expectError("none of the 0 depth frames");
  fs::remove(tmp / "depth.txt");
  EXPECT_THROW(openDataset(tmp.path()), UsageError);  // format can no longer be detected
  DatasetSettings tum;
  tum.format = "tum";
  EXPECT_THROW(openDataset(tmp.path(), tum), DataError);
}

TEST(Dataset, TumFramesWithMismatchedImagesFailOnLoad) {
  test::TempDir tmp;
  makeTum(tmp.path(), 1);
  writePng(tmp / "rgb/0.png", ImageRgb{2, 2, std::vector<Rgb>(4)});
  auto ds = openDataset(tmp.path());
  try {
    ds->load(0);
    FAIL();
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("0.png: colour image is 2x2 but the depth image is 4x3"), std::string::npos)
        << e.what();
  }
  writeText(tmp / "depth/0.png", "not a png");
  EXPECT_THROW(ds->load(0), FormatError);
}

TEST(Dataset, RejectsDepthScalesOffByAThousand) {
  test::TempDir tmp;
  makeTum(tmp.path(), 1);  // 5000 units = 1 m at the TUM scale
  for (double wrong : {5.0, 5e6}) {
    DatasetSettings o;
    o.depth_scale = wrong;
    auto ds = openDataset(tmp.path(), o);
    try {
      ds->load(0);
      FAIL() << "scale " << wrong << " accepted";
    } catch (const DataError& e) {
      EXPECT_NE(std::string(e.what()).find("the scale looks wrong"), std::string::npos) << e.what();
    }
  }
  DatasetSettings fine;
  fine.depth_scale = 1000.0;  // 5 m: plausible
  EXPECT_NO_THROW(openDataset(tmp.path(), fine)->load(0));
}

TEST(Dataset, RejectsBad3DMatchPoses) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  test::TempDir tmp;
  fs::copy_file(root / "camera-intrinsics.txt", tmp / "camera-intrinsics.txt");
  fs::copy_file(root / "seq-01/frame-000000.depth.png", tmp / "frame-000000.depth.png");
  writeText(tmp / "frame-000000.pose.txt", "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  EXPECT_THROW(openDataset(tmp.path()), DataError);
  writeText(tmp / "frame-000000.pose.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n");
  EXPECT_THROW(openDataset(tmp.path()), FormatError);
  fs::remove(tmp / "frame-000000.pose.txt");
  EXPECT_THROW(openDataset(tmp.path()), DataError);
}

TEST(Dataset, CloudListsAndSingleClouds) {
  test::TempDir tmp;
  PointCloud c = test::cloudOf({{1, 0, 0}});
  writePcd(tmp / "a.pcd", c, PcdEncoding::Binary);
  writeText(tmp / "list.txt", "# cloud pose\na.pcd 1 2 3 0 0 0 1\na.pcd 0 0 0 0 0 1 0\n");
  auto list = openDataset(tmp / "list.txt");
  ASSERT_EQ(list->size(), 2u);
  EXPECT_EQ(list->load(0).T_world_sensor.translation(), Eigen::Vector3d(1, 2, 3));
  DatasetSettings o;
  o.pose = Eigen::Isometry3d(Eigen::Translation3d(0, 0, 5));
  auto single = openDataset(tmp / "a.pcd", o);
  ASSERT_EQ(single->size(), 1u);
  EXPECT_EQ(single->load(0).T_world_sensor.translation().z(), 5.0);
  writeText(tmp / "list.txt", "missing.pcd 0 0 0 0 0 0 1\n");
  EXPECT_THROW(openDataset(tmp / "list.txt"), DataError);
  writeText(tmp / "list.txt", "");
  EXPECT_THROW(openDataset(tmp / "list.txt"), DataError);
  EXPECT_THROW(openDataset(tmp / "nothing-here"), UsageError);
  EXPECT_THROW(openDataset(tmp.path()), UsageError);  // a folder of nothing known
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

TEST(ColourInDepthView, LooksUpEachDepthRayInTheColourImage) {
  // Colour at twice the depth resolution, same field of view: depth pixel (u, v) sees colour
  // pixel (2u + 1, 2v + 1) with these intrinsics (the centre of its 2 x 2 block).
  const CameraIntrinsics depth_k{100, 100, 1.5, 1.0};
  const CameraIntrinsics colour_k{200, 200, 4.0, 3.0};
  ImageRgb colour{8, 6, std::vector<Rgb>(48)};
  for (uint32_t y = 0; y < 6; ++y) {
    for (uint32_t x = 0; x < 8; ++x) colour.pixels[y * 8 + x] = Rgb{static_cast<uint8_t>(x), static_cast<uint8_t>(y), 7};
  }
  const ImageRgb seen = colourInDepthView(colour, colour_k, depth_k, 4, 3);
  ASSERT_EQ(seen.width, 4u);
  ASSERT_EQ(seen.height, 3u);
  for (uint32_t v = 0; v < 3; ++v) {
    for (uint32_t u = 0; u < 4; ++u) {
      const Rgb p = seen.pixels[v * 4 + u];
      EXPECT_EQ(p.r, 2 * u + 1) << u << "," << v;
      EXPECT_EQ(p.g, 2 * v + 1) << u << "," << v;
    }
  }
  // Rays that leave the colour image are black.
  const ImageRgb narrow = colourInDepthView(colour, CameraIntrinsics{400, 400, 4.0, 3.0}, depth_k, 4, 3);
  EXPECT_EQ(narrow.pixels[0].b, 0);
}

TEST(Dataset, ReadsAScanNetExportWithColourAtItsOwnResolution) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  // The real 3DMatch frames laid out as ScanNet exports them: depth/N.png, colour as JPEG at
  // twice the resolution with its own intrinsics, pose/N.txt, 4x4 intrinsic matrices; frame 2
  // lost by the reconstruction (-inf pose), as ScanNet marks it.
  const CameraIntrinsics k = readIntrinsicsFile(root / "camera-intrinsics.txt");
  test::TempDir tmp;
  for (const char* dir : {"color", "depth", "pose", "intrinsic"}) fs::create_directories(tmp / dir);
  auto matrix = [](const CameraIntrinsics& c) {
    std::ostringstream m;
    m.precision(17);
    m << c.fx << " 0 " << c.cx << " 0\n0 " << c.fy << " " << c.cy << " 0\n0 0 1 0\n0 0 0 1\n";
    return m.str();
  };
  const CameraIntrinsics colour_k{2 * k.fx, 2 * k.fy, 2 * k.cx + 0.5, 2 * k.cy + 0.5};
  writeText(tmp / "intrinsic" / "intrinsic_depth.txt", matrix(k));
  writeText(tmp / "intrinsic" / "intrinsic_color.txt", matrix(colour_k));
  // The frame numbers of the real sequence: 116 must come after 2 (numbers, not names, sort).
  for (int n : {0, 1, 2, 116, 422}) {
    char stem[32];
    std::snprintf(stem, sizeof stem, "frame-%06d", n);
    const fs::path seq = root / "seq-01";
    fs::copy(seq / (std::string(stem) + ".depth.png"), tmp / "depth" / (std::to_string(n) + ".png"));
    if (n == 2) {
      writeText(tmp / "pose" / "2.txt", "-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n");
    } else {
      fs::copy(seq / (std::string(stem) + ".pose.txt"), tmp / "pose" / (std::to_string(n) + ".txt"));
    }
    const ImageRgb small = readPngRgb(seq / (std::string(stem) + ".color.png"));
    ImageRgb big{small.width * 2, small.height * 2, std::vector<Rgb>(small.pixels.size() * 4)};
    for (uint32_t y = 0; y < big.height; ++y) {
      for (uint32_t x = 0; x < big.width; ++x) big.pixels[y * big.width + x] = small.pixels[(y / 2) * small.width + x / 2];
    }
    writeFileAtomic(tmp / "color" / (std::to_string(n) + ".jpg"), encodeJpeg(big, {95, false, false}));
  }
  const auto scannet = openDataset(tmp.path());
  EXPECT_EQ(scannet->format(), "scannet");
  ASSERT_EQ(scannet->size(), 4u);
  EXPECT_EQ(scannet->framesDropped(), 1u);
  const auto reference = openDataset(root);
  const Frame a = reference->load(3), b = scannet->load(2);  // frame 116 in both
  EXPECT_TRUE(a.T_world_sensor.isApprox(b.T_world_sensor));
  ASSERT_EQ(a.cloud.points.size(), b.cloud.points.size());
  for (size_t i = 0; i < a.cloud.points.size(); i += 97) {
    if (a.cloud.points[i].allFinite()) {
      EXPECT_EQ(a.cloud.points[i], b.cloud.points[i]) << i;
    }
  }
  ASSERT_TRUE(b.cloud.hasColours());
  double difference = 0;
  for (size_t i = 0; i < a.cloud.colours.size(); ++i) {
    difference += std::abs(a.cloud.colours[i].r - b.cloud.colours[i].r) + std::abs(a.cloud.colours[i].g - b.cloud.colours[i].g) +
                  std::abs(a.cloud.colours[i].b - b.cloud.colours[i].b);
  }
  EXPECT_LT(difference / (3.0 * static_cast<double>(a.cloud.colours.size())), 4.0);
  // A missing colour frame is named, not skipped.
  fs::remove(tmp / "color" / "422.jpg");
  EXPECT_THROW(openDataset(tmp.path()), DataError);
}

}  // namespace
}  // namespace chronomap
