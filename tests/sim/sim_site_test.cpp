// The site preset: floors of their own stacked, patrolled every night; a shorter run is the
// start of a longer one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/core/file.h"
#include "chronomap/sim/building.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::bytesOf;

TEST(SimSite, FloorsAreBuildingsOfTheirOwnStackedAndNumbered) {
  const SceneState site = makeScene("site", 4);
  std::vector<SceneState> floors;
  for (int f = 0; f < kSiteFloors; ++f) floors.push_back(siteFloor(4, f));
  ASSERT_EQ(site.rooms.size(), floors[0].rooms.size() * kSiteFloors);
  size_t k = 0;
  std::set<uint32_t> ids;
  for (int f = 0; f < kSiteFloors; ++f) {
    const double up = f * kSiteFloorHeight_m;
    for (const Object& local : floors[static_cast<size_t>(f)].objects) {
      const Object& o = site.objects.at(k++);
      EXPECT_EQ(o.id, static_cast<uint32_t>(f) * kSiteIdStride + local.id);
      EXPECT_TRUE(ids.insert(o.id).second) << "object ids are unique";
      EXPECT_EQ(o.kind, local.kind);
      EXPECT_EQ(o.present, local.present);
      ASSERT_EQ(o.parts.size(), local.parts.size());
      for (size_t p = 0; p < o.parts.size(); ++p) {
        EXPECT_EQ(o.parts[p].box.min(), local.parts[p].box.min() + Eigen::Vector3d(0, 0, up));
        EXPECT_EQ(o.parts[p].box.max(), local.parts[p].box.max() + Eigen::Vector3d(0, 0, up));
        // Every part lies between its floor's slab and the next one.
        EXPECT_GE(o.parts[p].box.min().z(), up - 0.2);
        EXPECT_LE(o.parts[p].box.max().z(), up + kSiteFloorHeight_m - 0.1);
      }
      if (o.room >= 0) {
        const Room& room = site.rooms.at(static_cast<size_t>(o.room));
        EXPECT_NE(room.name.find("(floor " + std::to_string(f) + ")"), std::string::npos) << room.name;
      }
    }
  }
  EXPECT_EQ(k, site.objects.size());
  for (const Room& r : site.rooms) EXPECT_TRUE(ids.count(r.door_object)) << r.name;
  // Each floor is a building of its own: their furniture differs.
  const auto layout = [](const SceneState& floor) {
    std::vector<double> corners;
    for (const Object& o : floor.objects) {
      for (const Part& p : o.parts) corners.push_back(p.box.min().x() + 7.0 * p.box.min().y());
    }
    return corners;
  };
  EXPECT_NE(layout(floors[0]), layout(floors[1]));
  EXPECT_NE(layout(floors[1]), layout(floors[2]));
  EXPECT_NEAR(site.bounds.max().z(), (kSiteFloors - 1) * kSiteFloorHeight_m + 2.5 + 0.017, 1e-9);
}

TEST(SimSite, NightlyPatrolsOfEveryFloorAndTheFirstSessionsOfALongerRun) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "site";
  s.sessions = 2;
  s.resolution_scale = 0.1;      // 64 x 48
  s.voxel_resolution_m = 0.2;    // a coarse truth: quick
  s.threads = 2;
  s.floors = 2;                  // two floors of the three: quicker, and still stacked
  const SimulationSummary two = chronomap::simulate(s, tmp / "two");
  s.sessions = 1;
  chronomap::simulate(s, tmp / "one");

  const auto scene = nlohmann::json::parse(readTextFile(tmp / "two" / "scene.json"));
  // The change events, spooled to a file while simulating, are spliced in as dump(1) puts them.
  EXPECT_EQ(scene.dump(1) + "\n", readTextFile(tmp / "two" / "scene.json"));
  EXPECT_FALSE(fs::exists(tmp / "two" / ".events.tmp"));
  EXPECT_EQ(scene["preset"], "site");
  EXPECT_EQ(scene["site"]["floors"], 2);
  ASSERT_EQ(scene["sessions"].size(), 2u);
  ASSERT_EQ(two.session_dirs.size(), 2u);
  EXPECT_EQ(two.session_dirs[1].filename(), "session_001");  // three digits: a year of them sorts
  double last_time = 0.0;
  for (const auto& session : scene["sessions"]) {
    const double hour = session["hour"];
    EXPECT_TRUE(hour >= 22.0 || hour < 3.0) << hour;  // at night
    const double time = session["time_s"];
    if (last_time > 0.0) {
      EXPECT_NEAR(time - last_time, 86400.0, 5 * 3600.0);  // every night
    }
    last_time = time;
    // Every floor patrolled, its frames one after the other, the camera 1.2 m above its floor.
    const auto poses = parseTumTrajectory(
        readTextFile(tmp / "two" / session["dir"].get<std::string>() / "groundtruth.txt"), "groundtruth");
    ASSERT_EQ(session["floors"].size(), 2u);
    size_t frames = 0;
    for (const auto& floor : session["floors"]) {
      const size_t first = floor["first_frame"], n = floor["frames"];
      EXPECT_EQ(first, frames);
      EXPECT_GT(n, 100u);
      frames += n;
      const double z = 1.2 + 0.017 + kSiteFloorHeight_m * floor["floor"].get<double>();
      for (size_t i = first; i < first + n; ++i) ASSERT_NEAR(poses.at(i).pose.translation().z(), z, 1e-5);
    }
    EXPECT_EQ(frames, session["frames"].get<size_t>());
    EXPECT_EQ(frames, poses.size());
  }
  // The changes of the night, each naming an object of one of the floors.
  ASSERT_GT(scene["events"].size(), 0u);
  for (const auto& e : scene["events"]) {
    const uint32_t id = e["object"];
    EXPECT_LT(id / kSiteIdStride, 2u);
    EXPECT_LT(id % kSiteIdStride, 1000u);
    EXPECT_EQ(e["cause"], "random");
  }

  // The one-session run is the first session of the two-session run, byte for byte.
  size_t compared = 0;
  for (const auto& e : fs::recursive_directory_iterator(tmp / "one")) {
    if (!e.is_regular_file() || e.path().filename() == "scene.json") continue;
    const fs::path rel = fs::relative(e.path(), tmp / "one");
    ASSERT_EQ(bytesOf(e.path()), bytesOf(tmp / "two" / rel)) << rel;
    ++compared;
  }
  EXPECT_GT(compared, 400u);
  const auto first = nlohmann::json::parse(readTextFile(tmp / "one" / "scene.json"));
  EXPECT_EQ(first["sessions"][0], scene["sessions"][0]);
}

TEST(SimSite, BadFloorCountsAreRefused) {
  test::TempDir tmp;
  SimulationSettings s;
  s.preset = "site";
  for (int floors : {0, 51}) {
    s.floors = floors;
    EXPECT_THROW(chronomap::simulate(s, tmp / "x"), UsageError) << floors;
  }
  EXPECT_FALSE(fs::exists(tmp / "x"));
}

TEST(SimSite, UnknownPresetsNameTheSite) {
  try {
    makeScene("campus", 1);
    FAIL() << "no error";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("site"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace chronomap
