#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "chronomap/analysis/diff.h"
#include "chronomap/temporal/temporal_map.h"
#include "builders.h"
#include "chronomap/core/error.h"

namespace chronomap {
namespace {

constexpr int kBase = kKeyOrigin - 8;  // the test region straddles the root's centre
constexpr int kSide = 16;


// Counters with a chosen probability: hits / length = -ln(1 - p).
VoxelCounters withProbability(double p, uint32_t hits = 4, uint8_t red = 100) {
  VoxelCounters c;
  c.hits = hits;
  c.length_m = static_cast<float>(hits / -std::log(1.0 - p));
  c.red = uint32_t{red} * hits;
  c.green = 7 * hits;
  c.blue = 9 * hits;
  return c;
}


DiffSettings mode(DiffMode m, double alpha = -1.0) {
  DiffSettings s;
  s.mode = m;
  s.alpha = alpha;
  return s;
}

std::map<VoxelKey, ChangeCell> byKey(const DiffMap& d) {
  std::map<VoxelKey, ChangeCell> out;
  for (const ChangeCell& c : d.cells()) out[c.key] = c;
  return out;
}

// ---------------------------------------------------------------------------------------------
// Analytic cases.

TEST(Diff, HardModeSeesOnlyOccupiedFreeChanges) {
  SessionMap a(0.05), b(0.05);
  a.add(test::at(0, 0, 0, kBase), withProbability(0.9));  // occupied -> free: vanished
  b.add(test::at(0, 0, 0, kBase), test::freeVoxel(0.25f));
  a.add(test::at(1, 0, 0, kBase), test::freeVoxel(0.25f));  // free -> occupied: appeared
  b.add(test::at(1, 0, 0, kBase), withProbability(0.8, 4, 210));
  a.add(test::at(2, 0, 0, kBase), withProbability(0.9));  // occupied -> unknown: no change
  b.add(test::at(3, 0, 0, kBase), test::freeVoxel(0.25f));           // unknown -> free: no change
  a.add(test::at(4, 0, 0, kBase), test::freeVoxel(0.5f));       // free -> free
  b.add(test::at(4, 0, 0, kBase), test::freeVoxel(0.125f));
  a.add(test::at(5, 0, 0, kBase), withProbability(0.6));  // occupied -> occupied
  b.add(test::at(5, 0, 0, kBase), withProbability(0.99));

  const DiffMap d = diff(a, b, mode(DiffMode::Hard));
  ASSERT_EQ(d.cells().size(), 2u);
  const auto cells = byKey(d);
  EXPECT_EQ(cells.at(test::at(0, 0, 0, kBase)).kind, ChangeKind::Vanished);
  EXPECT_EQ(cells.at(test::at(0, 0, 0, kBase)).colour.r, 100) << "a vanished voxel keeps the colour of what vanished";
  EXPECT_EQ(cells.at(test::at(1, 0, 0, kBase)).kind, ChangeKind::Appeared);
  EXPECT_EQ(cells.at(test::at(1, 0, 0, kBase)).colour.r, 210) << "an appeared voxel has the colour of the new surface";
  EXPECT_NEAR(cells.at(test::at(1, 0, 0, kBase)).value, 0.8, 1e-5);
  EXPECT_EQ(d.voxelCount(ChangeKind::Appeared), 1u);
  EXPECT_EQ(d.voxelCount(ChangeKind::Vanished), 1u);
}

TEST(Diff, ThresholdBandAndContinuousFollowTheirDefinitions) {
  SessionMap a(0.05), b(0.05);
  a.add(test::at(0, 0, 0, kBase), withProbability(0.45));  // crosses 0.5 by 0.1
  b.add(test::at(0, 0, 0, kBase), withProbability(0.55));
  a.add(test::at(1, 0, 0, kBase), withProbability(0.05));  // 0.05 -> 0.7: a jump of 0.65
  b.add(test::at(1, 0, 0, kBase), withProbability(0.7));
  a.add(test::at(2, 0, 0, kBase), withProbability(0.3));  // 0.3 -> 0.35: no bin changes, small jump
  b.add(test::at(2, 0, 0, kBase), withProbability(0.35));
  a.add(test::at(3, 0, 0, kBase), test::freeVoxel(0.25f));  // free in a, unknown in b
  a.add(test::at(4, 0, 0, kBase), test::freeVoxel(0.25f));  // identical
  b.add(test::at(4, 0, 0, kBase), test::freeVoxel(0.25f));

  const auto hard = byKey(diff(a, b, mode(DiffMode::Hard)));
  EXPECT_EQ(hard.size(), 2u);
  EXPECT_TRUE(hard.count(test::at(0, 0, 0, kBase)) && hard.count(test::at(1, 0, 0, kBase)));

  const auto threshold = byKey(diff(a, b, mode(DiffMode::Threshold, 0.4)));
  ASSERT_EQ(threshold.size(), 1u) << "only the 0.65 jump exceeds alpha = 0.4";
  EXPECT_EQ(threshold.at(test::at(1, 0, 0, kBase)).kind, ChangeKind::Appeared);
  const auto threshold_low = byKey(diff(a, b, mode(DiffMode::Threshold, 0.04)));
  EXPECT_EQ(threshold_low.size(), 3u) << "0.1, 0.65 and 0.05 exceed 0.04";

  const auto band = byKey(diff(a, b, mode(DiffMode::Band, 0.1)));
  ASSERT_EQ(band.size(), 1u) << "0.45 and 0.55 lie in the grey band (0.4, 0.6)";
  EXPECT_TRUE(band.count(test::at(1, 0, 0, kBase)));

  const auto cont = byKey(diff(a, b, mode(DiffMode::Continuous)));
  ASSERT_EQ(cont.size(), 4u) << "every voxel known in both, the unknown one excluded";
  EXPECT_NEAR(cont.at(test::at(0, 0, 0, kBase)).value, 0.1, 1e-5);
  EXPECT_NEAR(cont.at(test::at(1, 0, 0, kBase)).value, 0.65, 1e-5);
  EXPECT_NEAR(cont.at(test::at(2, 0, 0, kBase)).value, 0.05, 1e-5);
  EXPECT_EQ(cont.at(test::at(4, 0, 0, kBase)).value, 0.0f);
  EXPECT_EQ(cont.at(test::at(4, 0, 0, kBase)).kind, ChangeKind::Unchanged);
  EXPECT_EQ(cont.at(test::at(2, 0, 0, kBase)).kind, ChangeKind::Appeared);
}

TEST(Diff, UnknownAgainstAnythingIsNeverAChange) {
  SessionMap a(0.05), b(0.05);
  for (int i = 0; i < 8; ++i) a.add(test::at(i, 0, 0, kBase), i % 2 ? test::freeVoxel(0.25f) : withProbability(0.9));
  for (int i = 0; i < 8; ++i) b.add(test::at(i, 5, 0, kBase), i % 2 ? withProbability(0.9) : test::freeVoxel(0.25f));
  for (DiffMode m : {DiffMode::Hard, DiffMode::Threshold, DiffMode::Band, DiffMode::Continuous}) {
    EXPECT_TRUE(diff(a, b, mode(m)).empty()) << toString(m);
    EXPECT_TRUE(diff(a, SessionMap(0.05), mode(m)).empty()) << toString(m);
  }
}

TEST(Diff, CompressedFreeCubesCompareAtTheFinerSide) {
  SessionMap a(0.05), b(0.05);
  for (int z = 0; z < 8; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 8; ++x) {
        a.add(test::at(x, y, z, kBase), test::freeVoxel(0.25f));
        b.add(test::at(x, y, z, kBase), (x == 3 && y == 4 && z == 5) ? withProbability(0.9) : test::freeVoxel(0.5f));
      }
    }
  }
  a.compressFree();
  b.compressFree();
  ASSERT_LT(a.leafCount(), 64u) << "a compressed";
  const DiffMap hard = diff(a, b, mode(DiffMode::Hard));
  ASSERT_EQ(hard.cells().size(), 1u);
  EXPECT_EQ(hard.cells()[0].key, test::at(3, 4, 5, kBase));
  EXPECT_EQ(hard.cells()[0].level, 0);
  EXPECT_EQ(hard.cells()[0].kind, ChangeKind::Appeared);
  // Continuous: uniform cubes known in both come out as one cell each, with value 0.
  const DiffMap cont = diff(a, b, mode(DiffMode::Continuous));
  EXPECT_EQ(cont.voxelCount(), 512u);
  EXPECT_LT(cont.cells().size(), 512u);
  EXPECT_EQ(cont.voxelCount(ChangeKind::Unchanged), 511u);
}

