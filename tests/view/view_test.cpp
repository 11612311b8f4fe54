// The viewer's library side: snapshots with a level of detail against the 4D map's own
// snapshot, packets, the API's answers and refusals, tours.

#include <gtest/gtest.h>

#include <limits>
#include <map>
#include <set>
#include <tuple>
#include <vector>

#include "assets.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"
#include "chronomap/view/api.h"
#include "chronomap/view/packet.h"
#include "chronomap/view/scene.h"
#include "chronomap/view/tour.h"
#include "pipeline/demo_report.h"
#include "test_support.h"

namespace chronomap {
namespace {

using test::randomSessionMap;

// Four sessions of a random 24^3 block, one every 1000 s: most voxels change state.
TemporalMap fourSessions() {
  TemporalMap map(0.05);
  for (int s = 0; s < 4; ++s) map.add(1000.0 * (s + 1), randomSessionMap(100 + s, 24, 0.2));
  return map;
}

// The occupied unit voxels of the map's own snapshot, grouped into cells at `level`:
// cell corner -> occupied voxels in it.
std::map<VoxelKey, uint64_t> referenceCells(const TemporalMap& map, double t, int level) {
  std::map<VoxelKey, uint64_t> cells;
  map.snapshot(t).forEachLeaf([&](const LeafView& leaf) {
    if (leaf.counters.state() != VoxelState::Occupied) return;
    ASSERT_EQ(leaf.level, 0);
    const auto mask = static_cast<uint16_t>(~((1u << level) - 1u));
    ++cells[VoxelKey{static_cast<uint16_t>(leaf.key.x & mask), static_cast<uint16_t>(leaf.key.y & mask),
                     static_cast<uint16_t>(leaf.key.z & mask)}];
  });
  return cells;
}

std::map<VoxelKey, uint64_t> cellsOf(const VoxelSet& v) {
  std::map<VoxelKey, uint64_t> cells;
  for (size_t i = 0; i < v.keys.size(); ++i) cells[v.keys[i]] = v.members[i];
  return cells;
}

TEST(ViewSnapshot, UnitVoxelsAreTheSnapshotsOccupiedVoxels) {
  const TemporalMap map = fourSessions();
  for (double t : {1000.0, 2500.0, 4000.0}) {
    const VoxelSet v = snapshotVoxels(map, SnapshotRequest{t, 1000000, 0, std::nullopt});
    EXPECT_EQ(v.level, 0);
    const auto ref = referenceCells(map, t, 0);
    EXPECT_EQ(cellsOf(v), ref) << "t=" << t;
    EXPECT_EQ(v.occupied_voxels, ref.size());
    ASSERT_TRUE(v.rank.has_value());
    for (size_t i = 0; i < v.keys.size(); ++i) {
      // Colour and age come from the entry valid at t.
      const auto value = map.valueAt(v.keys[i], t);
      ASSERT_TRUE(value);
      EXPECT_EQ(v.colours[i], value->meanColour());
      EXPECT_LE(v.since[i], *v.rank);
      EXPECT_EQ(map.history(v.keys[i]).size() > 1 || v.changes[i] == 0, true);
    }
  }
}

TEST(ViewSnapshot, BudgetPicksTheFinestLevelThatFits) {
  const TemporalMap map = fourSessions();
  const size_t occupied = referenceCells(map, 4000, 0).size();
  const auto level1 = referenceCells(map, 4000, 1), level2 = referenceCells(map, 4000, 2);
  ASSERT_GT(occupied, level1.size());
  ASSERT_GT(level1.size(), level2.size());
  // Room for the level-1 cells but not for the unit voxels: level 1.
  VoxelSet v = snapshotVoxels(map, SnapshotRequest{4000, level1.size(), 0, std::nullopt});
  EXPECT_EQ(v.level, 1);
  EXPECT_EQ(cellsOf(v), level1);
  EXPECT_EQ(v.occupied_voxels, occupied);
  // One cell fewer: level 2.
  v = snapshotVoxels(map, SnapshotRequest{4000, level1.size() - 1, 0, std::nullopt});
  EXPECT_EQ(v.level, 2);
  EXPECT_EQ(cellsOf(v), level2);
  // A coarse first picture on request.
  v = snapshotVoxels(map, SnapshotRequest{4000, 1000000, 2, std::nullopt});
  EXPECT_EQ(v.level, 2);
  // The 24^3 block lies in one aligned cube of 32^3 voxels: level 5 for a budget of one cell.
  v = snapshotVoxels(map, SnapshotRequest{4000, 1, 0, std::nullopt});
  EXPECT_EQ(v.level, 5);
  ASSERT_EQ(v.keys.size(), 1u);
  EXPECT_EQ(v.members[0], occupied);
  EXPECT_EQ(v.occupied_voxels, occupied);
}

TEST(ViewSnapshot, RegionAndTimesBeforeTheFirstSession) {
  const TemporalMap map = fourSessions();
  const VoxelKey lo = test::at(0, 0, 0), hi = test::at(7, 23, 23);
  const VoxelSet v = snapshotVoxels(map, SnapshotRequest{4000, 1000000, 0, std::array<VoxelKey, 2>{lo, hi}});
  auto ref = referenceCells(map, 4000, 0);
  std::erase_if(ref, [&](const auto& kv) { return kv.first.x > hi.x; });
  EXPECT_EQ(cellsOf(v), ref);
  EXPECT_TRUE(snapshotVoxels(map, SnapshotRequest{999, 10, 0, std::nullopt}).keys.empty());
  EXPECT_THROW(snapshotVoxels(map, SnapshotRequest{4000, 0, 0, std::nullopt}), UsageError);
  EXPECT_THROW(snapshotVoxels(map, SnapshotRequest{4000, 10, kMaxLevel + 1, std::nullopt}), UsageError);
}

TEST(ViewPacket, RoundTripAndBadInput) {
  const TemporalMap map = fourSessions();
  const VoxelSet v = snapshotVoxels(map, SnapshotRequest{3000, 1000000, 0, std::nullopt});
  const Packet p = readPacket(encodeSnapshot(v, map));
  EXPECT_EQ(p.header["cells"], v.keys.size());
  EXPECT_EQ(p.header["rank"], 2);
  const auto keys = p.values<uint16_t>("keys");
  ASSERT_EQ(keys.size(), 3 * v.keys.size());
  for (size_t i = 0; i < v.keys.size(); ++i) {
    EXPECT_EQ((VoxelKey{keys[3 * i], keys[3 * i + 1], keys[3 * i + 2]}), v.keys[i]);
  }
  EXPECT_EQ(p.values<uint32_t>("members"), v.members);
  EXPECT_EQ(p.values<uint16_t>("since"), v.since);
  EXPECT_THROW(readPacket("CMV2...."), FormatError);
  std::string truncated = encodeSnapshot(v, map);
  truncated.resize(truncated.size() - 1);
  EXPECT_THROW(readPacket(truncated), FormatError);
  EXPECT_THROW(p.bytes("nothing"), FormatError);
}

TEST(ViewDiff, SameObjectsAsDiffAndSegmentWithTheDemosSettings) {
  const TemporalMap map = fourSessions();
  // The viewer's defaults are the demo's, which docs/changes.md measured.
  const ChangeSettings demo = recommendedChangeSettings();
  const DiffRequest defaults = changeSettings();
  EXPECT_EQ(defaults.diff.mode, demo.diff.mode);
  EXPECT_EQ(defaults.diff.neighbourhood_voxels, demo.diff.neighbourhood_voxels);
  EXPECT_EQ(defaults.diff.min_shift_voxels, demo.diff.min_shift_voxels);
  EXPECT_EQ(defaults.diff.shift_plane_ratio, demo.diff.shift_plane_ratio);
  EXPECT_EQ(defaults.diff.kept_surface_radius_voxels, demo.diff.kept_surface_radius_voxels);
  EXPECT_EQ(defaults.diff.dark_surface_radius_voxels, demo.diff.dark_surface_radius_voxels);
  EXPECT_EQ(defaults.segment.connectivity, demo.segment.connectivity);
  EXPECT_EQ(defaults.segment.min_voxels, demo.segment.min_voxels);

  DiffRequest r = defaults;
  r.t0_s = 1000;
  r.t1_s = 2000;
  r.segment.min_voxels = 1;
  const DiffObjects o = diffObjects(map, r);
  const Segmentation ref = segment(diff(map, 1000, 2000, r.diff), r.segment);
  ASSERT_EQ(o.segmentation.components.size(), ref.components.size());
  ASSERT_FALSE(ref.components.empty());
  const Packet p = readPacket(encodeDiff(o, r, 5));
  EXPECT_EQ(p.header["components"].size(), ref.components.size());
  EXPECT_EQ(p.header["components"][0]["voxels"], ref.components[0].voxels);
  EXPECT_EQ(p.header["cells_sent"], std::min<size_t>(5, o.diff.cells().size()));
  EXPECT_EQ(p.values<uint32_t>("component").size(), p.header["cells_sent"].get<size_t>());
  for (const auto& c : o.segmentation.components) {
    for (uint32_t cell : c.cells) EXPECT_EQ(o.component_of_cell[cell], c.id);
  }
}

TEST(ViewHistory, UnitVoxelAndBusiestVoxelOfACube) {
  const TemporalMap map = fourSessions();
  const VoxelKey k = test::at(3, 4, 5);
  const auto h = historyJson(map, k, 0);
  EXPECT_EQ(h["entries"].size(), map.history(k).size());
  EXPECT_EQ(h["key"], (nlohmann::json{k.x, k.y, k.z}));
  // In a 4^3 cube: an ever-occupied voxel with the most entries.
  const VoxelKey corner = test::at(0, 0, 0);
  const auto c = historyJson(map, corner, 2);
  const VoxelKey chosen{c["key"][0].get<uint16_t>(), c["key"][1].get<uint16_t>(), c["key"][2].get<uint16_t>()};
  size_t most = 0;
  for (int i = 0; i < 64; ++i) {
    const auto h2 = map.history(test::at(i % 4, (i / 4) % 4, i / 16));
    bool occupied = false;
    for (const auto& e : h2) occupied = occupied || e.counters.state() == VoxelState::Occupied;
    if (occupied) most = std::max(most, h2.size());
  }
  EXPECT_EQ(map.history(chosen).size(), most);
  EXPECT_THROW(historyJson(map, test::at(1, 0, 0), 2), UsageError);  // not a corner
  EXPECT_THROW(historyJson(map, corner, kMaxHistoryLevel + 1), UsageError);
}

TEST(ViewApi, AnswersAndRefusals) {
  const TemporalMap map = fourSessions();
  const Api api(map, "four.cmap");
  auto get = [&](const std::string& path, Query q = {}) { return api.get(path, q); };
  EXPECT_EQ(get("/").status, 200);
  EXPECT_NE(get("/").body.find("viewer.js"), std::string::npos);
  EXPECT_EQ(get("/viewer.js").body, std::string(viewerScript()));
  const auto info = nlohmann::json::parse(get("/api/map").body);
  EXPECT_EQ(info["sessions"].size(), 4u);
  EXPECT_EQ(info["name"], "four.cmap");
  const Reply snap = get("/api/snapshot", {{"session", "1"}});
  ASSERT_EQ(snap.status, 200);
  EXPECT_EQ(readPacket(snap.body).header["occupied_voxels"], referenceCells(map, 2000, 0).size());
  EXPECT_EQ(get("/api/snapshot", {{"t", "1970-01-01T00:50:00Z"}}).status, 200);  // 3000 s
  EXPECT_EQ(get("/api/diff", {{"from", "0"}, {"to", "3"}}).status, 200);
  // The objects as JSON: the one call's list (findChanges with the recommended settings), as
  // `chronomap diff --json` and Python print it.
  const Reply objects = get("/api/diff", {{"t0", "1000"}, {"t1", "4000"}, {"format", "json"}});
  ASSERT_EQ(objects.status, 200) << objects.body;
  const auto listed = nlohmann::json::parse(objects.body);
  EXPECT_FALSE(listed["objects"].empty());
  EXPECT_EQ(listed["objects"], changedObjectsJson(findChanges(map, 1000, 4000).objects));
  EXPECT_EQ(listed["settings"], changeSettingsJson(recommendedChangeSettings()));
  EXPECT_EQ(get("/api/diff", {{"from", "0"}, {"to", "3"}, {"format", "xml"}}).status, 400);
  EXPECT_EQ(get("/api/history", {{"key", "32770,32768,32768"}}).status, 200);
  // Anything else of the disk or of the API: 404.
  for (const char* path : {"/../etc/passwd", "/etc/passwd", "/api", "/api/", "/api/map/x", "/viewer.js/..", "/index.htm"}) {
    EXPECT_EQ(get(path).status, 404) << path;
  }
  // Malformed queries, times outside the map, budgets above the limit: 400 with a reason.
  const std::vector<std::pair<std::string, Query>> bad = {
      {"/api/snapshot", {}},
      {"/api/snapshot", {{"session", "4"}}},
      {"/api/snapshot", {{"session", "-1"}}},
      {"/api/snapshot", {{"session", "1x"}}},
      {"/api/snapshot", {{"session", "1"}, {"t", "2000"}}},
      {"/api/snapshot", {{"t", "999"}}},
      {"/api/snapshot", {{"t", "4001"}}},
      {"/api/snapshot", {{"t", "nan"}}},
      {"/api/snapshot", {{"session", "1"}, {"budget", "0"}}},
      {"/api/snapshot", {{"session", "1"}, {"budget", "2000001"}}},
      {"/api/snapshot", {{"session", "1"}, {"budget", "99999999999999999999999"}}},
      {"/api/snapshot", {{"session", "1"}, {"level", "9"}}},
      {"/api/snapshot", {{"session", "1"}, {"region", "1,2,3"}}},
      {"/api/snapshot", {{"session", "1"}, {"region", "5,5,5,4,4,4"}}},
      {"/api/snapshot", {{"session", "1"}, {"region", "0,0,0,1,1,65536"}}},
      {"/api/snapshot", {{"session", "1"}, {"colour", "red"}}},
      {"/api/snapshot", {{"session", "1"}, {"session", "2"}}},
      {"/api/diff", {{"from", "0"}}},
      {"/api/diff", {{"from", "0"}, {"to", "9"}}},
      {"/api/history", {}},
      {"/api/history", {{"key", "1,2"}}},
      {"/api/history", {{"key", "1,2,3,4"}}},
      {"/api/history", {{"key", "1,2,3"}, {"level", "7"}}},
      {"/api/history", {{"key", "1,2,3"}, {"level", "2"}}},
      {"/api/map", {{"x", "1"}}},
      {"/api/predict", {}},
      {"/api/predict", {{"session", "4"}}},
      {"/api/predict", {{"session", "1"}, {"model", "crystal-ball"}}},
  };
  // Bytes that are not UTF-8 in what the error message quotes (found by fuzz_view): still JSON.
  const Reply latin1 = get(std::string("/api/d") + "\xe9" + "ff");
  EXPECT_EQ(latin1.status, 404);
  EXPECT_NO_THROW(nlohmann::json::parse(latin1.body));
  const Reply latin1_query = get("/api/snapshot", {{"session", "\xe9"}});
  EXPECT_EQ(latin1_query.status, 400);
  EXPECT_NO_THROW(nlohmann::json::parse(latin1_query.body));
  for (const auto& [path, query] : bad) {
    const Reply r = get(path, query);
    EXPECT_EQ(r.status, 400) << path << " " << (query.empty() ? "" : query.begin()->first);
    EXPECT_TRUE(nlohmann::json::parse(r.body).contains("error"));
  }
}

// Every refusal names the parameter, quotes the value as received (bytes that do not print are
// escaped, so a NUL does not cut the message short) and says what is allowed.
TEST(ViewApi, RefusalsQuoteTheValueAndSayWhatIsAllowed) {
  const TemporalMap map = fourSessions();
  const Api api(map, "four.cmap");
  auto error = [&](const std::string& path, const Query& query) {
    const Reply r = api.get(path, query);
    EXPECT_EQ(r.status, 400) << path;
    return nlohmann::json::parse(r.body)["error"].get<std::string>();
  };
  // `session=1%00`: before, the message was cut at the NUL and said only "session=1".
  EXPECT_EQ(error("/api/snapshot", {{"session", std::string("1\0", 2)}}),
            "session=1\\x00 is not a session number: expected a whole number from 0 to 3 (the map has 4 sessions)");
  const std::vector<std::tuple<std::string, Query, std::vector<std::string>>> cases = {
      {"/api/snapshot", {{"session", "4"}}, {"session=4 ", "from 0 to 3"}},
      {"/api/snapshot", {{"session", "\t1\n"}}, {"session=\\x091\\x0a ", "from 0 to 3"}},
      {"/api/snapshot", {{"session", "\xe9\x7f\\"}}, {"session=\\xe9\\x7f\\\\ ", "from 0 to 3"}},
      {"/api/snapshot", {}, {"session=", "t=", "give one of"}},
      {"/api/snapshot", {{"session", "1"}, {"t", "2000"}}, {"session=", "t=", "not both"}},
      {"/api/snapshot", {{"t", "nan"}}, {"t=nan ", "ISO-8601", "1970-01-01T00:16:40Z"}},
      {"/api/snapshot", {{"t", std::string("2000\0", 5)}}, {"t=2000\\x00 ", "ISO-8601"}},
      {"/api/snapshot", {{"t", "4001"}}, {"t=4001 ", "outside the map's sessions", "1970-01-01T01:06:40Z"}},
      {"/api/snapshot", {{"session", "1"}, {"budget", "0"}}, {"budget=0 ", "from 1 to 2000000"}},
      {"/api/snapshot", {{"session", "1"}, {"level", "9"}}, {"level=9 ", "from 0 to 8"}},
      {"/api/snapshot", {{"session", "1"}, {"region", "1,2,3"}}, {"region=1,2,3 ", "6 voxel keys", "x0,y0,z0,x1,y1,z1"}},
      {"/api/snapshot", {{"session", "1"}, {"region", "0,0,0,1,1,65536"}}, {"region=0,0,0,1,1,65536: ", "'65536'", "0 to 65535"}},
      {"/api/snapshot", {{"session", "1"}, {"region", "5,5,5,4,4,4"}}, {"region=5,5,5,4,4,4: ", "lower corner"}},
      {"/api/snapshot", {{"session", "1"}, {"colour", "red"}}, {"'colour'", "/api/snapshot", "session, t, budget, level, region"}},
      {"/api/snapshot", {{"session", "1"}, {std::string("x\0y", 3), "1"}}, {"'x\\x00y'"}},
      {"/api/snapshot", {{"session", "1"}, {"session", "2"}}, {"session", "more than once"}},
      {"/api/map", {{"x", "1"}}, {"'x'", "/api/map takes no parameters"}},
      {"/api/diff", {{"from", "0"}}, {"to=", "t1="}},
      {"/api/diff", {{"from", "0"}, {"to", "0"}, {"min_voxels", "-2"}}, {"min_voxels=-2 ", "from 1 to"}},
      {"/api/history", {}, {"key=x,y,z"}},
      {"/api/history", {{"key", "1,2"}}, {"key=1,2 ", "3 voxel keys", "x,y,z"}},
      {"/api/history", {{"key", "1,2,3"}, {"level", "7"}}, {"level=7 ", "from 0 to 6"}},
      {"/api/predict", {{"session", "1"}, {"model", std::string("crystal\0ball", 12)}}, {"model=crystal\\x00ball ", "latest, mean, markov, periodic, hourly or combined"}},
  };
  for (const auto& [path, query, parts] : cases) {
    const std::string message = error(path, query);
    for (const auto& part : parts) EXPECT_NE(message.find(part), std::string::npos) << path << ": " << message << " lacks " << part;
  }
  // What the request path held is escaped as well.
  EXPECT_EQ(nlohmann::json::parse(api.get(std::string("/api/x\0y", 8), {}).body)["error"], "no such path: /api/x\\x00y");
}

// /api/predict: every modelled cube with the probability RhythmModels::predict gives it, from
// models fitted on the first request (to every session) or given in the settings.
TEST(ViewApi, PredictionsAreTheTemporalModels) {
  const TemporalMap map = fourSessions();
  const double inf = std::numeric_limits<double>::infinity();
  const RhythmModels models = fitRhythm(map, -inf, inf);
  ASSERT_GT(models.voxels.size(), 100u);
  auto check = [&](const Api& api, const std::string& model, RhythmModel which, bool fitted) {
    const Reply r = api.get("/api/predict", {{"t", "2500"}, {"model", model}});
    ASSERT_EQ(r.status, 200) << r.body;
    const Packet p = readPacket(r.body);
    EXPECT_EQ(p.header["model"], model);
    EXPECT_EQ(p.header["fit_s"].get<double>() > 0, fitted);
    const auto keys = p.values<uint16_t>("keys");
    const auto levels = p.values<uint8_t>("levels");
    const auto prob = p.values<float>("p");
    ASSERT_EQ(levels.size(), models.voxels.size());
    ASSERT_EQ(keys.size(), 3 * levels.size());
    ASSERT_EQ(prob.size(), levels.size());
    for (size_t i = 0; i < levels.size(); ++i) {
      const VoxelRhythm& v = models.voxels[i];
      ASSERT_EQ((VoxelKey{keys[3 * i], keys[3 * i + 1], keys[3 * i + 2]}), v.corner);
      ASSERT_EQ(levels[i], v.level);
      ASSERT_FLOAT_EQ(prob[i], static_cast<float>(RhythmModels::predict(v, which, 2500.0))) << i;
    }
  };
  const Api fitting(map, "four.cmap");
  check(fitting, "combined", RhythmModel::Combined, true);
  check(fitting, "mean", RhythmModel::Mean, true);
  ApiSettings given;
  given.rhythm = std::make_shared<const RhythmModels>(models);
  check(Api(map, "four.cmap", given), "hourly", RhythmModel::Hourly, false);
  // The cost map is costmap() of the prediction, with the defaults of `chronomap costmap`.
  const Reply c = fitting.get("/api/costmap", {{"session", "2"}});
  ASSERT_EQ(c.status, 200) << c.body;
  const Packet cp = readPacket(c.body);
  const Costmap expected = costmap(predictMap(map, models, RhythmModel::Combined, 3000.0), CostmapSettings{}, &models);
  EXPECT_EQ(cp.header["width"], expected.width);
  EXPECT_EQ(cp.header["height"], expected.height);
  EXPECT_DOUBLE_EQ(cp.header["origin_m"][0].get<double>(), expected.origin_m.x());
  const auto cost = cp.values<uint8_t>("cost");
  ASSERT_EQ(cost.size(), expected.cost.size());
  for (size_t i = 0; i < cost.size(); ++i) ASSERT_EQ(static_cast<int8_t>(cost[i]), expected.cost[i]) << i;
  EXPECT_EQ(fitting.get("/api/costmap", {{"session", "9"}}).status, 400);
  // Models of another resolution are refused.
  RhythmModels other = models;
  other.resolution_m = 0.1;
  given.rhythm = std::make_shared<const RhythmModels>(other);
  EXPECT_EQ(Api(map, "four.cmap", given).get("/api/predict", {{"session", "0"}}).status, 400);
  EXPECT_EQ(Api(map, "four.cmap", given).get("/api/costmap", {{"session", "0"}}).status, 400);
}

// The prediction layer may be asked for any time from the first session to a week past the last
// (the viewer's date and hour field), not only for session times; beyond a week it is refused
// with a message that says the limit.
TEST(ViewApi, PredictionsReachAWeekPastTheLastSession) {
  const TemporalMap map = fourSessions();  // sessions at 1000 .. 4000 s
  const Api api(map, "four.cmap");
  const double inf = std::numeric_limits<double>::infinity();
  const RhythmModels models = fitRhythm(map, -inf, inf);
  const double later_s = 4000.0 + 3 * 24 * 3600.0 + 1800.0;
  for (const std::string& t : {std::string("2500"), exactNumber(later_s), std::string("1970-01-08T01:06:40Z")}) {
    const Reply r = api.get("/api/predict", {{"t", t}});
    ASSERT_EQ(r.status, 200) << t << ": " << r.body;
    const Packet p = readPacket(r.body);
    const double time_s = p.header["time_s"].get<double>();
    EXPECT_EQ(time_s, parseTime(t));
    const auto prob = p.values<float>("p");
    ASSERT_EQ(prob.size(), models.voxels.size());
    for (size_t i = 0; i < prob.size(); i += 37) {
      ASSERT_FLOAT_EQ(prob[i], static_cast<float>(RhythmModels::predict(models.voxels[i], RhythmModel::Combined, time_s)));
    }
    EXPECT_EQ(api.get("/api/costmap", {{"t", t}}).status, 200) << t;
  }
  // 1970-01-08T01:06:40Z is exactly a week past the last session (4000 s); a second later is not.
  for (const char* path : {"/api/predict", "/api/costmap"}) {
    const Reply r = api.get(path, {{"t", "1970-01-08T01:06:41Z"}});
    ASSERT_EQ(r.status, 400) << path;
    const std::string error = nlohmann::json::parse(r.body)["error"];
    EXPECT_NE(error.find("more than a week past the map's last session (1970-01-01T01:06:40Z)"), std::string::npos) << error;
    EXPECT_NE(error.find("1970-01-08T01:06:40Z"), std::string::npos) << error;
    EXPECT_EQ(api.get(path, {{"t", "999"}}).status, 400) << path;  // before the first session
  }
  // Snapshots and diffs keep to the sessions' times.
  EXPECT_EQ(api.get("/api/snapshot", {{"t", exactNumber(later_s)}}).status, 400);
}

TEST(ViewTour, HoldsEverySessionsOccupiedVoxelsAndTheBundle) {
  const TemporalMap map = fourSessions();
  TourReport report;
  const Packet p = readPacket(tourData(map, "four.cmap", TourSettings{}, &report));
  // A map's name need not be UTF-8.
  EXPECT_NO_THROW(readPacket(tourData(map, "f\xfcnf.cmap", TourSettings{})));
  ASSERT_EQ(report.occupied_voxels.size(), 4u);
  for (size_t s = 0; s < 4; ++s) {
    EXPECT_EQ(report.occupied_voxels[s], referenceCells(map, 1000.0 * (s + 1), 0).size());
  }
  EXPECT_EQ(report.level, 0);
  EXPECT_EQ(report.diffs, 4u);  // three consecutive pairs and the first to the last
  // Each pair's objects are the one call's, as the server lists them (/api/diff?format=json), so
  // the tour's "What changed" panel shows the objects and numbers chronomap diff --json prints.
  const Api api(map, "four.cmap");
  size_t listed = 0;
  for (const auto& d : p.header["diffs"]) {
    const std::string from = std::to_string(d["from"].get<int>()), to = std::to_string(d["to"].get<int>());
    const Reply r = api.get("/api/diff", {{"from", from}, {"to", to}, {"format", "json"}});
    ASSERT_EQ(r.status, 200) << r.body;
    ASSERT_TRUE(d.contains("objects")) << from << " -> " << to;
    EXPECT_EQ(d["objects"], nlohmann::json::parse(r.body)["objects"]) << from << " -> " << to;
    listed += d["objects"].size();
  }
  EXPECT_GT(listed, 0u);
  // The cells occupied in session s per the 2-bit states are that session's occupied voxels.
  const auto keys = p.values<uint16_t>("keys");
  const auto states = p.values<uint8_t>("states");
  for (size_t s = 0; s < 4; ++s) {
    std::map<VoxelKey, uint64_t> cells;
    for (size_t c = 0; c < keys.size() / 3; ++c) {
      if (((states[c] >> (2 * s)) & 3) == 2) cells[VoxelKey{keys[3 * c], keys[3 * c + 1], keys[3 * c + 2]}] = 1;
    }
    EXPECT_EQ(cells, referenceCells(map, 1000.0 * (s + 1), 0)) << "session " << s;
  }
  // A small budget coarsens the tour.
  TourSettings small;
  small.max_voxels = 50;
  tourData(map, "four.cmap", small, &report);
  EXPECT_GT(report.level, 0);
  // A byte budget below the timeline's size (cells x (11 bytes + 2 bits a session)) is refused,
  // one that holds the timeline and the diffs' cells (12 bytes each) is not.
  TourReport full;
  tourData(map, "four.cmap", TourSettings{}, &full);
  TourSettings tight;
  tight.max_bytes = full.cells * (11 + 1) - 1;
  EXPECT_THROW(tourData(map, "four.cmap", tight), UsageError);
  tight.max_bytes = full.cells * (11 + 1) + 12 * full.diff_cells;
  EXPECT_NO_THROW(tourData(map, "four.cmap", tight));
  tight.max_bytes -= 1;
  EXPECT_THROW(tourData(map, "four.cmap", tight), UsageError);

  test::TempDir dir;
  const auto r = writeTour(dir / "tour.html", map, "four.cmap");
  const auto bytes = test::bytesOf(dir / "tour.html");
  const std::string html(bytes.begin(), bytes.end());
  EXPECT_EQ(r.bytes, html.size());
  EXPECT_NE(html.find(R"(<script type="application/octet-stream" id="chronomap-data">)"), std::string::npos);
  EXPECT_NE(html.find(viewer_assets::base64(tourData(map, "four.cmap", TourSettings{}))), std::string::npos);
  EXPECT_NE(html.find(viewer_assets::inlineScript(viewerScript())), std::string::npos);
  EXPECT_EQ(html.find("<!--CHRONOMAP_"), std::string::npos);
  EXPECT_EQ(html.find("viewer.js\""), std::string::npos);  // nothing loaded from beside it
}

TEST(ViewAssets, Base64AndScriptEscaping) {
  EXPECT_EQ(viewer_assets::base64(""), "");
  EXPECT_EQ(viewer_assets::base64("f"), "Zg==");
  EXPECT_EQ(viewer_assets::base64("fo"), "Zm8=");
  EXPECT_EQ(viewer_assets::base64("foo"), "Zm9v");
  EXPECT_EQ(viewer_assets::base64(std::string("\xff\x00\x80", 3)), "/wCA");
  EXPECT_EQ(viewer_assets::inlineScript("a='</script><!--'"), "<script>a='<\\/script><\\!--'</script>");
  // The committed bundle is the one built in.
  const auto committed = test::bytesOf(std::filesystem::path(CHRONOMAP_SOURCE_DIR) / "viewer/dist/viewer.js");
  EXPECT_EQ(std::string(committed.begin(), committed.end()), std::string(viewer_assets::viewerScript()));
}

}  // namespace
}  // namespace chronomap
