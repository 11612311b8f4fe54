// The dynamic-map benchmark's sequences read as recordings: PCD VIEWPOINT and intensity, frames
// in the world frame handed out in the sensor frame, numeric order, detection, and bad
// VIEWPOINTs refused naming the file.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/ingest/registry.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

/// Writes one frame: `world` points, the VIEWPOINT values as given.
void writeFrame(const fs::path& path, const std::vector<Eigen::Vector3f>& world, const std::vector<std::string>& viewpoint) {
  PointCloud cloud;
  cloud.points = world;
  cloud.width = static_cast<uint32_t>(world.size());
  PcdExtras extras;
  extras.viewpoint = viewpoint;
  writePcd(path, cloud, PcdEncoding::Binary, &extras);
}

/// Writes a PCD header by hand with this VIEWPOINT line (for values writePcd refuses).
void writeWithViewpointLine(const fs::path& path, const std::string& viewpoint_line) {
  std::ofstream(path) << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
                      << viewpoint_line << "POINTS 1\nDATA ascii\n1 2 3\n";
}

std::string dataErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const DataError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no DataError";
  return {};
}

TEST(DynamicMapReader, PcdViewpointAndIntensityRoundTrip) {
  test::TempDir tmp;
  PointCloud cloud;
  cloud.points = {{1, 2, 3}, {4, 5, 6}};
  cloud.width = 2;
  PcdExtras extras;
  extras.viewpoint = {"1", "2", "3", "0.7071068", "0", "0", "0.7071068"};
  extras.intensity = {0.0f, 1.0f};
  for (PcdEncoding e : {PcdEncoding::Ascii, PcdEncoding::Binary, PcdEncoding::BinaryCompressed}) {
    writePcd(tmp / "a.pcd", cloud, e, &extras);
    PcdExtras back;
    const PointCloud read = readPcd(tmp / "a.pcd", back);
    EXPECT_EQ(read.points, cloud.points);
    EXPECT_EQ(back.viewpoint, extras.viewpoint);
    EXPECT_EQ(back.intensity, extras.intensity);
    EXPECT_EQ(readPcdViewpoint(tmp / "a.pcd"), extras.viewpoint);
  }
  const Eigen::Isometry3d T = pcdViewpointPose(extras.viewpoint, "a.pcd");
  EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  // qw = qz = 1/sqrt(2): 90 degrees about z, x goes to y.
  EXPECT_TRUE((T.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-6));
}

TEST(DynamicMapReader, FramesAreReadInNumericOrderWithTheViewpointAsPose) {
  test::TempDir tmp;
  fs::create_directories(tmp / "seq" / "pcd");
  // Frame numbers 2 and 10: 10 sorts after 2 although "10.pcd" < "2.pcd" by name.
  const std::vector<Eigen::Vector3f> world2 = {{1.0f, 0.0f, 0.5f}, {2.0f, 1.0f, 0.5f}};
  const std::vector<Eigen::Vector3f> world10 = {{3.0f, 3.0f, 1.0f}};
  writeFrame(tmp / "seq" / "pcd" / "2.pcd", world2, {"0.5", "0", "1", "1", "0", "0", "0"});
  writeFrame(tmp / "seq" / "pcd" / "10.pcd", world10, {"1", "2", "1", "0.7071068", "0", "0", "0.7071068"});
  std::ofstream(tmp / "seq" / "notes.txt") << "not a frame\n";
  EXPECT_EQ(detectDatasetReader(tmp / "seq").name, "dynamic-map");
  const auto dataset = openDataset(tmp / "seq");
  ASSERT_EQ(dataset->size(), 2u);
  EXPECT_EQ(dataset->format(), "dynamic-map");
  EXPECT_TRUE(dataset->poseOf(0).translation().isApprox(Eigen::Vector3d(0.5, 0, 1)));
  EXPECT_TRUE(dataset->poseOf(1).translation().isApprox(Eigen::Vector3d(1, 2, 1)));
  for (size_t i = 0; i < 2; ++i) {
    const Frame f = dataset->load(i);
    const auto& world = i == 0 ? world2 : world10;
    ASSERT_EQ(f.cloud.points.size(), world.size());
    // The points come in the sensor frame; the pose takes them back to where the file had them.
    for (size_t k = 0; k < world.size(); ++k) {
      const Eigen::Vector3d w = f.T_world_sensor * f.cloud.points[k].cast<double>();
      EXPECT_LT((w - world[k].cast<double>()).norm(), 1e-5) << i << " " << k;
    }
    EXPECT_NE(f.source.find(i == 0 ? "2.pcd" : "10.pcd"), std::string::npos);
  }
}

TEST(DynamicMapReader, BadViewpointsAreRefusedNamingTheFile) {
  test::TempDir tmp;
  fs::create_directories(tmp / "seq" / "pcd");
  const fs::path frame = tmp / "seq" / "pcd" / "000001.pcd";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"VIEWPOINT 0 0 nan 1 0 0 0\n", "not a finite number"},
      {"VIEWPOINT 0 0 0 0 0 0 0\n", "quaternion is zero"},
      {"VIEWPOINT 0 0 0 2 0 0 0\n", "not a unit quaternion"},
      {"VIEWPOINT 0 0 0 1 0 0\n", "6 values, expected 7"},
      {"", "has no VIEWPOINT"},
  };
  for (const auto& [line, expected] : cases) {
    writeWithViewpointLine(frame, line);
    const std::string message = dataErrorOf([&] { openDataset(tmp / "seq"); });
    EXPECT_NE(message.find(frame.string()), std::string::npos) << line << message;
    EXPECT_NE(message.find(expected), std::string::npos) << line << message;
  }
  // A quaternion a little off unit length (rounded in the file) is normalised.
  writeWithViewpointLine(frame, "VIEWPOINT 0 0 0 1.0000004 0 0 0\n");
  EXPECT_TRUE(openDataset(tmp / "seq")->poseOf(0).linear().isApprox(Eigen::Matrix3d::Identity()));
}

}  // namespace
}  // namespace chronomap