TEST(Diff, NeighbourhoodIgnoresShiftedSurfacesButNotObjects) {
  // A wall at x = 4 in a, at x = 5 in b (a localisation shift of one voxel); a box appears in b
  // three voxels away from anything a saw occupied.
  SessionMap a(0.05), b(0.05);
  for (int z = 0; z < 6; ++z) {
    for (int y = 0; y < 6; ++y) {
      for (int x = 0; x < 12; ++x) {
        a.add(test::at(x, y, z, kBase), x == 4 ? withProbability(0.9) : test::freeVoxel(0.25f));
        const bool box = x == 9 && y < 2 && z < 2;
        b.add(test::at(x, y, z, kBase), x == 5 || box ? withProbability(0.9) : test::freeVoxel(0.25f));
      }
    }
  }
  DiffSettings s;
  EXPECT_EQ(diff(a, b, s).voxelCount(), 36u + 36u + 4u) << "the shifted wall: 36 vanished, 36 appeared";
  s.neighbourhood_voxels = 1;
  const DiffMap near = diff(a, b, s);
  EXPECT_EQ(near.voxelCount(ChangeKind::Vanished), 0u);
  EXPECT_EQ(near.voxelCount(ChangeKind::Appeared), 4u) << "only the box";
  s.neighbourhood_voxels = 5;
  EXPECT_THROW(s.validate(), UsageError);
}

// A wall across the yz plane whose hits split between x = 4 and x = 5: `hits4` of every 10
// rays end at x = 4, the others at x = 5; the voxel with more hits is occupied, the other free.
void addSplitWall(SessionMap& m, uint32_t hits4) {
  for (int z = 0; z < 6; ++z) {
    for (int y = 0; y < 6; ++y) {
      for (int x = 0; x < 10; ++x) {
        if (x == 4 || x == 5) {
          const uint32_t hits = x == 4 ? hits4 : 10 - hits4;
          VoxelCounters c = withProbability(0.9, hits);
          if (hits < 5) {  // free: a few hits over a long path, P = 1 - exp(-1/4) = 0.22
            c = test::freeVoxel(hits == 0 ? 0.25f : 4.0f * static_cast<float>(hits));
            c.hits = hits;
          }
          m.add(test::at(x, y, z, kBase), c);
        } else {
          m.add(test::at(x, y, z, kBase), test::freeVoxel(0.25f));
        }
      }
    }
  }
}

TEST(Diff, MinShiftTellsAMovedSurfaceFromAShiftedOne) {
  // Pose error: 9 of 10 hits at x = 4 before, 6 of 10 at x = 5 after -- the wall moved by
  // half a voxel (2.5 cm), enough to flip both voxels.
  SessionMap wall_a(0.05), wall_b(0.05);
  addSplitWall(wall_a, 9);
  addSplitWall(wall_b, 4);
  // An object moved by one voxel: every hit at x = 4 before, every hit at x = 5 after.
  SessionMap obj_a(0.05), obj_b(0.05);
  addSplitWall(obj_a, 10);
  addSplitWall(obj_b, 0);
  ASSERT_EQ(wall_a.stateOf(test::at(5, 2, 2, kBase)), VoxelState::Free);
  ASSERT_EQ(wall_b.stateOf(test::at(5, 2, 2, kBase)), VoxelState::Occupied);
  ASSERT_EQ(wall_b.stateOf(test::at(4, 2, 2, kBase)), VoxelState::Free);

  // The hit-weighted centres: 4.1 -> 4.6 (wall), 4.0 -> 5.0 (object); lateral terms cancel.
  EXPECT_NEAR(surfaceShift(wall_a, wall_b, test::at(4, 2, 2, kBase), 1).value(), 0.5, 1e-9);
  EXPECT_NEAR(surfaceShift(wall_a, wall_b, test::at(4, 0, 0, kBase), 1).value(), 0.5, 1e-9) << "at the wall's corner";
  EXPECT_NEAR(surfaceShift(obj_a, obj_b, test::at(5, 3, 1, kBase), 1).value(), 1.0, 1e-9);
  EXPECT_FALSE(surfaceShift(wall_a, wall_b, test::at(8, 2, 2, kBase), 1)) << "no hits within one voxel";
  EXPECT_THROW(surfaceShift(wall_a, SessionMap(0.1), test::at(4, 2, 2, kBase), 1), UsageError);

  DiffSettings s;
  EXPECT_EQ(diff(wall_a, wall_b, s).voxelCount(), 72u) << "36 vanished at x = 4, 36 appeared at x = 5";
  EXPECT_EQ(diff(obj_a, obj_b, s).voxelCount(), 72u);
  s.neighbourhood_voxels = 1;
  EXPECT_TRUE(diff(wall_a, wall_b, s).empty()) << "min_shift 0: the neighbourhood rule drops both";
  EXPECT_TRUE(diff(obj_a, obj_b, s).empty());
  s.min_shift_voxels = 0.6;  // between the two shifts
  EXPECT_TRUE(diff(wall_a, wall_b, s).empty());
  EXPECT_EQ(diff(obj_a, obj_b, s).voxelCount(), 72u) << "the moved object is kept whole";
  s.min_shift_voxels = 0.4;
  EXPECT_EQ(diff(wall_a, wall_b, s).voxelCount(), 72u);
  s.min_shift_voxels = -0.1;
  EXPECT_THROW(s.validate(), UsageError);
  s.min_shift_voxels = std::nan("");
  EXPECT_THROW(s.validate(), UsageError);
}

// A surface that moves within its voxel: the hits stay in the same voxels, only where in them
// they ended changes. Only the recorded hit positions can see it.
/// A wall of 6 x 6 voxels at x = 4 whose hits end `offset` voxels from the centre, free space
/// around it, and with `sheet` a thin sheet behind it (x = 5).
SessionMap subVoxelWall(float offset, bool sheet) {
  SessionMap m(0.05);
  for (int z = 0; z < 6; ++z) {
    for (int y = 0; y < 6; ++y) {
      for (int x = 0; x < 10; ++x) {
        VoxelCounters c = test::freeVoxel(0.25f);
        if (x == 4) {
          c = withProbability(0.9, 10);
          c.offset[0] = 10.0f * offset;
        } else if (x == 5 && sheet) {
          c = withProbability(0.9, 2);
          c.offset[0] = 2.0f * -0.45f;
        }
        m.add(test::at(x, y, z, kBase), c);
      }
    }
  }
  return m;
}

