#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/ingest/png.h"
#include "chronomap/pipeline/maps.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/sim/building.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

TEST(PipelineSession, IntegratesADatasetAndRefusesOneWithoutPoints) {
  test::TempDir tmp;
  const IntegratedSession s = integrateDataset(test::writeWallDataset(tmp.path(), "wall", 2.0f), SessionSettings{});
  EXPECT_EQ(s.format, "clouds");
  EXPECT_EQ(s.stats.frames, 1u);
  EXPECT_GT(s.stats.points, 2000u);
  EXPECT_GT(s.map.counts().occupied_voxels, 300u);
  ASSERT_EQ(s.sensor_positions.size(), 1u);
  EXPECT_EQ(s.sensor_positions[0], Eigen::Vector3d::Zero());
  const nlohmann::json meta = sessionMetadata(tmp / "wall.txt", s, SessionSettings{});
  EXPECT_EQ(meta["frames"], 1);
  EXPECT_EQ(meta["format"], "clouds");
  // Every point beyond the range: nothing to integrate is an error, not an empty map.
  SessionSettings short_range;
  short_range.integrator.max_range_m = 1.0;
  EXPECT_THROW(integrateDataset(tmp / "wall.txt", short_range), DataError);
}

TEST(PipelineRegister, DepthCacheChangesNoCorrectionAndKeepsItsBudget) {
  test::TempDir tmp;
  SimulationSettings sim_settings;
  sim_settings.preset = "tiny";
  sim_settings.sessions = 2;
  sim_settings.resolution_scale = 0.25;
  const SimulationSummary simulated = chronomap::simulate(sim_settings, tmp / "sim");
  SessionSettings settings;
  settings.integrator.fast = true;
  RegistrationSettings registration = recommendedRegistration();
  registration.rounds = 1;
  registration.align.drift_rounds = 1;
  // Without a cache, and with one given in the settings with room for a third of the images
  // (used from the first integration on).
  const size_t frame_bytes = 160 * 120 * sizeof(uint16_t);
  const auto cache = std::make_shared<DepthImageCache>(simulated.frames * frame_bytes / 3);
  const auto run = [&](bool cached) {
    SessionSettings s = settings;
    if (cached) s.dataset.depth_cache = cache;
    RegistrationSettings r = registration;
    r.depth_cache_bytes = 0;  // none but the one given
    std::vector<SessionMap> maps;
    std::vector<std::vector<Eigen::Vector3d>> positions;
    for (const fs::path& dir : simulated.session_dirs) {
      IntegratedSession session = integrateDataset(dir, s);
      maps.push_back(std::move(session.map));
      positions.push_back(std::move(session.sensor_positions));
    }
    const std::vector<PoseCorrection> found = registerDatasets(maps, simulated.session_dirs, positions, s, r);
    return std::pair{found, maps};
  };
  const auto [plain, plain_maps] = run(false);
  EXPECT_EQ(cache->images(), 0u);
  const auto [found, maps] = run(true);
  ASSERT_EQ(found.size(), plain.size());
  for (size_t k = 0; k < found.size(); ++k) {
    EXPECT_TRUE(found[k].motion.matrix() == plain[k].motion.matrix()) << k;
    ASSERT_EQ(found[k].per_frame.size(), plain[k].per_frame.size());
    for (size_t i = 0; i < found[k].per_frame.size(); ++i) {
      EXPECT_TRUE(found[k].per_frame[i].matrix() == plain[k].per_frame[i].matrix()) << k << " " << i;
    }
    EXPECT_TRUE(maps[k] == plain_maps[k]) << k;
  }
  // The budget holds: about a third of the images kept, and found again in the later passes.
  EXPECT_GT(cache->images(), simulated.frames / 4);
  EXPECT_LT(cache->images(), simulated.frames / 2);
  EXPECT_LE(cache->bytes(), cache->budget_bytes());
  EXPECT_GT(cache->hits(), cache->images());
}

