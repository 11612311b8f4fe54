#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <map>
#include <set>

#include "chronomap/core/error.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/core/file.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/change_truth.h"
#include "sim/internal.h"
#include "test_support.h"
#include "builders.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::bytesOf;

/// Every file below `root`, relative, sorted.
std::vector<fs::path> filesBelow(const fs::path& root) {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    if (e.is_regular_file()) out.push_back(fs::relative(e.path(), root));
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Distance from p to the nearest surface of a present part.
double distanceToSurface(const SceneState& state, const Eigen::Vector3d& p) {
  double best = 1e9;
  for (const auto& o : state.objects) {
    if (!o.present) continue;
    for (const auto& part : o.parts) {
      const Eigen::Vector3d lo = part.box.min(), hi = part.box.max();
      const Eigen::Vector3d outside = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
      double d = outside.norm();
      if (d == 0.0) d = std::min((p - lo).minCoeff(), (hi - p).minCoeff());  // inside: to the nearest face
      best = std::min(best, d);
    }
  }
  return best;
}

TEST(Simulator, SameSeedSameBytesWhateverTheThreads) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "tiny";
  s.sessions = 2;
  s.resolution_scale = 0.25;
  s.threads = 1;
  chronomap::simulate(s, tmp / "a");
  s.threads = 2;
  chronomap::simulate(s, tmp / "b");
  const auto files = filesBelow(tmp / "a");
  ASSERT_EQ(files, filesBelow(tmp / "b"));
  ASSERT_GT(files.size(), 20u);
  for (const auto& f : files) EXPECT_EQ(bytesOf(tmp / "a" / f), bytesOf(tmp / "b" / f)) << f;
  // scene.json, its change events spliced in from a spool, is what nlohmann::json writes.
  const std::string scene = readTextFile(tmp / "a" / "scene.json");
  EXPECT_EQ(nlohmann::json::parse(scene).dump(1) + "\n", scene);
  s.seed = 2;
  chronomap::simulate(s, tmp / "c");
  EXPECT_NE(bytesOf(tmp / "a" / "scene.json"), bytesOf(tmp / "c" / "scene.json"));
}

TEST(Simulator, DepthNoiseFollowsTheModel) {
  const SceneState scene = makeScene("tiny", 3);
  const Renderer renderer(scene);
  SensorModel sensor;
  sensor.edge_dropout = 0.0;
  sensor.dark_dropout = 0.0;
  const Camera camera = kinectCamera(0.5);
  double sum = 0.0, sum2 = 0.0;
  size_t n = 0;
  for (int view = 0; view < 4; ++view) {
    const auto f = renderer.render(camera, test::cameraLooking({1.0, 1.75, 1.2}, 1.5708 * view), sensor, 12.0, 100 + view);
    for (size_t i = 0; i < f.true_depth_m.size(); ++i) {
      const double z = f.true_depth_m[i];
      if (z < 1.0 || f.depth.pixels[i] == 0) continue;
      const double e = (f.depth.pixels[i] / sensor.depth_scale - z) / (z * z);
      sum += e;
      sum2 += e * e;
      ++n;
    }
  }
  ASSERT_GT(n, 20000u);
  const double mean = sum / static_cast<double>(n);
  const double sigma = std::sqrt(sum2 / static_cast<double>(n) - mean * mean);
  EXPECT_NEAR(sigma, sensor.noise_per_m2, 0.1 * sensor.noise_per_m2) << n << " pixels";
  EXPECT_LT(std::abs(mean), 0.1 * sensor.noise_per_m2);
}

TEST(Simulator, FramesReprojectOntoTheTrueSurfaces) {
  const SceneState scene = makeScene("office", 4);
  const Renderer renderer(scene);
  SensorModel sensor;
  sensor.noise_per_m2 = 0.0;
  const Camera camera = kinectCamera(0.25);
  const CameraIntrinsics k{camera.fx, camera.fy, camera.cx, camera.cy};
  size_t points = 0;
  for (double yaw : {0.0, 1.0, 2.0, 3.0, 4.5}) {
    const Eigen::Isometry3d T = test::cameraLooking({3.0, 1.0, 1.2}, yaw);
    const auto f = renderer.render(camera, T, sensor, 10.0, 1);
    const PointCloud cloud = depthToCloud(f.depth, &f.rgb, k, sensor.depth_scale, "frame");
    for (const auto& p : cloud.points) {
      if (!p.allFinite()) continue;
      const Eigen::Vector3d w = T * p.cast<double>();
      ASSERT_LT(distanceToSurface(scene, w), 1e-3) << "point " << w.transpose();
      ++points;
    }
  }
  EXPECT_GT(points, 5000u);
}