TEST(Diff, MinShiftSeesAMoveWithinOneVoxel) {
  // The wall's hits end 0.4 voxels below the centre (x = 4.1 in voxel units from the voxel's
  // lower corner), then 0.35 above it (4.85): moved 0.75 voxels. The thin sheet behind it is
  // occupied only afterwards, so the diff has cells to test.
  const SessionMap before = subVoxelWall(-0.4f, false), after = subVoxelWall(0.35f, true);
  // Before: 360 hits at 4 - 0.4; after: 360 at 4 + 0.35 and 72 at 5 - 0.45. Mean x, per row of
  // the 3 x 3 window (10 and 2 hits a voxel): 3.6 before, (10 * 4.35 + 2 * 4.55) / 12 after.
  const double after_x = (10.0 * 4.35 + 2.0 * 4.55) / 12.0;
  EXPECT_NEAR(surfaceShift(before, after, test::at(5, 2, 2, kBase), 1).value(), after_x - 3.6, 1e-5);
  // Without positions (a map written before they were kept) the same hits sit at the centres.
  SessionMap before_c(0.05), after_c(0.05);
  for (const auto& [src, dst] : {std::pair{&before, &before_c}, std::pair{&after, &after_c}}) {
    src->forEachLeaf([&](const LeafView& leaf) {
      VoxelCounters c = leaf.counters;
      for (float& o : c.offset) o = 0.0f;
      if (leaf.level == 0) dst->add(leaf.key, c);
    });
  }
  EXPECT_NEAR(surfaceShift(before_c, after_c, test::at(5, 2, 2, kBase), 1).value(), 2.0 / 12.0, 1e-9);

  DiffSettings s;
  s.neighbourhood_voxels = 1;
  s.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  EXPECT_EQ(diff(before, after, s).voxelCount(), 36u) << "the sheet appeared where the wall moved";
  EXPECT_TRUE(diff(before_c, after_c, s).empty()) << "at the centres the move is a sixth of a voxel";
}

// A flat surface sampled on different parts by the two maps: a table top at z = 4 whose hits
// end 0.2 voxels above the voxels' centres in both maps, seen at x = 0..4 before and x = 4..9 after
// (a grazing view from the other side). Every voxel around it is known in both.
SessionMap tableTop(int x_from, int x_to, float z_offset, int y_from = 0, int y_to = 7) {
  SessionMap m(0.05);
  for (int z = 2; z < 7; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 10; ++x) {
        VoxelCounters c = test::freeVoxel(0.25f);
        if (z == 4 && x >= x_from && x <= x_to && y >= y_from && y <= y_to) {
          c = withProbability(0.9, 5);
          c.offset[2] = 5.0f * z_offset;
        }
        m.add(test::at(x, y, z, kBase), c);
      }
    }
  }
  return m;
}

// A pole along y at x = 4, z = 4 whose hits end `x_offset` voxels from the centres in x, give or
// take 0.02 (alternately), in the same free space.
SessionMap pole(float x_offset) {
  SessionMap m(0.05);
  for (int z = 2; z < 7; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 10; ++x) {
        VoxelCounters c = test::freeVoxel(0.25f);
        if (z == 4 && x == 4) {
          c = withProbability(0.9, 5);
          c.offset[0] = 5.0f * (x_offset + (y % 2 ? -0.02f : 0.02f));
        }
        m.add(test::at(x, y, z, kBase), c);
      }
    }
  }
  return m;
}

// A wall across x = 4 (z = 2..6, every y), hits at the voxels' centres, in the same free space.
SessionMap wallAtX4() {
  SessionMap m(0.05);
  for (int z = 2; z < 7; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 10; ++x) m.add(test::at(x, y, z, kBase), x == 4 ? withProbability(0.9, 5) : test::freeVoxel(0.25f));
    }
  }
  return m;
}

TEST(Diff, ShiftPlaneCountsOnlyAMoveAcrossAFlatSurface) {
  const SessionMap before = tableTop(0, 4, 0.2f), after = tableTop(4, 9, 0.2f), lower = tableTop(4, 9, -0.4f);
  const VoxelKey k = test::at(4, 4, 4, kBase);
  // The hits' means, over the 3 x 3 x 3 window: x = 3.5 before, 4.5 after, the same height.
  EXPECT_NEAR(surfaceShift(before, after, k, 1).value(), 1.0, 1e-6) << "the whole move: it slid along itself";
  EXPECT_NEAR(surfaceShift(before, after, k, 1, 0.2).value(), 0.0, 1e-6) << "across the plane: no move";
  // The same view of a top 0.6 voxels lower: that part counts.
  EXPECT_NEAR(surfaceShift(before, lower, k, 1).value(), std::hypot(1.0, 0.6), 1e-6);
  EXPECT_NEAR(surfaceShift(before, lower, k, 1, 0.2).value(), 0.6, 1e-6);
  // Where the maps see differently shaped surfaces (here a wall at x = 4 instead of the top) there
  // is no plane at 0.2: the pooled spread, x 0.1, y 2/3, z 0.4, has its least a quarter of the
  // middle one, so the whole move counts, (0.5, 0, -0.2). At a ratio of 1 it is a plane: across
  // x, 0.5.
  const SessionMap wall = wallAtX4();
  EXPECT_NEAR(surfaceShift(before, wall, k, 1, 0.2).value(), std::hypot(0.5, 0.2), 1e-6);
  EXPECT_NEAR(surfaceShift(before, wall, k, 1, 1.0).value(), 0.5, 1e-6);
  // A map with hits in two voxels of the window gives no plane (three needed): here the top's far
  // end at x = 5, y = 4..5 only, so the whole move, 1.5 in x and 0.5 in y.
  EXPECT_NEAR(surfaceShift(before, tableTop(5, 5, 0.2f, 4, 5), k, 1, 0.2).value(), std::hypot(1.5, 0.5), 1e-6);
  // A pole moved 0.3 voxels across itself: its points spread along y (2/3) and a little in x
  // (the 0.02 jitter), not at all in z. Points along a line give no plane, so the whole move counts;
  // taken as a plane, its normal would be z and the move 0.
  EXPECT_NEAR(surfaceShift(pole(0.0f), pole(0.3f), k, 1, 0.15).value(), 0.3, 1e-5);
  EXPECT_THROW(surfaceShift(before, after, k, 1, -0.1), UsageError);
  EXPECT_THROW(surfaceShift(before, after, k, 1, 1.5), UsageError);
  EXPECT_THROW(surfaceShift(before, after, k, 1, std::nan("")), UsageError);

  DiffSettings s;
  s.shift_plane_ratio = 1.1;
  EXPECT_THROW(s.validate(), UsageError);
  s.shift_plane_ratio = std::nan("");
  EXPECT_THROW(s.validate(), UsageError);
  s.shift_plane_ratio = DiffSettings::kRecommendedShiftPlaneRatio;
  EXPECT_NO_THROW(s.validate());
}