TEST(PipelineRegister, PresetsByName) {
  const RegistrationSettings localiser = registrationNamed("localiser");
  EXPECT_EQ(localiser.align.drift_knot_frames, 20);
  EXPECT_EQ(localiser.align.drift_knot_m, 0.0);
  EXPECT_EQ(localiser.align.radius_voxels, 2.0);
  EXPECT_TRUE(localiser.align.planar && localiser.align.drift_points);
  EXPECT_FALSE(localiser.align.keep_mean);
  const RegistrationSettings odometry = registrationNamed("odometry");
  EXPECT_EQ(odometry.rounds, 3);
  EXPECT_EQ(odometry.align.drift_knot_frames, 0);
  EXPECT_EQ(odometry.align.drift_knot_m, 0.5);
  EXPECT_EQ(odometry.align.radius_voxels, 6.0);
  EXPECT_EQ(odometry.align.fine_radius_voxels, 3.0);
  EXPECT_EQ(odometry.align.drift_rounds, 3);
  EXPECT_TRUE(odometry.align.planar && odometry.align.drift_points && odometry.align.keep_mean);
  EXPECT_NO_THROW(odometry.align.validate());
  EXPECT_NO_THROW(localiser.align.validate());
  try {
    registrationNamed("recommended");
    ADD_FAILURE() << "an unknown name was accepted";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("localiser or odometry"), std::string::npos) << e.what();
  }
}

TEST(PipelineBuild, SortsByTimeAndRefusesClashesBeforeIntegrating) {
  test::TempDir tmp;
  BuildSettings s;
  s.map = tmp / "map.cmap";
  s.datasets = {test::writeWallDataset(tmp.path(), "late", 2.0f), test::writeWallDataset(tmp.path(), "early", 2.5f)};
  s.times_s = {200.0, 100.0};
  size_t steps = 0;
  s.progress.step = [&](const std::string&) { ++steps; };
  const BuildResult r = build(s);
  EXPECT_TRUE(r.created);
  EXPECT_EQ(r.sessions, 2u);
  ASSERT_EQ(r.added.size(), 2u);
  EXPECT_EQ(r.added[0].time_s, 100.0);  // time order, not argument order
  EXPECT_EQ(r.added[0].dataset.filename(), "early.txt");
  EXPECT_FALSE(r.added[0].correction);
  EXPECT_EQ(steps, 2u);  // one line per dataset
  EXPECT_EQ(readTemporalMap(s.map).sessionCount(), 2u);
  EXPECT_EQ(r.file_bytes, fs::file_size(s.map));
  // A time the map holds already, without replace: refused, the map unchanged.
  const auto before = test::bytesOf(s.map);
  s.times_s = {100.0, 300.0};
  EXPECT_THROW(build(s), UsageError);
  EXPECT_EQ(test::bytesOf(s.map), before);
  // Times missing for datasets that carry none.
  s.map = tmp / "other.cmap";
  s.times_s.clear();
  EXPECT_THROW(build(s), UsageError);
  EXPECT_FALSE(fs::exists(s.map));
}

TEST(PipelineAdd, AppendsOrRewritesAsThePolicySays) {
  test::TempDir tmp;
  for (int i = 0; i < 4; ++i) {
    writeSessionMap(tmp / ("s" + std::to_string(i) + ".cmap"), test::randomSessionMap(40 + i, 16, 0.3),
                        {{"recorded_at", 1000.0 * i}});
  }
  AddSessionSettings s;
  s.map = tmp / "map.cmap";
  s.session = tmp / "s0.cmap";
  AddSessionResult r = addSession(s);
  EXPECT_TRUE(r.created);
  EXPECT_FALSE(r.appended);
  EXPECT_EQ(r.time_s, 0.0);  // from the file's metadata
  s.session = tmp / "s1.cmap";
  s.write = WritePolicy::Append;
  const auto first = test::bytesOf(s.map);
  r = addSession(s);
  EXPECT_TRUE(r.appended);
  EXPECT_GT(r.record_bytes, 0u);
  EXPECT_EQ(r.file_bytes, first.size() + r.record_bytes);
  const auto appended = test::bytesOf(s.map);
  EXPECT_TRUE(std::equal(first.begin(), first.end(), appended.begin()));  // the bytes before it untouched
  s.session = tmp / "s2.cmap";
  s.write = WritePolicy::Rewrite;
  r = addSession(s);
  EXPECT_FALSE(r.appended);
  EXPECT_EQ(r.sessions, 3u);
  s.session = tmp / "s3.cmap";
  s.write = WritePolicy::Auto;
  s.time_s = 5000.0;  // given, overrides the file's
  r = addSession(s);
  EXPECT_EQ(r.time_s, 5000.0);
  const TemporalMap map = readTemporalMap(s.map);
  ASSERT_EQ(map.sessionCount(), 4u);
  EXPECT_EQ(map.sessions().back().time_s, 5000.0);
  // A session without a recorded time and none given.
  writeSessionMap(tmp / "untimed.cmap", test::wallSession(10), {});
  s.session = tmp / "untimed.cmap";
  s.time_s.reset();
  EXPECT_THROW(addSession(s), UsageError);
  EXPECT_EQ(parseWritePolicy("append"), WritePolicy::Append);
  EXPECT_THROW(parseWritePolicy("sometimes"), UsageError);
}