TEST(Simulator, ChangeEventsShowInTheTruth) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "office";
  s.sessions = 5;
  s.resolution_scale = 0.1;
  chronomap::simulate(s, tmp.path());
  const auto scene = nlohmann::json::parse(readTextFile(tmp / "scene.json"));
  ASSERT_EQ(scene["sessions"].size(), 5u);
  ASSERT_GT(scene["events"].size(), 3u);
  std::vector<std::vector<VoxelKey>> truth;
  for (int i = 0; i < 5; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "occupancy_%02d.cmap", i);
    const SessionMap m = readSessionMap(tmp / "truth" / name);
    truth.emplace_back();
    m.forEachLeaf([&](const LeafView& l) { truth.back().push_back(l.key); });
    std::sort(truth.back().begin(), truth.back().end());
  }
  auto has = [&](int session, const VoxelKey& k) {
    return std::binary_search(truth[static_cast<size_t>(session)].begin(), truth[static_cast<size_t>(session)].end(), k);
  };
  std::set<std::string> kinds;
  for (const auto& e : scene["events"]) {
    const int from = e["from_session"], to = e["to_session"];
    ASSERT_EQ(to, from + 1);
    ASSERT_FALSE(e["voxels"].empty()) << e["kind"];
    kinds.insert(e["kind"].get<std::string>());
    for (const auto& v : e["voxels"]) {
      const VoxelKey k{v[0].get<uint16_t>(), v[1].get<uint16_t>(), v[2].get<uint16_t>()};
      ASSERT_NE(has(from, k), has(to, k)) << "event " << e["kind"] << " of object " << e["object"];
    }
  }
  EXPECT_GE(kinds.size(), 2u);
  // The evaluators read back the events the simulator wrote.
  const std::vector<ChangeEvent> events = readTruthEvents(tmp / "scene.json");
  ASSERT_EQ(events.size(), scene["events"].size());
  for (size_t i = 0; i < events.size(); ++i) {
    const auto& e = scene["events"][i];
    EXPECT_EQ(events[i].from_session, e["from_session"].get<uint32_t>());
    EXPECT_EQ(events[i].object, e["object"].get<uint32_t>());
    EXPECT_EQ(toString(events[i].object_kind), e["object_kind"].get<std::string>());
    EXPECT_EQ(toString(events[i].kind), e["kind"].get<std::string>());
    EXPECT_EQ(events[i].voxels.size(), e["voxel_count"].get<size_t>());
  }
}

TEST(Simulator, TheWeeksPresetFollowsItsScheduleAndSaysSo) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "weeks";
  s.sessions = 14;  // the first week
  s.resolution_scale = 0.1;
  const SimulationSummary summary = chronomap::simulate(s, tmp.path());
  const auto scene = nlohmann::json::parse(readTextFile(tmp / "scene.json"));
  ASSERT_EQ(scene["sessions"].size(), 14u);
  // Two sessions a day from the first Monday, one before noon and one after.
  for (size_t i = 0; i < 14; ++i) {
    const double t = summary.times_s[i];
    EXPECT_EQ(static_cast<int>((t - kScheduleStart_s) / 86400.0), static_cast<int>(i / 2));
    EXPECT_EQ(summary.hours[i] >= 12.0, i % 2 == 1);
    EXPECT_EQ(scene["sessions"][i]["weekday"].get<int>(), static_cast<int>(i / 2) % 7);
  }
  // The true schedule: seven routines with their objects, and each day's exceptions.
  const auto& schedule = scene["schedule"];
  ASSERT_EQ(schedule["routines"].size(), 7u);
  ASSERT_EQ(schedule["days"].size(), 7u);
  std::map<uint32_t, std::string> routine_of;
  for (const auto& r : schedule["routines"]) {
    EXPECT_FALSE(r["rule"].get<std::string>().empty());
    for (const auto& id : r["objects"]) routine_of[id.get<uint32_t>()] = r["name"];
  }
  for (int d = 0; d < 7; ++d) {
    EXPECT_EQ(schedule["days"][d]["worker_away"].get<bool>(), scheduleDay(s.seed, d).worker_away);
  }
  // Every change is a routine's, on one of that routine's objects; the true state of every
  // session is the schedule's at its time.
  ASSERT_FALSE(scene["events"].empty());
  for (const auto& e : scene["events"]) {
    EXPECT_EQ(e["cause"], "routine");
    EXPECT_EQ(routine_of.at(e["object"].get<uint32_t>()), e["routine"]);
  }
  const SceneState home = makeScene("weeks", s.seed);
  for (size_t i = 0; i < 14; i += 5) {
    SceneState state = home;
    applySchedule(state, home, s.seed, summary.times_s[i]);
    char name[64];
    std::snprintf(name, sizeof name, "occupancy_%02zu.cmap", i);
    EXPECT_EQ(readSessionMap(tmp / "truth" / name), sim_detail::truthMap(truthOccupancy(state, KeyGrid(0.05)),
                                                                      KeyGrid(0.05)))
        << "session " << i;
  }
  // Other presets' changes are random.
  test::TempDir office;
  s.preset = "office";
  s.sessions = 3;
  chronomap::simulate(s, office.path());
  const auto office_scene = nlohmann::json::parse(readTextFile(office / "scene.json"));
  EXPECT_FALSE(office_scene.contains("schedule"));
  for (const auto& e : office_scene["events"]) EXPECT_EQ(e["cause"], "random");
}