// The 4D map keeps a surface's new position when it moved by half a voxel or more within its
// voxels (ChangeCriterion::surface_shift_voxels): its diff then finds the sub-voxel move the two
// session maps show. Without (the map kept the first position while the state stayed) it did not.
TEST(Diff, AFourDMapKeepsWhatTheShiftTestReads) {
  const SessionMap before = subVoxelWall(-0.4f, false), after = subVoxelWall(0.35f, true);
  DiffSettings s;
  s.neighbourhood_voxels = 1;
  s.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  TemporalMap map(0.05);  // the default criterion
  map.add(1000, before);
  map.add(2000, after);
  EXPECT_EQ(diff(map, 1000, 2000, s), diff(before, after, s));
  EXPECT_EQ(diff(map, 1000, 2000, s).voxelCount(), 36u);
  TemporalMap first_positions(0.05, ChangeCriterion{0.0, 0.0, 0.0});
  first_positions.add(1000, before);
  first_positions.add(2000, after);
  EXPECT_TRUE(diff(first_positions, 1000, 2000, s).empty());
  EXPECT_GT(map.counts().entries, first_positions.counts().entries);
}

// seen_at_both: a box seen in session 1, out of session 2's view, gone in session 3. As last
// observed, session 2's time still holds the box, so 2 -> 3 shows it vanish; compared as the two
// sessions saw it, 2 -> 3 has nothing (session 2 saw none of it) and 1 -> 3 has the box, as the
// session maps' diffs do.
TEST(Diff, SeenAtBothComparesWhatTheTwoSessionsObserved) {
  auto room = [](bool box, bool box_seen) {
    SessionMap m(0.05);
    for (int z = 0; z < 4; ++z) {
      for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
          const bool in_box = x >= 4 && y >= 4 && z < 2;
          if (in_box && !box_seen) continue;
          m.add(test::at(x, y, z, kBase), in_box && box ? withProbability(0.9) : test::freeVoxel(0.25f));
        }
      }
    }
    return m;
  };
  const SessionMap s1 = room(true, true), s2 = room(true, false), s3 = room(false, true);
  TemporalMap map(0.05);
  map.add(1000, s1);
  map.add(2000, s2);
  map.add(3000, s3);
  DiffSettings last;
  EXPECT_EQ(diff(map, 2000, 3000, last).voxelCount(), 32u);
  DiffSettings seen;
  seen.seen_at_both = true;
  EXPECT_TRUE(diff(map, 2000, 3000, seen).empty());
  EXPECT_EQ(diff(map, 2000, 3000, seen), diff(s2, s3, seen));
  EXPECT_EQ(diff(map, 1000, 3000, seen).voxelCount(), 32u);
  EXPECT_EQ(diff(map, 1000, 3000, seen), diff(s1, s3, seen));
  // The rules read only what was seen: a vanished voxel beside the box's unseen part is one.
  seen.neighbourhood_voxels = 1;
  last.neighbourhood_voxels = 1;
  EXPECT_EQ(diff(map, 1000, 3000, seen), diff(s1, s3, seen));
}

// The weak-change rule. A wall at x = 6, free space in front of it. In b, part of a session's
// frames measure a 2 x 2 patch of the wall two voxels nearer (x = 4) while the others still see
// the whole wall where a saw it: the patch "appeared" in front of a surface that is still there.
// A box put at the same place instead hides the wall's 2 x 2 voxels behind it (unknown in b), and
// a wall that moved leaves free space where it stood: both stay changes.
SessionMap wallScene(int patch_x, bool wall_behind_patch, bool wall_at_6) {
  SessionMap m(0.05);
  for (int z = 0; z < 6; ++z) {
    for (int y = 0; y < 6; ++y) {
      const bool in_patch = y >= 2 && y < 4 && z >= 2 && z < 4;
      for (int x = 0; x < 7; ++x) {
        if (in_patch && x == patch_x) {
          m.add(test::at(x, y, z, kBase), withProbability(0.9));
        } else if (x == 6) {
          if (!wall_at_6) m.add(test::at(x, y, z, kBase), test::freeVoxel(0.25f));
          else if (!in_patch || wall_behind_patch) m.add(test::at(x, y, z, kBase), withProbability(0.9));
        } else if (!(in_patch && x > patch_x && patch_x >= 0)) {
          m.add(test::at(x, y, z, kBase), test::freeVoxel(0.25f));
        }
      }
    }
  }
  return m;
}

TEST(Diff, KeptSurfaceDropsADepthErrorInFrontOfASurfaceStillSeen) {
  const SessionMap a = wallScene(-1, true, true);
  DiffSettings s = mode(DiffMode::Band);
  s.neighbourhood_voxels = 1;
  s.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  // The patch two voxels before the wall is beyond the neighbourhood rule's reach.
  const SessionMap error = wallScene(4, true, true);
  EXPECT_EQ(diff(a, error, s).voxelCount(ChangeKind::Appeared), 4u);
  s.kept_surface_radius_voxels = 1;
  EXPECT_EQ(diff(a, error, s).voxelCount(), 4u) << "the wall lies two voxels away: radius 1 does not see it";
  s.kept_surface_radius_voxels = DiffSettings::kRecommendedKeptSurfaceRadius;
  EXPECT_EQ(diff(a, error, s).voxelCount(), 0u) << "all 36 wall voxels within 3 are still occupied";
  // The same from b to a: the patch vanished in front of a wall both saw.
  EXPECT_EQ(diff(error, a, s).voxelCount(), 0u);

  // A box in front of the wall: a's 36 wall voxels within 3 of each box voxel, 4 of them hidden
  // behind the box in b (unknown): 32 / 36 = 0.89 still seen, under the default share of 0.9.
  const SessionMap box = wallScene(4, false, true);
  EXPECT_EQ(diff(a, box, s).voxelCount(ChangeKind::Appeared), 4u);
  s.kept_surface_share = 0.85;
  EXPECT_EQ(diff(a, box, s).voxelCount(), 0u) << "32 / 36 >= 0.85";
  s.kept_surface_share = DiffSettings::kDefaultKeptSurfaceShare;

  // The wall still occupied in b but its hits 0.6 voxel farther back in every voxel (a surface
  // pushed by less than a voxel): not the same surface, the patch stays.
  auto moveWallHits = [](SessionMap& m, float offset) {
    std::vector<std::pair<VoxelKey, VoxelCounters>> deltas;
    m.forEachLeaf([&](const LeafView& l) {
      if (l.key.x != test::at(6, 0, 0, kBase).x || l.counters.hits == 0) return;
      VoxelCounters d;
      d.offset[0] = offset * static_cast<float>(l.counters.hits);
      deltas.emplace_back(l.key, d);
    });
    for (const auto& [k, d] : deltas) m.add(k, d);
  };
  SessionMap pushed = error, was = a;
  moveWallHits(pushed, 0.3f);
  EXPECT_EQ(diff(a, pushed, s).voxelCount(ChangeKind::Appeared), 0u) << "0.3 voxel: the same surface";
  moveWallHits(was, -0.3f);
  EXPECT_EQ(diff(was, pushed, s).voxelCount(ChangeKind::Appeared), 4u);

  // The wall moved from x = 6 to x = 4 over the patch... and everywhere: free where it stood.
  const SessionMap moved = wallScene(4, true, false);
  EXPECT_EQ(diff(a, moved, s).voxelCount(ChangeKind::Appeared), 4u);
  EXPECT_EQ(diff(a, moved, s).voxelCount(ChangeKind::Vanished), 36u);

  // Off by default; checked.
  EXPECT_EQ(DiffSettings{}.kept_surface_radius_voxels, 0);
  s.kept_surface_radius_voxels = 5;
  EXPECT_THROW(s.validate(), UsageError);
  s.kept_surface_radius_voxels = 3;
  s.kept_surface_share = 0.0;
  EXPECT_THROW(s.validate(), UsageError);
  s.kept_surface_share = 1.5;
  EXPECT_THROW(s.validate(), UsageError);
}

