// --up through the workflows: a cloud in a camera's optical frame read upright, the up recorded in
// the map's metadata, one up for every session of a 4D map.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/render/top_view.h"
#include "chronomap/sim/box_room.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/temporal_file.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

/// One frame of the default box room from a camera at 1.2 m in a corner looking horizontally
/// across it, written twice:
/// as the camera gives it (optical frame: y down, z forward) and turned z-up (-y becomes +z),
/// both seen from the origin. Returns the first; the second is "zup.pcd" beside it.
fs::path writeOpticalAndZUpClouds(const fs::path& dir) {
  PinholeCamera camera;
  camera.width = 120;
  camera.height = 90;
  camera.fx = camera.fy = 100.0;
  camera.cx = 59.5;
  camera.cy = 44.5;
  const Frame f = renderFrame(defaultRoom(), camera, lookHorizontal({-1.8, -1.6, 1.2}, std::numbers::pi / 4));
  PointCloud zup = f.cloud;
  const Eigen::Matrix3f r = uprightRotation(UpAxis::MinusY).cast<float>();
  for (auto& p : zup.points) p = r * p;  // entries 0 and +-1: exact
  writePcd(dir / "optical.pcd", f.cloud, PcdEncoding::Binary);
  writePcd(dir / "zup.pcd", zup, PcdEncoding::Binary);
  return dir / "optical.pcd";
}

/// Three frames of the box room from a camera looking horizontally at 1.2 m, z up: a cloud list.
fs::path writeZUpRecording(const fs::path& dir) {
  PinholeCamera camera;
  camera.width = 120;
  camera.height = 90;
  camera.fx = camera.fy = 100.0;
  camera.cx = 59.5;
  camera.cy = 44.5;
  std::ofstream list(dir / "zup_list.txt");
  for (int i = 0; i < 3; ++i) {
    const Eigen::Isometry3d pose = lookHorizontal({-1.2 + 0.6 * i, -0.8 + 0.5 * i, 1.2}, 0.4 + 2.1 * i);
    writePcd(dir / ("zup_" + std::to_string(i) + ".pcd"), renderFrame(defaultRoom(), camera, pose).cloud,
             PcdEncoding::Binary);
    const Eigen::Quaterniond q(pose.linear());
    list << "zup_" << i << ".pcd " << pose.translation().x() << " " << pose.translation().y() << " "
         << pose.translation().z() << " " << q.x() << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
  }
  return dir / "zup_list.txt";
}

SessionSettings upSettings(std::optional<UpAxis> axis, bool estimate = false) {
  SessionSettings s;
  s.integrator.max_range_m = 8.0;
  s.up = {axis, estimate};
  return s;
}

TEST(PipelineUp, AnOpticalCloudReadWithUpMinusYIsTheZUpCloud) {
  test::TempDir tmp;
  const fs::path optical = writeOpticalAndZUpClouds(tmp.path());
  const IntegratedSession turned = integrateDataset(optical, upSettings(UpAxis::MinusY));
  const IntegratedSession zup = integrateDataset(tmp / "zup.pcd", upSettings(std::nullopt));
  const IntegratedSession raw = integrateDataset(optical, upSettings(std::nullopt));
  // The same voxels, counters and all, and so the same top view; the cloud as recorded differs.
  EXPECT_GT(turned.map.counts().occupied_voxels, 300u);
  EXPECT_TRUE(turned.map == zup.map);
  EXPECT_FALSE(turned.map == raw.map);
  const ImageRgb top = renderTopView(turned.map);
  EXPECT_EQ(top.pixels, renderTopView(zup.map).pixels);
  // Upright, the occupied voxels span the room's height, floor (1.2 m below the camera) to ceiling
  // (1.4 m above): the top view looks down on a floor plan. As recorded, z is the camera's forward
  // axis: everything lies in front of it.
  auto heights = [](const SessionMap& m) {
    double lo = 1e9, hi = -1e9;
    m.forEachLeaf([&](const LeafView& l) {
      if (l.level != 0 || l.counters.state() != VoxelState::Occupied) return;
      lo = std::min(lo, m.grid().centerOf(l.key).z());
      hi = std::max(hi, m.grid().centerOf(l.key).z());
    });
    return std::pair{lo, hi};
  };
  EXPECT_NEAR(heights(turned.map).first, -1.2, 0.05);
  EXPECT_NEAR(heights(turned.map).second, 1.4, 0.05);
  EXPECT_GT(heights(raw.map).first, 0.0);
}