TEST(Simulator, RareEventsAreLabelledInTheTruth) {
  // Eight sessions of the weeks preset with rare events: the last quarter (sessions 6 and 7)
  // holds them, as rareEventOf() says; each is an event labelled rare, with its voxels, and the
  // next session's undoing of it is labelled after_rare.
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "weeks";
  s.sessions = 8;
  s.resolution_scale = 0.1;
  s.rare_events = true;
  const SimulationSummary summary = chronomap::simulate(s, tmp.path());
  const auto scene = nlohmann::json::parse(readTextFile(tmp / "scene.json"));
  const auto& rare = scene["schedule"]["rare_events"];
  size_t expected = 0;
  for (int i = 0; i < 8; ++i) {
    const auto kind = rareEventOf(s.seed, i, summary.times_s);
    if (!kind) continue;
    ASSERT_LT(expected, rare.size());
    EXPECT_EQ(rare[expected]["session"], i);
    EXPECT_EQ(rare[expected]["what"], describe(*kind));
    ++expected;
  }
  EXPECT_EQ(rare.size(), expected);
  ASSERT_GE(expected, 1u);
  std::set<int> rare_sessions;
  size_t labelled = 0;
  for (const auto& e : scene["events"]) {
    const std::string cause = e["cause"];
    EXPECT_TRUE(cause == "routine" || cause == "rare" || cause == "after_rare") << cause;
    if (cause != "rare") continue;
    ++labelled;
    EXPECT_GT(e["voxel_count"].get<size_t>(), 100u);
    EXPECT_EQ(e["voxels"].size(), e["voxel_count"].get<size_t>());
    rare_sessions.insert(e["to_session"].get<int>());
  }
  EXPECT_GE(labelled, 1u);
  for (const auto& e : scene["events"]) {
    if (e["cause"] == "after_rare") {
      EXPECT_TRUE(rare_sessions.count(e["to_session"].get<int>() - 1)) << e.dump();
    }
  }
  // readTruthEvents keeps the cause and what happened.
  size_t read_rare = 0;
  for (const ChangeEvent& e : readTruthEvents(tmp / "scene.json")) read_rare += e.cause == "rare";
  EXPECT_EQ(read_rare, labelled);
  // Not for the other presets.
  s.preset = "office";
  test::TempDir office;
  EXPECT_THROW(chronomap::simulate(s, office.path()), UsageError);
}

TEST(Simulator, DaylightAndRepaintChangeOnlyColoursAndAreLabelled) {
  // Four sessions of the weeks preset, with and without the daylight and the repaint: depth,
  // poses, truth and change events are the same bytes; colour images differ; scene.json holds
  // the true light curves and the repaint with the desk's voxels.
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "weeks";
  s.sessions = 4;
  s.resolution_scale = 0.1;
  s.threads = 1;
  chronomap::simulate(s, tmp / "plain");
  s.lighting = "daylight";
  s.repaint = true;
  const SimulationSummary summary = chronomap::simulate(s, tmp / "lit");
  const auto files = filesBelow(tmp / "plain");
  ASSERT_EQ(files, filesBelow(tmp / "lit"));
  size_t rgb_differ = 0, repainted_objects_files = 0;
  for (const auto& f : files) {
    const std::string name = f.string();
    const bool same = bytesOf(tmp / "plain" / f) == bytesOf(tmp / "lit" / f);
    if (name.find("/rgb/") != std::string::npos) {
      rgb_differ += !same;
    } else if (name.find("objects_") != std::string::npos) {
      repainted_objects_files += !same;  // the desk's colour, from the repaint on
    } else if (name != "scene.json") {
      EXPECT_TRUE(same) << name;
    }
  }
  EXPECT_GT(rgb_differ, 0u);
  EXPECT_EQ(repainted_objects_files, 1u);  // session 3 of 4: 4 - 4 / 4
  const auto plain = nlohmann::json::parse(readTextFile(tmp / "plain" / "scene.json"));
  auto lit = nlohmann::json::parse(readTextFile(tmp / "lit" / "scene.json"));
  EXPECT_FALSE(plain.contains("lighting"));
  EXPECT_FALSE(plain.contains("repaints"));
  ASSERT_TRUE(lit.contains("lighting"));
  const auto& light = lit["lighting"];
  ASSERT_EQ(light["hours"].size(), 97u);
  for (size_t q = 0; q < 97; q += 7) {
    const double h = light["hours"][q];
    EXPECT_DOUBLE_EQ(light["ceiling"][q][0].get<double>(), Daylight::ceiling(h).x());
    EXPECT_DOUBLE_EQ(light["daylight"][q][2].get<double>(), Daylight::daylight(h).z());
  }
  ASSERT_EQ(lit["repaints"].size(), 1u);
  const auto& r = lit["repaints"][0];
  EXPECT_EQ(r["to_session"], 3);
  EXPECT_EQ(r["object_kind"], "table");  // the kitchen table: no routine moves it
  EXPECT_GT(r["voxel_count"].get<size_t>(), 100u);
  EXPECT_EQ(r["voxels"].size(), r["voxel_count"].get<size_t>());
  const auto objects = nlohmann::json::parse(readTextFile(tmp / "lit" / "truth" / "objects_03.json"));
  bool found = false;
  for (const auto& o : objects) {
    if (o["id"] != r["object"]) continue;
    found = true;
    EXPECT_EQ(o["parts"][0]["color"], r["to"]);
  }
  EXPECT_TRUE(found);
  lit.erase("lighting");
  lit.erase("repaints");
  EXPECT_EQ(lit, plain);  // the rest of scene.json is the same
  EXPECT_EQ(summary.times_s.size(), 4u);
  s.lighting = "moonlight";
  test::TempDir bad;
  EXPECT_THROW(chronomap::simulate(s, bad.path()), UsageError);
}