// The dark-surface rule, on the wall scene: a 2 x 2 patch appears two voxels before a wall (x = 6)
// and hides the wall's voxels behind it, as a box would; the weak-change rule keeps it (32 of 36
// wall voxels still seen, under 0.9). The 3DMatch sofa (docs/changes.md) measured 8 to 12 cm apart
// by two sessions looks like this. The patch's colour decides: dark (mean of red, green and blue
// under 40) and darker than the wall the other map sees around it (under 0.6 of its brightness), it
// is the wall measured at another depth; bright, or as dark as that wall, it is an object.
SessionMap recoloured(const SessionMap& m, Rgb wall, Rgb patch) {
  SessionMap out(m.resolution_m());
  m.forEachLeaf([&](const LeafView& l) {
    VoxelCounters c = l.counters;
    const Rgb col = l.key.x == test::at(6, 0, 0, kBase).x ? wall : patch;
    c.red = uint32_t{col.r} * c.hits;
    c.green = uint32_t{col.g} * c.hits;
    c.blue = uint32_t{col.b} * c.hits;
    out.add(l.key, c);
  });
  return out;
}

TEST(Diff, DarkSurfaceDropsADarkSurfaceSeenNearASurfaceOfTheOtherMap) {
  const Rgb grey{150, 150, 150}, dark{30, 40, 20}, black{0, 0, 0}, bright{200, 60, 40};
  const SessionMap a = recoloured(wallScene(-1, true, true), grey, grey);
  DiffSettings s = mode(DiffMode::Band);
  s.neighbourhood_voxels = 1;
  s.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  s.kept_surface_radius_voxels = DiffSettings::kRecommendedKeptSurfaceRadius;
  const SessionMap dark_patch = recoloured(wallScene(4, false, true), grey, dark);
  EXPECT_EQ(diff(a, dark_patch, s).voxelCount(ChangeKind::Appeared), 4u) << "the weak-change rule keeps it";
  s.dark_surface_radius_voxels = 1;
  EXPECT_EQ(diff(a, dark_patch, s).voxelCount(), 4u) << "the wall lies two voxels away: radius 1 does not reach it";
  s.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  EXPECT_TRUE(diff(a, dark_patch, s).empty()) << "mean 30 < 40, the wall two voxels away";
  EXPECT_TRUE(diff(dark_patch, a, s).empty()) << "vanished: the dark patch was the first map's";
  // Brightness 40 is not under 40; a brighter threshold takes it.
  const SessionMap forty = recoloured(wallScene(4, false, true), grey, Rgb{40, 40, 40});
  EXPECT_EQ(diff(a, forty, s).voxelCount(), 4u);
  s.dark_surface_brightness = 41.0;
  EXPECT_TRUE(diff(a, forty, s).empty());
  s.dark_surface_brightness = DiffSettings::kDefaultDarkSurfaceBrightness;
  // A bright patch is an object (mean 100).
  EXPECT_EQ(diff(a, recoloured(wallScene(4, false, true), grey, bright), s).voxelCount(), 4u);
  // A dark patch before a wall as dark (a dark object both maps see alike): 30 is not under
  // 0.6 x 30, so it is an object; with the contrast condition dropped (1) it is not.
  const SessionMap a_dark = recoloured(wallScene(-1, true, true), dark, dark);
  const SessionMap dark_on_dark = recoloured(wallScene(4, false, true), dark, dark);
  EXPECT_EQ(diff(a_dark, dark_on_dark, s).voxelCount(), 4u);
  s.dark_surface_contrast = 1.0;
  EXPECT_EQ(diff(a_dark, dark_on_dark, s).voxelCount(), 4u) << "30 is not under 1 x 30 either";
  EXPECT_TRUE(diff(a_dark, recoloured(wallScene(4, false, true), dark, Rgb{20, 20, 20}), s).empty());
  s.dark_surface_contrast = DiffSettings::kDefaultDarkSurfaceContrast;
  // A dark patch farther than the radius from the wall (x = 2, four voxels before it) is kept.
  const SessionMap far_patch = recoloured(wallScene(2, false, true), grey, dark);
  EXPECT_EQ(diff(a, far_patch, s).voxelCount(ChangeKind::Appeared), 4u);
  // Pure black hits count as dark where the map holds colour around them (the wall) ...
  EXPECT_TRUE(diff(a, recoloured(wallScene(4, false, true), grey, black), s).empty());
  // ... but maps without colour (every sum zero) have no dark surface.
  const SessionMap a_plain = recoloured(wallScene(-1, true, true), black, black);
  EXPECT_EQ(diff(a_plain, recoloured(wallScene(4, false, true), black, black), s).voxelCount(), 4u);

  // Off by default; checked.
  EXPECT_EQ(DiffSettings{}.dark_surface_radius_voxels, 0);
  s.dark_surface_radius_voxels = 5;
  EXPECT_THROW(s.validate(), UsageError);
  s.dark_surface_radius_voxels = 3;
  for (double b : {-1.0, 256.0, std::nan("")}) {
    s.dark_surface_brightness = b;
    EXPECT_THROW(s.validate(), UsageError) << b;
  }
  s.dark_surface_brightness = DiffSettings::kDefaultDarkSurfaceBrightness;
  for (double c : {0.0, 1.5, std::nan("")}) {
    s.dark_surface_contrast = c;
    EXPECT_THROW(s.validate(), UsageError) << c;
  }
}

// The dark-surface rule judges objects. A light floor (z = 0, grey 150) that both sessions see,
// free space above it; in the second session a dark object (mean colour 30) stands on it, 2 x 2
// voxels wide and `height` tall, hiding the floor under it (unknown there). `bright_layers` of its
// top layers are bright (mean 100) instead.
SessionMap floorScene(int height, int bright_layers = 0) {
  auto coloured = [](uint8_t grey) {
    VoxelCounters c = withProbability(0.9);
    c.red = c.green = c.blue = uint32_t{grey} * c.hits;
    return c;
  };
  SessionMap m(0.05);
  for (int z = 0; z < 8; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 8; ++x) {
        const bool under = x >= 3 && x < 5 && y >= 3 && y < 5;
        if (z == 0) {
          if (!under || height == 0) m.add(test::at(x, y, z, kBase), coloured(150));
        } else if (under && z <= height) {
          m.add(test::at(x, y, z, kBase), coloured(z > height - bright_layers ? 100 : 30));
        } else {
          m.add(test::at(x, y, z, kBase), test::freeVoxel(0.25f));
        }
      }
    }
  }
  return m;
}

