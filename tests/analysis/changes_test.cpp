// What changed, and which objects (analysis/changes.h): the analytic scene of builders.h with its
// known answer, the recommended settings against the raw diff, moves shared with alerts.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "builders.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/moves.h"
#include "chronomap/core/error.h"

namespace chronomap {
namespace {

using test::at;

/// The centre of the voxels (x0..x1, y0..y1, z0..z1) of the scene's grid.
Eigen::Vector3d centreOf(const SessionMap& map, int x0, int x1, int y0, int y1, int z0, int z1) {
  return (map.grid().centerOf(at(x0, y0, z0)) + map.grid().centerOf(at(x1, y1, z1))) / 2.0;
}

TEST(Changes, TheAnalyticSceneGivesItsKnownObjects) {
  const SessionMap before = test::changesScene(false), after = test::changesScene(true);
  const Changes c = findChanges(before, after);  // the recommended settings
  ASSERT_EQ(c.objects.size(), 3u);
  const ChangedObject& b = c.objects[0];
  const ChangedObject& a = c.objects[1];
  const ChangedObject& moved = c.objects[2];
  EXPECT_EQ(b.id, 1u);
  EXPECT_EQ(b.kind, ObjectChange::Appeared);
  EXPECT_EQ(b.voxels, 72u);
  EXPECT_TRUE(b.centroid_m.isApprox(centreOf(after, 12, 14, 2, 4, 1, 8), 1e-9));
  EXPECT_TRUE(b.size_m().isApprox(Eigen::Vector3d(0.15, 0.15, 0.4), 1e-9));
  EXPECT_EQ(b.mean_colour, (Rgb{40, 40, 200}));
  EXPECT_EQ(a.id, 2u);
  EXPECT_EQ(a.kind, ObjectChange::Vanished);
  EXPECT_EQ(a.voxels, 64u);
  EXPECT_TRUE(a.centroid_m.isApprox(centreOf(before, 2, 5, 2, 5, 1, 4), 1e-9));
  EXPECT_TRUE(a.size_m().isApprox(Eigen::Vector3d(0.2, 0.2, 0.2), 1e-9));
  EXPECT_EQ(a.mean_colour, (Rgb{200, 40, 40}));
  // The green box moved by 18 voxels in x: one object, from its old place to its new.
  EXPECT_EQ(moved.id, 3u);
  EXPECT_EQ(moved.kind, ObjectChange::Moved);
  EXPECT_EQ(moved.voxels, 54u);
  EXPECT_EQ(moved.from.voxels, 27u);
  EXPECT_EQ(moved.to.voxels, 27u);
  EXPECT_TRUE(moved.from.centroid_m.isApprox(centreOf(before, 2, 4, 10, 12, 1, 3), 1e-9));
  EXPECT_TRUE(moved.to.centroid_m.isApprox(centreOf(after, 20, 22, 10, 12, 1, 3), 1e-9));
  EXPECT_TRUE(moved.centroid_m.isApprox(moved.to.centroid_m, 1e-12));
  EXPECT_NEAR(moved.distance_m, 0.9, 1e-9);
  EXPECT_EQ(moved.mean_colour, (Rgb{40, 200, 40}));
  ASSERT_EQ(moved.components.size(), 2u);
  // The patch P before the wall is no change (the weak-change rule); the small box D (8 voxels)
  // is one, but no object (fewer than 20 voxels).
  EXPECT_EQ(c.appeared_voxels, 72u + 27u + 8u);
  EXPECT_EQ(c.segmentation.dropped, 1u);
  EXPECT_EQ(c.vanished_voxels, 64u + 27u);
}

TEST(Changes, TheRawSettingsGiveThePlainDiffsComponents) {
  const SessionMap before = test::changesScene(false), after = test::changesScene(true);
  const Changes raw = findChanges(before, after, rawChangeSettings());
  EXPECT_EQ(raw.diff, diff(before, after));
  ASSERT_EQ(raw.objects.size(), 6u);  // B, A, C's two halves, the patch, D
  const std::vector<uint64_t> voxels{72, 64, 27, 27, 25, 8};
  for (size_t i = 0; i < voxels.size(); ++i) {
    EXPECT_EQ(raw.objects[i].voxels, voxels[i]) << i;
    EXPECT_NE(raw.objects[i].kind, ObjectChange::Moved) << i;
    EXPECT_EQ(raw.objects[i].id, i + 1);
  }
  EXPECT_EQ(raw.appeared_voxels, 72u + 27u + 25u + 8u);
}

TEST(Changes, AFourDMapGivesWhatItsSnapshotsGive) {
  TemporalMap map(0.05);
  map.add(100.0, test::changesScene(false));
  map.add(200.0, test::changesScene(true));
  const Changes four_d = findChanges(map, 100.0, 200.0);
  const Changes sessions = findChanges(test::changesScene(false), test::changesScene(true));
  EXPECT_EQ(four_d.diff, sessions.diff);
  EXPECT_EQ(changedObjectsJson(four_d.objects), changedObjectsJson(sessions.objects));
  ASSERT_EQ(four_d.objects.size(), 3u);
}

TEST(Changes, TheJsonFormNamesEveryField) {
  const Changes c = findChanges(test::changesScene(false), test::changesScene(true));
  const nlohmann::json j = changedObjectsJson(c.objects);
  ASSERT_EQ(j.size(), 3u);
  EXPECT_EQ(j[0]["kind"], "appeared");
  EXPECT_EQ(j[0]["voxels"], 72);
  EXPECT_EQ(j[0]["colour"], nlohmann::json::array({40, 40, 200}));
  EXPECT_FALSE(j[0].contains("from"));
  EXPECT_EQ(j[1]["kind"], "vanished");
  EXPECT_EQ(j[2]["kind"], "moved");
  EXPECT_EQ(j[2]["from"]["voxels"], 27);
  EXPECT_NEAR(j[2]["distance_m"].get<double>(), 0.9, 1e-9);
  EXPECT_NEAR(j[2]["size"][2].get<double>(), 0.15, 1e-9);
  for (const char* key : {"id", "kind", "voxels", "centroid", "size", "bbox_min", "bbox_max", "colour", "components"}) {
    EXPECT_TRUE(j[1].contains(key)) << key;
  }
  const nlohmann::json s = changeSettingsJson(recommendedChangeSettings());
  EXPECT_EQ(s["diff"]["mode"], "band");
  EXPECT_EQ(s["segment"]["min_voxels"], 20);
  EXPECT_EQ(s["moves"]["pair"], true);
}

TEST(Changes, BadSettingsAreRefused) {
  ChangeSettings s = recommendedChangeSettings();
  s.moves.max_size_ratio = 0.5;
  EXPECT_THROW(findChanges(test::changesScene(false), test::changesScene(true), s), UsageError);
  s = recommendedChangeSettings();
  s.diff.neighbourhood_voxels = 9;
  EXPECT_THROW(findChanges(test::changesScene(false), test::changesScene(true), s), UsageError);
}

/// A component with the given kind, voxels and bounding box (metres), grey.
Component part(ChangeKind kind, uint64_t voxels, Eigen::Vector3d lo, Eigen::Vector3d hi) {
  Component c;
  c.kind = kind;
  c.voxels = voxels;
  c.bbox_min_m = lo;
  c.bbox_max_m = hi;
  c.centroid_m = (lo + hi) / 2.0;
  c.mean_colour = Rgb{120, 120, 120};
  return c;
}

// The demo's sessions 1 -> 2 pair a closed door leaf that vanished with a robot that appeared
// 3.5 m away: alike in voxels, height and colour, not in footprint. With alike_footprints they are
// not a move, while a box moved whole, seen from another side (a thinner slice, fewer voxels),
// still is. (Off by default: on the office's seed 2 it lost true moves, docs/changes.md.)
TEST(Moves, WithAlikeFootprintsAThinLeafIsNotASquareObjectMoved) {
  MoveSettings footprints;
  footprints.alike_footprints = true;
  const Component door = part(ChangeKind::Vanished, 700, {6.0, 1.6, 0.0}, {6.05, 2.5, 1.0});
  const Component robot = part(ChangeKind::Appeared, 800, {2.5, 0.2, 0.0}, {3.0, 0.7, 1.0});
  EXPECT_EQ(pairMoves({door, robot}, MoveSettings{}).size(), 1u) << "the default pairs them";
  EXPECT_TRUE(pairMoves({door, robot}, footprints).empty());
  const Component box_then = part(ChangeKind::Vanished, 400, {1.0, 1.0, 0.0}, {1.5, 1.4, 0.5});
  const Component box_now = part(ChangeKind::Appeared, 250, {3.0, 1.0, 0.0}, {3.4, 1.3, 0.5});
  const std::vector<MovePair> moves = pairMoves({door, box_then, robot, box_now}, footprints);
  ASSERT_EQ(moves.size(), 1u);
  EXPECT_EQ(moves[0].vanished, 1u);
  EXPECT_EQ(moves[0].appeared, 3u);
}

}  // namespace
}  // namespace chronomap
