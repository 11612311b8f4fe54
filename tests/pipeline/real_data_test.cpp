// End-to-end checks on real recordings from ../shared/data.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <octomap/ColorOcTree.h>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/export/export.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/session.h"
#include "test_support.h"

namespace chronomap {
namespace {

TEST(RealData, ThreeDMatchFramesAgreeWithEachOther) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  auto ds = openDataset(root);
  IntegratorSettings s;
  s.compress_free = false;
  SessionMap map02(0.05), map1(0.05);
  integrate(FrameVector({ds->load(0), ds->load(2)}), map02, s);
  integrate(FrameVector({ds->load(1)}), map1, s);
  size_t surface = 0, occupied = 0, near = 0;
  map1.forEachLeaf([&](const LeafView& l) {
    if (l.counters.state() != VoxelState::Occupied) return;
    ++surface;
    occupied += map02.stateOf(l.key) == VoxelState::Occupied;
    bool any = false;  // within one voxel (pose and depth noise of a few centimetres)
    for (int dx = -1; dx <= 1 && !any; ++dx)
      for (int dy = -1; dy <= 1 && !any; ++dy)
        for (int dz = -1; dz <= 1 && !any; ++dz)
          any = map02.stateOf({static_cast<uint16_t>(l.key.x + dx), static_cast<uint16_t>(l.key.y + dy),
                               static_cast<uint16_t>(l.key.z + dz)}) == VoxelState::Occupied;
    near += any;
  });
  ASSERT_GT(surface, 1000u);
  const double exact = static_cast<double>(occupied) / static_cast<double>(surface);
  const double within_one = static_cast<double>(near) / static_cast<double>(surface);
  RecordProperty("same_voxel_fraction", std::to_string(exact));
  RecordProperty("within_one_voxel_fraction", std::to_string(within_one));
  EXPECT_GT(exact, 0.9) << "frame 1 surface voxels occupied in the map of frames 0 and 2";
  EXPECT_GT(within_one, 0.99);
}

// The real-data control (docs/changes.md): the five frames of a static room split into two
// sessions and diffed with the recommended settings: every object found is false. `a` and `b`
// name the sequence's frames (0, 1, 2, 116 and 422). As `chronomap build --fast --register
// --register-drift 20 --register-planar --register-points` and `diff MAP@T1 MAP@T2` do, each
// session is a folder of its frames (links), the sessions are registered to their consensus and
// go through a 4D map file.
struct StaticRoomSplit {
  TemporalMap map{0.05};
  SegmentSettings segment_settings;
  StaticRoomSplit(const std::filesystem::path& root, std::initializer_list<int> a, std::initializer_list<int> b) {
    namespace fs = std::filesystem;
    test::TempDir tmp;
    auto folder = [&](const std::string& name, std::initializer_list<int> frames) {
      const fs::path dir = tmp / name;
      fs::create_directories(dir / "seq");
      fs::create_symlink(root / "camera-intrinsics.txt", dir / "camera-intrinsics.txt");
      for (int f : frames) {
        char stem[32];
        std::snprintf(stem, sizeof stem, "frame-%06d", f);
        for (const char* part : {".color.png", ".depth.png", ".pose.txt"}) {
          fs::create_symlink(root / "seq-01" / (stem + std::string(part)), dir / "seq" / (stem + std::string(part)));
        }
      }
      return dir / "seq";
    };
    const std::vector<fs::path> paths = {folder("a", a), folder("b", b)};
    SessionSettings settings;
    settings.integrator.fast = true;
    std::vector<SessionMap> maps;
    std::vector<std::vector<Eigen::Vector3d>> positions;
    for (const fs::path& p : paths) {
      IntegratedSession s = integrateDataset(p, settings);
      maps.push_back(std::move(s.map));
      positions.push_back(std::move(s.sensor_positions));
    }
    registerDatasets(maps, paths, positions, settings, recommendedRegistration());
    TemporalMap built(0.05);
    built.add(1000, maps[0]);
    built.add(2000, maps[1]);
    writeTemporalMap(tmp / "m.cmap", built, {});
    map = readTemporalMap(tmp / "m.cmap");
    sessions = std::move(maps);
    segment_settings.connectivity = Connectivity::Vertex;
    segment_settings.min_voxels = 20;
  }
  // The recommended diff's settings up to the weak-change rule.
  static DiffSettings recommended() {
    DiffSettings d;
    d.mode = DiffMode::Band;
    d.neighbourhood_voxels = 1;
    d.min_shift_voxels = DiffSettings::kRecommendedMinShift;
    d.shift_plane_ratio = DiffSettings::kRecommendedShiftPlaneRatio;
    return d;
  }
  size_t objects(const DiffSettings& d) const { return segment(diff(map, 1000, 2000, d), segment_settings).components.size(); }
  size_t sessionMapObjects(const DiffSettings& d) const {
    return segment(diff(sessions[0], sessions[1], d), segment_settings).components.size();
  }
  std::vector<SessionMap> sessions;
};

// Frames 0, 2 and 422 against 1 and 116: frame 116 measures part of a dark leather sofa 13 cm
// nearer than frame 0 while frame 1, in the same session, still sees it where frame 0 does: two
// false objects (about 100 and 30 voxels) without the weak-change rule, one with it. (Before the
// 4D map stored a surface's new position (ChangeCriterion::surface_shift_voxels), it kept the
// first session's hit positions where the state stayed, and the rule dropped both; the two
// session maps, diffed directly, give one, as the map does now.)
TEST(RealData, StaticRoomSplitInTwoSessionsGivesOneFalseObject) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  const StaticRoomSplit split(root, {0, 2, 422}, {1, 116});
  DiffSettings d = StaticRoomSplit::recommended();
  EXPECT_EQ(split.objects(d), 2u) << "the sofa, without the weak-change rule";
  d.kept_surface_radius_voxels = DiffSettings::kRecommendedKeptSurfaceRadius;
  EXPECT_EQ(split.objects(d), 1u);
  EXPECT_EQ(split.objects(d), split.sessionMapObjects(d)) << "the 4D map answers as the two session maps";
  d.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  EXPECT_EQ(split.objects(d), 1u) << "the dark-surface rule removes none";
  d.seen_at_both = true;
  EXPECT_EQ(split.objects(d), split.sessionMapObjects(d));
}