TEST(Diff, DarkSurfaceDropsThinDarkLayersAlongASurfaceButNotObjectsStandingOnIt) {
  const SessionMap empty_floor = floorScene(0);
  DiffSettings s = mode(DiffMode::Band);
  s.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  ASSERT_EQ(s.dark_surface_radius_voxels, 2);
  // A dark object 4 voxels tall: its lower two layers lie within 2 voxels of the floor, dark
  // and darker than it, as a chair's legs do; its upper two do not, so the object is kept whole
  // (voxel by voxel the rule would drop the lower 8 of its 16 voxels).
  const SessionMap tall = floorScene(4);
  EXPECT_EQ(diff(empty_floor, tall, s).voxelCount(ChangeKind::Appeared), 16u);
  EXPECT_EQ(diff(tall, empty_floor, s).voxelCount(ChangeKind::Vanished), 16u) << "taken away: kept as well";
  // A dark layer two voxels thick along the floor is the floor measured at another depth (the
  // 3DMatch sofa's patches, 8 to 12 cm in front of the surface the other session saw) ...
  const SessionMap thin = floorScene(2);
  EXPECT_TRUE(diff(empty_floor, thin, s).empty());
  EXPECT_TRUE(diff(thin, empty_floor, s).empty());
  // ... unless the radius does not reach its top (the rule's price: a dark mat on a light floor is none).
  s.dark_surface_radius_voxels = 1;
  EXPECT_EQ(diff(empty_floor, thin, s).voxelCount(), 8u);
  s.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  // The share: with its top layer bright, 4 of the layer's 8 voxels are dark.
  const SessionMap half = floorScene(2, 1);
  EXPECT_TRUE(diff(empty_floor, half, s).empty()) << "4 / 8 >= 0.5";
  s.dark_surface_share = 0.6;
  EXPECT_EQ(diff(empty_floor, half, s).voxelCount(), 8u) << "4 / 8 < 0.6: the whole object stays";
  s.dark_surface_share = DiffSettings::kDefaultDarkSurfaceShare;
  EXPECT_EQ(diff(empty_floor, floorScene(2, 2), s).voxelCount(), 8u) << "a bright layer";
  // The same in the recommended pipeline: the tall object's appeared voxels are what the rules
  // before keep, and the dark-surface rule removes none of them.
  DiffSettings rec = mode(DiffMode::Band);
  rec.neighbourhood_voxels = 1;
  rec.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  rec.kept_surface_radius_voxels = DiffSettings::kRecommendedKeptSurfaceRadius;
  const uint64_t before_rule = diff(empty_floor, tall, rec).voxelCount();
  EXPECT_GT(before_rule, 0u);
  rec.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  EXPECT_EQ(diff(empty_floor, tall, rec).voxelCount(), before_rule);
  // Checked.
  for (double share : {0.0, 1.5, std::nan("")}) {
    s.dark_surface_share = share;
    EXPECT_THROW(s.validate(), UsageError) << share;
  }
}

TEST(Diff, SettingsAreChecked) {
  EXPECT_THROW(parseDiffMode("soft"), UsageError);
  EXPECT_EQ(parseDiffMode("band"), DiffMode::Band);
  EXPECT_THROW(mode(DiffMode::Threshold, 1.0).validate(), UsageError);
  EXPECT_THROW(mode(DiffMode::Band, 0.5).validate(), UsageError);
  EXPECT_THROW(mode(DiffMode::Band, std::nan("")).validate(), UsageError);
  EXPECT_NO_THROW(mode(DiffMode::Hard, 7.0).validate()) << "hard ignores alpha";
  EXPECT_EQ(mode(DiffMode::Threshold).effectiveAlpha(), DiffSettings::kDefaultThresholdAlpha);
  EXPECT_THROW(diff(SessionMap(0.05), SessionMap(0.1)), UsageError);
  TemporalMap m(0.05);
  EXPECT_THROW(diff(m, 0.0, std::numeric_limits<double>::infinity()), UsageError);
}

TEST(Diff, CellsMustNotOverlap) {
  ChangeCell big;
  big.key = test::at(0, 0, 0, kBase);
  big.level = 1;
  ChangeCell inside;
  inside.key = test::at(1, 1, 1, kBase);
  EXPECT_THROW(DiffMap::fromCells(0.05, {}, {big, inside}), FormatError);
  ChangeCell misaligned;
  misaligned.key = test::at(1, 0, 0, kBase);
  misaligned.level = 1;
  EXPECT_THROW(DiffMap::fromCells(0.05, {}, {misaligned}), FormatError);
  inside.value = std::nanf("");
  EXPECT_THROW(DiffMap::fromCells(0.05, {}, {inside}), FormatError);
  ChangeCell beside;
  beside.key = test::at(2, 2, 2, kBase);
  EXPECT_EQ(DiffMap::fromCells(0.05, {}, {beside, big}).cells()[0].key, big.key) << "sorted by Morton code";
}

// ---------------------------------------------------------------------------------------------
// Random maps against a slow reference: voxel by voxel, compareVoxel on find()'s counters.

SessionMap randomMap(std::mt19937_64& rng, const std::vector<uint8_t>& world) {
  SessionMap m(0.05);
  const int lo = static_cast<int>(rng() % 6), hi = kSide - static_cast<int>(rng() % 6);
  for (int z = lo; z < hi; ++z) {
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        if (rng() % 12 == 0) continue;  // unobserved
        const bool occ = world[(z * kSide + y) * kSide + x] != (rng() % 15 == 0);
        if (occ) {
          VoxelCounters c = withProbability(0.5 + 0.49 * static_cast<double>(rng() % 100) / 100.0,
                                            1 + static_cast<uint32_t>(rng() % 4), static_cast<uint8_t>(rng()));
          // Where in the voxel the hits ended: anywhere within it.
          for (float& o : c.offset) o = static_cast<float>(c.hits) * (static_cast<float>(rng() % 101) / 100.0f - 0.5f);
          m.add(test::at(x, y, z, kBase), c);
        } else if (rng() % 20 == 0) {
          m.add(test::at(x, y, z, kBase), withProbability(0.02 + 0.47 * static_cast<double>(rng() % 100) / 100.0));
        } else {
          m.add(test::at(x, y, z, kBase), test::freeVoxel(0.125f * static_cast<float>(1 + rng() % 4)));
        }
      }
    }
  }
  if (rng() % 2 == 0) m.compressFree();
  return m;
}

std::vector<uint8_t> randomWorld(std::mt19937_64& rng) {
  std::vector<uint8_t> w(kSide * kSide * kSide);
  for (auto& v : w) v = rng() % 8 == 0;
  return w;
}

// Expands a diff into unit voxels.
std::map<VoxelKey, ChangeCell> unitCells(const DiffMap& d) {
  std::map<VoxelKey, ChangeCell> out;
  for (const ChangeCell& c : d.cells()) {
    const int side = 1 << c.level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          ChangeCell u = c;
          u.key = VoxelKey{static_cast<uint16_t>(c.key.x + dx), static_cast<uint16_t>(c.key.y + dy),
                           static_cast<uint16_t>(c.key.z + dz)};
          u.level = 0;
          out[u.key] = u;
        }
      }
    }
  }
  return out;
}