TEST(PipelineUp, AutoPicksMinusYAndTheMetadataRecordsTheTurn) {
  test::TempDir tmp;
  const fs::path optical = writeOpticalAndZUpClouds(tmp.path());
  const IntegratedSession s = integrateDataset(optical, upSettings(std::nullopt, true));
  EXPECT_EQ(s.up.axis, UpAxis::MinusY);
  EXPECT_EQ(s.up.from, "auto");
  EXPECT_TRUE(s.map == integrateDataset(optical, upSettings(UpAxis::MinusY)).map);
  // A z-up recording (three frames of a camera looking horizontally, as the simulator's): +z.
  EXPECT_EQ(integrateDataset(writeZUpRecording(tmp.path()), upSettings(std::nullopt, true)).up.axis, UpAxis::PlusZ);
  writeSessionMap(tmp / "s.cmap", s.map, sessionMetadata(optical, s, upSettings(std::nullopt, true)));
  const nlohmann::json meta = metadataOf(readCmap(tmp / "s.cmap"));
  EXPECT_EQ(meta["up"], "-y");
  EXPECT_EQ(meta["up_from"], "auto");
  const Eigen::Matrix3d r = uprightRotation(UpAxis::MinusY);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) EXPECT_EQ(meta["world_rotation"][i][j].get<double>(), r(i, j));
  }
  EXPECT_EQ(storedUp(meta, "s.cmap").axis, UpAxis::MinusY);
  // +z as recorded adds nothing: such files keep their bytes.
  const IntegratedSession plain = integrateDataset(tmp / "zup.pcd", upSettings(std::nullopt));
  EXPECT_FALSE(sessionMetadata(tmp / "zup.pcd", plain, upSettings(std::nullopt)).contains("up"));
}

TEST(PipelineUp, ABuildKeepsOneUpForEverySessionOfItsMap) {
  test::TempDir tmp;
  const fs::path optical = writeOpticalAndZUpClouds(tmp.path());
  fs::copy_file(optical, tmp / "later.pcd");
  BuildSettings b;
  b.map = tmp / "m.cmap";
  b.datasets = {optical, tmp / "later.pcd"};
  b.times_s = {100.0, 200.0};
  b.session = upSettings(std::nullopt, true);
  b.registration = RegistrationSettings{};
  b.registration->rounds = 1;
  const BuildResult first = build(b);
  EXPECT_EQ(first.up.axis, UpAxis::MinusY);
  ASSERT_EQ(first.added.size(), 2u);
  // Registered as read upright: the same cloud twice needs no correction.
  for (const BuiltSession& s : first.added) EXPECT_LT(s.correction->motion.translation().norm(), 0.05);
  EXPECT_EQ(userMetadataOf(readCmap(b.map))["up"], "-y");
  // Another build into the map without --up takes the map's own; a different --up is refused.
  b.datasets = {tmp / "later.pcd"};
  b.times_s = {300.0};
  b.session = upSettings(std::nullopt);
  b.registration.reset();
  const BuildResult second = build(b);
  EXPECT_EQ(second.up.axis, UpAxis::MinusY);
  EXPECT_EQ(second.up.from, "map");
  EXPECT_EQ(userMetadataOf(readCmap(b.map))["up"], "-y");
  const TemporalMap map = readTemporalMap(b.map);
  EXPECT_TRUE(map.snapshot(300.0) == map.snapshot(200.0));  // the third session read upright too
  b.times_s = {400.0};
  b.session = upSettings(UpAxis::PlusZ);
  try {
    build(b);
    ADD_FAILURE() << "a build with another up was accepted";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("--up +z"), std::string::npos) << e.what();
  }
  // A session map integrated with another up is refused by add as well.
  const IntegratedSession plain = integrateDataset(optical, upSettings(std::nullopt));
  writeSessionMap(tmp / "plain.cmap", plain.map, sessionMetadata(optical, plain, upSettings(std::nullopt)));
  AddSessionSettings a;
  a.map = b.map;
  a.session = tmp / "plain.cmap";
  a.time_s = 500.0;
  EXPECT_THROW(addSession(a), UsageError);
}

}  // namespace
}  // namespace chronomap