// Frames 116 and 422 against 0, 1 and 2: each session agrees with itself, and the two measure the
// dark sofa 8 to 12 cm apart (while they agree within 5 mm on bright surfaces). The weak-change
// rule cannot tell that from a moved sofa; the dark-surface rule takes the sofa's colour as the
// cue and the patches' thinness (every voxel within 2 of the surface the other session saw) as
// the sign that they are that surface, not an object set in front of it (docs/changes.md).
TEST(RealData, StaticRoomSplitWithTheSofaMeasuredApartNeedsTheDarkSurfaceRule) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  const StaticRoomSplit split(root, {116, 422}, {0, 1, 2});
  DiffSettings d = StaticRoomSplit::recommended();
  d.kept_surface_radius_voxels = DiffSettings::kRecommendedKeptSurfaceRadius;
  EXPECT_EQ(split.objects(d), 4u) << "the sofa's patches and lighter remnants, with the weak-change rule alone";
  d.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  const size_t with_rule = split.objects(d);
  // Measured: 2 (3 before the shift test counted only a flat surface's move across it, which
  // removes one object from both counts; 1 while the 4D map kept the first session's hit positions,
  // when the session maps, diffed directly, gave 3). The rule removes two of the four.
  EXPECT_EQ(with_rule, 2u);
  EXPECT_EQ(with_rule, split.sessionMapObjects(d)) << "the 4D map answers as the two session maps";
}

TEST(RealData, OctomapScanIntegratesAsALaserScanFromTheOrigin) {
  CHRONOMAP_REQUIRE_DATA(path, "octomap-data/scan.dat.bz2");
  const PointCloud scan = readCloud(path);
  ASSERT_EQ(scan.size(), 88206u);
  SessionMap map(0.2);
  IntegratorSettings s;
  s.max_range_m = 30.0;  // the scan reaches 29 m
  const IntegrationStats st = integrate(FrameVector({Frame{scan, Eigen::Isometry3d::Identity(), 0, path}}), map, s);
  EXPECT_EQ(st.points, 88206u);
  uint64_t hits = 0;
  map.forEachLeaf([&](const LeafView& l) { hits += l.counters.hits; });
  EXPECT_EQ(hits, 88206u);
  const SessionMapCounts c = map.counts();
  EXPECT_GT(c.occupied_voxels, 5000u);
  EXPECT_GT(c.free_voxels, 10 * c.occupied_voxels);
  EXPECT_EQ(map.stateOf(*map.grid().keyOf({0.1, 0.1, 0.1})), VoxelState::Free);  // the sensor sees around it
}

TEST(RealData, SingleKinectCloudIntegratesAndExports) {
  CHRONOMAP_REQUIRE_DATA(path, "pcl-kinect/office1.pcd");
  auto ds = openDataset(path);
  SessionMap map(0.05);
  const IntegrationStats st = integrate(*ds, map);
  EXPECT_EQ(st.points + st.pointsSkipped(), 640u * 480u);
  EXPECT_GT(st.points, 30000u);  // an office seen from afar: most of it lies beyond 3 m
  EXPECT_GT(st.points_invalid, 0u);
  test::TempDir tmp;
  const size_t n = exportOccupiedPly(tmp / "o.ply", map);
  EXPECT_EQ(n, map.counts().occupied_voxels);
  const PointCloud back = readPly(tmp / "o.ply");
  ASSERT_EQ(back.size(), n);
  // Every exported centre lies in an occupied voxel.
  for (size_t i = 0; i < back.size(); i += 97) {
    EXPECT_EQ(map.stateOf(*map.grid().keyOf(back.points[i].cast<double>())), VoxelState::Occupied);
  }
  exportOctomap(tmp / "o.ot", map);
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read((tmp / "o.ot").string()));
  ASSERT_TRUE(tree);
  auto* colour = dynamic_cast<octomap::ColorOcTree*>(tree.get());
  ASSERT_NE(colour, nullptr);
  EXPECT_DOUBLE_EQ(colour->getResolution(), 0.05);
  size_t occupied = 0;
  for (auto it = colour->begin_leafs(); it != colour->end_leafs(); ++it) {
    if (colour->isNodeOccupied(*it)) occupied += static_cast<size_t>(std::pow(8, 16 - it.getDepth()));
  }
  EXPECT_EQ(occupied, map.counts().occupied_voxels);
  // Our keys are OctoMap's keys: the same voxel is occupied in both.
  size_t checked = 0;
  map.forEachLeaf([&](const LeafView& l) {
    if (l.level != 0 || l.counters.state() != VoxelState::Occupied || checked > 500) return;
    auto* node = colour->search(octomap::OcTreeKey(l.key.x, l.key.y, l.key.z));
    ASSERT_NE(node, nullptr);
    EXPECT_TRUE(colour->isNodeOccupied(node));
    ++checked;
  });
}

}  // namespace
}  // namespace chronomap