TEST(Diff, EqualsVoxelByVoxelReferenceOnRandomMaps) {
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    std::mt19937_64 rng(seed);
    auto world = randomWorld(rng);
    const SessionMap a = randomMap(rng, world);
    for (auto& v : world) v ^= rng() % 10 == 0;
    const SessionMap b = randomMap(rng, world);
    for (DiffMode m : {DiffMode::Hard, DiffMode::Threshold, DiffMode::Band, DiffMode::Continuous}) {
      const DiffSettings s = mode(m);
      const auto got = unitCells(diff(a, b, s));
      size_t expected_count = 0;
      // The region plus a margin: nothing outside it may appear.
      for (int z = -1; z <= kSide; ++z) {
        for (int y = -1; y <= kSide; ++y) {
          for (int x = -1; x <= kSide; ++x) {
            const VoxelKey k = test::at(x, y, z, kBase);
            const auto expected =
                compareVoxel(a.find(k).value_or(VoxelCounters{}), b.find(k).value_or(VoxelCounters{}), s);
            const auto it = got.find(k);
            ASSERT_EQ(expected.has_value(), it != got.end())
                << "seed " << seed << " mode " << toString(m) << " voxel " << x << "," << y << "," << z;
            if (!expected) continue;
            ++expected_count;
            EXPECT_EQ(it->second.kind, expected->kind);
            EXPECT_EQ(it->second.colour, expected->colour);
            EXPECT_FLOAT_EQ(it->second.value, expected->value);
          }
        }
      }
      EXPECT_EQ(got.size(), expected_count);
    }
  }
}

// The neighbourhood rule written out plainly: is an occupied voxel within r of k in `other`,
// and how far did the mean hit position of the window move (each voxel's hits at its centre
// plus the offsets it recorded)?
bool referenceOccupiedNear(const SessionMap& other, const VoxelKey& k, int r) {
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const VoxelKey n{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy),
                         static_cast<uint16_t>(k.z + dz)};
        if (other.stateOf(n) == VoxelState::Occupied) return true;
      }
    }
  }
  return false;
}

// With plane_ratio > 0, the move along the normal of the plane the voxels' mean hit positions
// share (each map's about its own mean), found here from their singular vectors.
std::optional<double> referenceShiftVoxels(const SessionMap& a, const SessionMap& b, const VoxelKey& k, int r,
                                           double plane_ratio = 0.0, bool* planar = nullptr) {
  double ax = 0, ay = 0, az = 0, bx = 0, by = 0, bz = 0, wa = 0, wb = 0;
  std::vector<Eigen::Vector3d> points;
  std::vector<int> owner;
  int points_a = 0, points_b = 0;
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const VoxelKey n{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy),
                         static_cast<uint16_t>(k.z + dz)};
        if (a.stateOf(n) == VoxelState::Unknown || b.stateOf(n) == VoxelState::Unknown) continue;
        const VoxelCounters ca = *a.find(n), cb = *b.find(n);
        const double ha = ca.hits, hb = cb.hits;
        ax += ha * (k.x + dx) + ca.offset[0], ay += ha * (k.y + dy) + ca.offset[1];
        az += ha * (k.z + dz) + ca.offset[2], wa += ha;
        bx += hb * (k.x + dx) + cb.offset[0], by += hb * (k.y + dy) + cb.offset[1];
        bz += hb * (k.z + dz) + cb.offset[2], wb += hb;
        for (const VoxelCounters* c : {&ca, &cb}) {
          if (c->hits == 0) continue;
          points.emplace_back(dx + double(c->offset[0]) / c->hits, dy + double(c->offset[1]) / c->hits,
                              dz + double(c->offset[2]) / c->hits);
          owner.push_back(c == &ca ? 0 : 1);
          ++(c == &ca ? points_a : points_b);
        }
      }
    }
  }
  if (wa == 0 || wb == 0) return std::nullopt;
  const Eigen::Vector3d moved(bx / wb - ax / wa, by / wb - ay / wa, bz / wb - az / wa);
  if (planar) *planar = false;
  if (plane_ratio > 0.0 && points_a >= 3 && points_b >= 3) {
    // Each map's points about their own mean (a's first), stacked.
    Eigen::Vector3d mean[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    for (size_t i = 0; i < points.size(); ++i) mean[owner[i]] += points[i];
    mean[0] /= points_a;
    mean[1] /= points_b;
    Eigen::MatrixXd centred(points.size(), 3);
    for (size_t i = 0; i < points.size(); ++i) {
      centred.row(static_cast<Eigen::Index>(i)) = (points[i] - mean[owner[i]]).transpose();
    }
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred, Eigen::ComputeThinV);
    const Eigen::Vector3d sv = svd.singularValues();  // decreasing: spreads are their squares / n
    // Not along a line (the middle spread a tenth of the largest or more), the least spread small.
    if (sv[1] * sv[1] > 0.1 * sv[0] * sv[0] && sv[2] * sv[2] <= plane_ratio * sv[1] * sv[1]) {
      if (planar) *planar = true;
      return std::abs(moved.dot(svd.matrixV().col(2)));
    }
  }
  return moved.norm();
}

// Property: two maps see patches of one plane (random orientation) that overlap in part, the
// second's plane `delta` voxels further along its normal; every hit lies on its plane. Across the
// plane the shift is delta wherever both maps have hits in three voxels of the window that do
// not lie in a line; the whole move is not (the patches differ).
TEST(Diff, ShiftPlaneMeasuresTheMoveAlongTheNormalOfRandomPlanes) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  size_t checked = 0, slid = 0;
  for (int trial = 0; trial < 40; ++trial) {
    Eigen::Vector3d n(unit(rng), unit(rng), unit(rng));
    if (n.norm() < 0.2) continue;
    n.normalize();
    const double delta = 0.4 * (unit(rng) + 1.0) / 2.0;  // [0, 0.4] voxels
    const Eigen::Vector3d centre(6.0 + 0.5 * unit(rng), 6.0 + 0.5 * unit(rng), 6.0 + 0.5 * unit(rng));
    const Eigen::Vector3d cut = unit(rng) * Eigen::Vector3d(n.y(), -n.x(), 0.0).normalized();
    SessionMap maps[2] = {SessionMap(0.05), SessionMap(0.05)};
    for (int m = 0; m < 2; ++m) {
      const double c = n.dot(centre) + m * delta;
      for (int z = 0; z < 13; ++z) {
        for (int y = 0; y < 13; ++y) {
          for (int x = 0; x < 13; ++x) {
            VoxelCounters v = test::freeVoxel(0.25f);
            // The voxel's centre (x + 0.5, ...) projected onto the plane: a hit when it stays in
            // the voxel and on this map's side of the cut through the plane (before: one side,
            // after: the other and a band across it).
            const Eigen::Vector3d mid(x + 0.5, y + 0.5, z + 0.5);
            const Eigen::Vector3d p = mid - (n.dot(mid) - c) * n;
            const Eigen::Vector3d off = p - mid;
            const double side = (p - centre).dot(cut.normalized());
            const bool mine = m == 0 ? side < 0.5 : side > -0.5;
            if (off.cwiseAbs().maxCoeff() < 0.5 && mine) {
              v = withProbability(0.9, 1 + static_cast<uint32_t>(rng() % 4));
              for (int a = 0; a < 3; ++a) v.offset[a] = static_cast<float>(v.hits * off[a]);
            }
            maps[m].add(test::at(x, y, z, kBase), v);
          }
        }
      }
    }
    for (int z = 4; z < 9; ++z) {
      for (int y = 4; y < 9; ++y) {
        for (int x = 4; x < 9; ++x) {
          const VoxelKey k = test::at(x, y, z, kBase);
          int with_hits[2] = {0, 0};
          anyKeyWithin(k, 1, [&](const VoxelKey& q) {
            for (int m = 0; m < 2; ++m) with_hits[m] += maps[m].find(q).value_or(VoxelCounters{}).hits > 0;
            return false;
          });
          if (with_hits[0] < 3 || with_hits[1] < 3) continue;
          bool planar = false;
          referenceShiftVoxels(maps[0], maps[1], k, 1, 0.2, &planar);
          if (!planar) continue;  // the points of one map in a line: no plane to speak of
          const double across = surfaceShift(maps[0], maps[1], k, 1, 0.2).value();
          ASSERT_NEAR(across, delta, 1e-4) << "trial " << trial << " at " << x << "," << y << "," << z;
          ++checked;
          slid += surfaceShift(maps[0], maps[1], k, 1).value() > delta + 0.05;
        }
      }
    }
  }
  EXPECT_GT(checked, 500u);
  EXPECT_GT(slid, 100u) << "the patches differ: the whole move is larger where they do";
}