TEST(Simulator, DaylightCurves) {
  // Night: only the dim night light; working hours: the lamps; the sun warm when low.
  EXPECT_EQ(Daylight::daylight(3.0), Eigen::Vector3d::Zero());
  EXPECT_EQ(Daylight::daylight(21.0), Eigen::Vector3d::Zero());
  EXPECT_LT(Daylight::ceiling(3.0).x(), 0.1);
  EXPECT_GT(Daylight::ceiling(12.0).x(), 0.5);
  const Eigen::Vector3d dusk = Daylight::daylight(18.5), noon = Daylight::daylight(12.75);
  EXPECT_GT(dusk.x(), 2.0 * dusk.z());             // warm at sunset
  EXPECT_NEAR(noon.x(), noon.z(), 1e-3);            // white when high
  EXPECT_EQ(Daylight::daylight(12.0 + 24.0), Daylight::daylight(12.0));
  Daylight d;
  d.building = Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(10, 6, 3));
  EXPECT_DOUBLE_EQ(d.window(Eigen::Vector3d(5, 0, 1)), 1.0);
  EXPECT_NEAR(d.window(Eigen::Vector3d(5, 3, 1)), std::exp(-1.5), 1e-12);
  const Eigen::Vector3d at = d.at(18.5, Eigen::Vector3d(5, 3, 1));
  EXPECT_TRUE(at.isApprox(Daylight::ceiling(18.5) + std::exp(-1.5) * dusk));
}

TEST(Simulator, TinySessionWithTruePosesMatchesTheTruth) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "tiny";
  s.sessions = 1;
  s.resolution_scale = 0.5;
  const auto summary = chronomap::simulate(s, tmp.path());
  DatasetSettings dopt;
  dopt.trajectory = (summary.session_dirs[0] / "groundtruth.txt").string();
  auto dataset = openDataset(summary.session_dirs[0], dopt);
  SessionMap map(0.05);
  integrate(*dataset, map, IntegratorSettings{});
  const SessionMap truth_map = readSessionMap(tmp / "truth" / "occupancy_00.cmap");
  std::vector<VoxelKey> truth;
  truth_map.forEachLeaf([&](const LeafView& l) { truth.push_back(l.key); });
  const OccupancyScore score = scoreOccupancy(map, truth);
  std::cout << "tiny, true poses: precision " << score.precision << ", recall " << score.recall << " ("
            << score.predicted << " occupied, " << score.truth_known << " truth voxels observed)\n";
  EXPECT_GE(score.precision, 0.9);
  EXPECT_GE(score.recall, 0.9);
  EXPECT_GT(score.predicted, 1000u);
}

TEST(Simulator, RejectsBadSettings) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "castle";
  EXPECT_THROW(chronomap::simulate(s, tmp.path()), UsageError);
  s.preset = "tiny";
  s.resolution_scale = 3.0;
  EXPECT_THROW(chronomap::simulate(s, tmp.path()), UsageError);
  s.resolution_scale = 0.25;
  s.sessions = -1;
  EXPECT_THROW(chronomap::simulate(s, tmp.path()), UsageError);
}

}  // namespace
}  // namespace chronomap