TEST(PipelineMaps, MapReferencesAndTheDiffOfTwoTimesEqualsTheDiffOfTheirSnapshots) {
  test::TempDir tmp;
  EXPECT_FALSE(parseMapRef("a.cmap").time_s);
  const MapRef ref = parseMapRef("a.cmap@1000");
  EXPECT_EQ(ref.path, "a.cmap");
  EXPECT_EQ(ref.time_s, 1000.0);
  std::ofstream(tmp / "odd@name.cmap") << "x";
  EXPECT_FALSE(parseMapRef((tmp / "odd@name.cmap").string()).time_s);  // an existing file wins

  TemporalMap map(0.05);
  for (int i = 0; i < 4; ++i) map.add(100.0 * i, test::randomSessionMap(70 + i, 16, 0.3));
  writeTemporalMap(tmp / "map.cmap", map, {});
  const std::string m = (tmp / "map.cmap").string();
  DiffSettings settings;
  const DiffMap fast = diffMaps(parseMapRef(m + "@100"), parseMapRef(m + "@300"), settings);
  const DiffMap slow = diff(map.snapshot(100.0), map.snapshot(300.0), settings);
  EXPECT_EQ(fast.voxelCount(ChangeKind::Appeared), slow.voxelCount(ChangeKind::Appeared));
  EXPECT_EQ(fast.voxelCount(ChangeKind::Vanished), slow.voxelCount(ChangeKind::Vanished));
  EXPECT_GT(slow.voxelCount(), 0u);
  EXPECT_THROW(diffMaps(parseMapRef(m), parseMapRef(m + "@300"), settings), UsageError);  // a 4D map needs a time
  EXPECT_THROW(snapshotAt(map, -50.0, m), UsageError);          // before the first session (at 0)
}

TEST(PipelineMaps, ExportsByExtension) {
  test::TempDir tmp;
  const SessionMap map = test::wallSession(10);
  EXPECT_EQ(exportSessionMap(tmp / "m.cmap", map), map.leafCount());
  EXPECT_EQ(readSessionMap(tmp / "m.cmap").counts().occupied_voxels, map.counts().occupied_voxels);
  EXPECT_EQ(exportSessionMap(tmp / "m.ply", map), map.counts().occupied_voxels);
  EXPECT_GT(exportSessionMap(tmp / "m.ot", map), 0u);
  ExportSettings big;
  big.pixels_per_voxel = 4;
  // The picture has its frame of axes, scale bar and legend (render/top_view.h), whose size does
  // not follow the map's pixels (it was exactly 16 times as many pixels before the frame); the
  // count returned is the file's.
  const size_t small = exportSessionMap(tmp / "m1.png", map, {1, {}});
  const size_t large = exportSessionMap(tmp / "m4.png", map, big);
  const ImageRgb one = readPngRgb(tmp / "m1.png"), four = readPngRgb(tmp / "m4.png");
  EXPECT_EQ(small, size_t{one.width} * one.height);
  EXPECT_EQ(large, size_t{four.width} * four.height);
  EXPECT_NE(small, large);
  EXPECT_THROW(exportSessionMap(tmp / "m.txt", map), UsageError);
  EXPECT_FALSE(fs::exists(tmp / "m.txt"));
}

}  // namespace
}  // namespace chronomap