TEST(Diff, NeighbourhoodRuleEqualsReferenceOnRandomMaps) {
  size_t kept_by_shift = 0, dropped = 0, plane_decided = 0;
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    std::mt19937_64 rng(seed * 31);
    auto world = randomWorld(rng);
    const SessionMap a = randomMap(rng, world);
    for (auto& v : world) v ^= rng() % 10 == 0;
    const SessionMap b = randomMap(rng, world);
    for (int r : {1, 2}) {
      for (const auto& [min_shift, plane_ratio] : {std::pair{0.0, 0.0}, {0.2, 0.0}, {0.6, 0.0}, {0.2, 0.5}, {0.6, 1.0}}) {
        DiffSettings s = mode(seed % 2 ? DiffMode::Hard : DiffMode::Band);
        const auto plain = unitCells(diff(a, b, s));
        s.neighbourhood_voxels = r;
        s.min_shift_voxels = min_shift;
        s.shift_plane_ratio = plane_ratio;
        const auto got = unitCells(diff(a, b, s));
        size_t expected_count = 0, ties = 0;
        for (const auto& [k, c] : plain) {
          const bool near = referenceOccupiedNear(c.kind == ChangeKind::Appeared ? a : b, k, r);
          bool planar = false;
          const auto shift = referenceShiftVoxels(a, b, k, r, plane_ratio, &planar);
          const auto whole = referenceShiftVoxels(a, b, k, r);
          // Decisions the plane changed: kept by the whole move, dropped across the plane.
          plane_decided += planar && near && whole && *whole >= min_shift && *shift < min_shift;
          const bool moved = min_shift > 0.0 && shift && *shift >= min_shift;
          const bool keep = !near || moved;
          // Rounding decides a tie; the plane's eigenvectors (here from singular vectors) round
          // differently.
          if (near && shift && std::abs(*shift - min_shift) < (plane_ratio > 0.0 ? 1e-6 : 1e-9)) {
            ++ties;
            continue;
          }
          ASSERT_EQ(keep, got.count(k) == 1) << "seed " << seed << " r " << r << " min shift " << min_shift
                                             << " shift " << shift.value_or(-1.0);
          expected_count += keep;
          if (near && moved) ++kept_by_shift;
          if (!keep) ++dropped;
        }
        EXPECT_GE(got.size(), expected_count);
        EXPECT_LE(got.size(), expected_count + ties);
      }
    }
  }
  EXPECT_GT(kept_by_shift, 50u) << "the random maps exercise the shift test";
  EXPECT_GT(plane_decided, 20u) << "and decisions its measure across planes changes";
  EXPECT_GT(dropped, 50u);
}

TEST(Diff, FourDimensionalDiffEqualsDiffOfSnapshots) {
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    std::mt19937_64 rng(seed * 7919);
    auto world = randomWorld(rng);
    TemporalMap map(0.05);
    std::vector<double> times;
    for (int i = 0; i < 7; ++i) {
      for (auto& v : world) v ^= rng() % 12 == 0;
      const double t = 1000.0 + 100.0 * static_cast<double>(rng() % 50);  // any order
      if (std::find(times.begin(), times.end(), t) != times.end()) continue;
      map.add(t, randomMap(rng, world));
      times.push_back(t);
    }
    std::sort(times.begin(), times.end());
    std::vector<double> probes = times;
    probes.push_back(times.front() - 1.0);  // before the first session
    probes.push_back(times.back() + 50.0);
    for (int trial = 0; trial < 10; ++trial) {
      const double t1 = probes[rng() % probes.size()], t2 = probes[rng() % probes.size()];
      for (DiffMode m : {DiffMode::Hard, DiffMode::Threshold, DiffMode::Band, DiffMode::Continuous}) {
        DiffSettings s = mode(m);
        s.neighbourhood_voxels = trial % 3 == 0 ? 1 : 0;
        if (trial % 6 == 0) s.min_shift_voxels = 0.4;
        if (trial % 4 == 1) s.kept_surface_radius_voxels = 2;
        if (trial % 5 == 2) s.dark_surface_radius_voxels = 2;
        const DiffMap fast = diff(map, t1, t2, s);
        const DiffMap slow = diff(map.snapshot(t1), map.snapshot(t2), s);
        if (m == DiffMode::Continuous) {
          // Snapshots compress free space (one leaf where the 4D map holds several lists), and
          // continuous mode reports unchanged free space per leaf pair: the same voxels with the
          // same kinds and values, in cells of other sizes.
          ASSERT_TRUE(unitCells(fast) == unitCells(slow)) << "seed " << seed << " t1 " << t1 << " t2 " << t2;
          continue;
        }
        ASSERT_TRUE(fast == slow) << "seed " << seed << " mode " << toString(m) << " t1 " << t1 << " t2 " << t2
                                  << ": " << fast.cells().size() << " vs " << slow.cells().size() << " cells";
      }
    }
  }
}

TEST(Diff, FourDimensionalDiffVisitsOnlyChangedSubtrees) {
  // Many sessions over a wide area; one session changes one voxel. A diff across that session
  // visits one path; a diff across an unchanging session visits almost nothing.
  TemporalMap map(0.05);
  std::mt19937_64 rng(5);
  auto world = randomWorld(rng);
  for (int i = 0; i < 6; ++i) map.add(100.0 * i, randomMap(rng, world));
  SessionMap one(0.05);
  one.add(test::at(40, 40, 40, kBase), withProbability(0.9));
  map.add(1000.0, one);
  SessionMap flip(0.05);
  flip.add(test::at(40, 40, 40, kBase), test::freeVoxel(0.25f));
  map.add(1100.0, flip);
  DiffStats stats;
  const DiffMap d = diff(map, 1000.0, 1100.0, {}, &stats);
  ASSERT_EQ(d.cells().size(), 1u);
  EXPECT_EQ(d.cells()[0].kind, ChangeKind::Vanished);
  EXPECT_LE(stats.inner_nodes_visited, static_cast<size_t>(kTreeDepth) + 1) << "one root-to-leaf path";
  EXPECT_EQ(stats.lists_compared, 1u);
  DiffStats none;
  EXPECT_TRUE(diff(map, 1100.0, 1200.0, {}, &none).empty());
  EXPECT_LE(none.inner_nodes_visited, 1u);
}

}  // namespace
}  // namespace chronomap
