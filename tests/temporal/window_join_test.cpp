// A history kept as windows (temporal/window.h: continuedWindow, windowsOf, joinWindows) against
// the same sessions added night by night to one map compacted after each.

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/temporal/window.h"
#include "builders.h"
#include "window_compare.h"

namespace chronomap {
namespace {

using test::at;
using test::freeVoxel;
using test::occupiedVoxelExact;
using test::sameButFreeLengths;
using test::sameHistory;

constexpr int kWindowSide = 16;

double windowNightTime(int i) { return 5000.0 + 3600.0 * i; }

/// One night: the occupied voxels of `occupied` and free space around them, observed in a box
/// that differs from night to night (so neighbouring lists begin on different nights), sometimes
/// with holes, half of the nights compressed (so later occupied voxels refine coarse free cubes),
/// with lengths that are not binary fractions (so the order of every sum shows in the bits).
SessionMap night(std::mt19937_64& rng, const std::vector<uint8_t>& occupied) {
  SessionMap m(0.05);
  int lo[3], hi[3];
  const bool everything = rng() % 4 == 0;
  for (int a = 0; a < 3; ++a) {
    lo[a] = everything ? 0 : static_cast<int>(rng() % 8);
    hi[a] = everything ? kWindowSide : lo[a] + 4 + static_cast<int>(rng() % (kWindowSide - lo[a] - 3));
  }
  const bool holes = rng() % 3 == 0;
  std::uniform_real_distribution<float> length(0.013f, 0.9f);
  for (int z = lo[2]; z < hi[2]; ++z) {
    for (int y = lo[1]; y < hi[1]; ++y) {
      for (int x = lo[0]; x < hi[0]; ++x) {
        if (holes && rng() % 12 == 0) continue;
        if (occupied[(z * kWindowSide + y) * kWindowSide + x] != 0) {
          m.add(at(x, y, z), occupiedVoxelExact(1 + static_cast<uint32_t>(rng() % 3), static_cast<uint8_t>(rng() % 256)));
        } else if (rng() % 60 == 0) {
          VoxelCounters c = freeVoxel(2.0f + length(rng));  // free, but with a hit: never merged
          c.hits = 1;
          c.red = c.green = c.blue = static_cast<uint32_t>(rng() % 256);
          m.add(at(x, y, z), c);
        } else {
          m.add(at(x, y, z), freeVoxel(length(rng)));
        }
      }
    }
  }
  if (rng() % 2 == 0) m.compressFree();
  return m;
}

struct Built {
  TemporalMap whole{0.05};
  std::vector<TemporalMap> windows;
  std::vector<TemporalMap> whole_at;  // the whole map when each window was closed
  size_t refined_between_windows = 0;  // windows whose tree holds more inner nodes than the one before
  size_t coarser_continued = 0;         // windows continued with fewer lists than the one before held
};

/// `nights` nights of a seed, into one map and into windows of `k` nights, both compacted after
/// every night.
Built build(uint64_t seed, int nights, int k, const ChangeCriterion& criterion = {}) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> occupied(kWindowSide * kWindowSide * kWindowSide, 0);
  for (auto& o : occupied) o = rng() % 25 == 0;
  Built b;
  b.whole = TemporalMap(0.05, criterion);
  TemporalMap open(0.05, criterion);
  int own = 0;
  for (int i = 0; i < nights; ++i) {
    for (int f = 0; f < 12; ++f) occupied[rng() % occupied.size()] ^= 1;
    const SessionMap s = night(rng, occupied);
    b.whole.add(windowNightTime(i), s);
    b.whole.compact(TemporalMap::Relayout::kWhenMerged);
    open.add(windowNightTime(i), s);
    open.compact(TemporalMap::Relayout::kWhenMerged);
    if (++own == k) {
      b.windows.push_back(open);
      b.whole_at.push_back(b.whole);
      open = continuedWindow(open);
      b.coarser_continued += open.counts().slots < b.windows.back().counts().slots;
      own = 0;
    }
  }
  if (own > 0) {
    b.windows.push_back(open);
    b.whole_at.push_back(b.whole);
  }
  for (size_t j = 1; j < b.windows.size(); ++j) {
    b.refined_between_windows += b.windows[j].counts().inner_nodes > b.windows[j - 1].counts().inner_nodes;
  }
  return b;
}

TEST(WindowJoin, JoinedWindowsAreTheWholeHistoryBitForBit) {
  // The change criterion's every rule: the default (shift test), probability and colour
  // thresholds, the evidence rule, and every state change alone.
  std::vector<ChangeCriterion> criteria(5);
  criteria[1].probability_threshold = 0.2;
  criteria[2].colour_distance = 30.0;
  criteria[3].min_hits = 2;
  criteria[3].min_free_length_m = 0.2;
  criteria[4].surface_shift_voxels = 0.0;
  size_t refined = 0, windows = 0, coarser = 0;
  for (uint64_t seed = 1; seed <= 15; ++seed) {
    const int k = 1 + static_cast<int>(seed % 4);  // 2, 3, 4, 1, ...
    const Built b = build(seed, 14, k, criteria[seed % criteria.size()]);
    SCOPED_TRACE("seed " + std::to_string(seed) + ", windows of " + std::to_string(k) + ", criterion " +
                 std::to_string(seed % criteria.size()));
    windows += b.windows.size();
    refined += b.refined_between_windows;
    coarser += b.coarser_continued;
    const TemporalMap joined = joinWindows(b.windows);
    ASSERT_TRUE(sameHistory(joined, b.whole));
    // Every window answers its own nights as the whole map did when the window was closed, node
    // for node, but for the lengths of free voxels without hits in cubes it merged (a cube it
    // then refined again splits the summed length evenly), and in the states the whole map
    // answers now.
    int night_index = 0;
    for (size_t j = 0; j < b.windows.size(); ++j) {
      for (size_t r = j == 0 ? 0 : 1; r < b.windows[j].sessionCount(); ++r, ++night_index) {
        const double t = windowNightTime(night_index);
        ASSERT_EQ(b.windows[j].sessions()[r].time_s, t);
        const SessionMap snap = b.windows[j].snapshot(t);
        ASSERT_TRUE(sameButFreeLengths(snap, b.whole_at[j].snapshot(t))) << "window " << j << ", night " << night_index;
        const SessionMap now = b.whole.snapshot(t);
        for (int z = 0; z < kWindowSide; ++z) {
          for (int y = 0; y < kWindowSide; ++y) {
            for (int x = 0; x < kWindowSide; ++x) {
              ASSERT_EQ(snap.stateOf(at(x, y, z)), now.stateOf(at(x, y, z))) << "night " << night_index;
            }
          }
        }
      }
    }
    ASSERT_EQ(night_index, 14);
  }
  EXPECT_GT(windows, 50u);
  // Later windows refined cubes that earlier ones held whole, and continued windows merged
  // cubes whose parts were free alike: the join split the coarser ones' entries both ways.
  EXPECT_GT(refined, 10u);
  EXPECT_GT(coarser, 10u);
}

TEST(WindowJoin, AContinuedWindowStartsFromTheLatestStates) {
  const Built b = build(3, 6, 100);
  ASSERT_EQ(b.windows.size(), 1u);
  const TemporalMap& map = b.windows[0];
  const TemporalMap next = continuedWindow(map);
  ASSERT_EQ(next.sessionCount(), 1u);
  EXPECT_EQ(next.sessions()[0].time_s, map.sessions().back().time_s);
  EXPECT_LT(next.counts().slots, map.counts().slots);  // merged where the states are free alike
  EXPECT_EQ(next.counts().entries, next.counts().slots);  // one entry a list
  EXPECT_TRUE(next.snapshot(windowNightTime(5)) == map.snapshot(windowNightTime(5)));
  // Joining a map with its continuation, nothing added, gives the map back.
  EXPECT_TRUE(sameHistory(joinWindows({map, next}), map));
  EXPECT_THROW(continuedWindow(TemporalMap(0.05)), UsageError);
}

TEST(WindowJoin, ACubeAWindowHoldsCoarserIsSplitInTheJoin) {
  // Night 0 sees a cube of eight free voxels as one compressed leaf (a list of level 1 with an
  // entry of its own), night 1 sees it again; the continued window carries it, night 3 occupies
  // one voxel of it, which refines it there: the join splits window 0's entries.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> length(0.013f, 0.9f);
  SessionMap coarse(0.05), one_occupied(0.05);
  for (int i = 0; i < 8; ++i) {
    const VoxelKey k = at(2 + (i & 1), 4 + ((i >> 1) & 1), 6 + (i >> 2));
    coarse.add(k, freeVoxel(length(rng)));
    one_occupied.add(k, i == 5 ? occupiedVoxelExact(3) : freeVoxel(length(rng)));
  }
  coarse.compressFree();
  ASSERT_EQ(coarse.leafCount(), 1u);
  TemporalMap first(0.05);
  first.add(windowNightTime(0), coarse);
  first.add(windowNightTime(1), coarse);  // no change: no entry
  ASSERT_EQ(first.counts().slots, 1u);
  TemporalMap second = continuedWindow(first), whole = first;
  for (const auto& [t, s] : {std::pair{2, &coarse}, std::pair{3, &one_occupied}, std::pair{4, &coarse}}) {
    second.add(windowNightTime(t), *s);
    whole.add(windowNightTime(t), *s);
  }
  EXPECT_EQ(second.counts().slots, 8u);
  const TemporalMap joined = joinWindows({first, second});
  EXPECT_TRUE(sameHistory(joined, whole));
  const auto h = joined.history(at(3, 4, 7));
  ASSERT_EQ(h.size(), 3u);  // free (window 0's entry, split), occupied, free
  const auto before = first.history(at(3, 4, 7));  // the level-1 list's entry, read per voxel (split)
  ASSERT_EQ(before.size(), 1u);
  EXPECT_EQ(before[0].level, 1);
  EXPECT_EQ(h[0].level, 0);
  EXPECT_EQ(h[0].counters.length_m, before[0].counters.length_m);
}

TEST(WindowJoin, AMapWithEmptyInnerNodesIsCutAndJoinedBack) {
  // Removing a session that alone observed a place leaves inner nodes without children, which
  // the map keeps: the windows keep them too.
  const Built b = build(9, 6, 1000);
  TemporalMap map = b.windows.front();
  SessionMap far(0.05);
  far.add(at(200, 200, 200), occupiedVoxelExact(2));
  map.add(windowNightTime(3) + 1.0, far);
  map.remove(windowNightTime(3) + 1.0);
  ASSERT_GT(map.counts().inner_nodes, b.windows.front().counts().inner_nodes);
  for (uint32_t k = 1; k <= 4; ++k) EXPECT_TRUE(sameHistory(joinWindows(windowsOf(map, k)), map)) << "k " << k;
}

// A first window longer than the others (the windowed layout's staggered first window,
// store/tiled_file.h firstWindowSessions): window 0 holds sessions [0, f), window j > 0 the k
// after f + (j - 1)·k with the one before carried; they join back to the map.
TEST(WindowJoin, AFirstWindowOfItsOwnLengthJoinsBack) {
  const Built first = build(27, 10, 1000);
  const TemporalMap& map = first.whole;
  for (uint32_t k = 1; k <= 3; ++k) {
    for (const uint32_t f : {1u, k, k + 1, 2 * k, 9u, 10u, 12u}) {
      SCOPED_TRACE("windows of " + std::to_string(k) + ", the first of " + std::to_string(f));
      const std::vector<TemporalMap> windows = windowsOf(map, k, f);
      ASSERT_EQ(windows.size(), f >= 10 ? 1 : 1 + (10 - f + k - 1) / k);
      size_t begin = 0;  // the rank of each window's first session of its own
      for (size_t j = 0; j < windows.size(); ++j) {
        const TemporalMap& w = windows[j];
        const size_t own = std::min<size_t>(j == 0 ? f : k, 10 - begin);
        ASSERT_EQ(w.sessionCount(), own + (j > 0));
        EXPECT_EQ(w.sessions().back().time_s, map.sessions()[begin + own - 1].time_s);
        for (size_t r = 0; r < w.sessionCount(); ++r) {
          ASSERT_TRUE(w.snapshot(w.sessions()[r].time_s) == map.snapshot(w.sessions()[r].time_s));
        }
        begin += own;
      }
      EXPECT_EQ(begin, 10u);
      EXPECT_TRUE(sameHistory(joinWindows(windows), map));
    }
    // first_k 0 is k.
    const std::vector<TemporalMap> a = windowsOf(map, k, 0), b = windowsOf(map, k, k);
    ASSERT_EQ(a.size(), b.size());
    for (size_t j = 0; j < a.size(); ++j) EXPECT_TRUE(sameHistory(a[j], b[j])) << "window " << j;
  }
}

TEST(WindowJoin, AHistoryCutIntoWindowsJoinsBackAndGoesOn) {
  for (uint64_t seed = 20; seed < 26; ++seed) {
    // Ten nights in one map; then cut, and five more nights both ways.
    const Built first = build(seed, 10, 1000);
    const TemporalMap& map = first.windows.front();
    for (uint32_t k = 1; k <= 4; ++k) {
      SCOPED_TRACE("seed " + std::to_string(seed) + ", windows of " + std::to_string(k));
      std::vector<TemporalMap> windows = windowsOf(map, k);
      ASSERT_EQ(windows.size(), (10 + k - 1) / k);
      ASSERT_TRUE(sameHistory(joinWindows(windows), map));
      for (size_t j = 0; j < windows.size(); ++j) {
        const TemporalMap& w = windows[j];
        ASSERT_EQ(w.sessionCount(), std::min<size_t>(10, (j + 1) * k) - j * k + (j > 0));
        for (size_t r = j == 0 ? 0 : 1; r < w.sessionCount(); ++r) {
          ASSERT_TRUE(w.snapshot(w.sessions()[r].time_s) == map.snapshot(w.sessions()[r].time_s));
        }
        EXPECT_LE(w.counts().slots, map.counts().slots);
      }
      // Go on from the last window.
      TemporalMap whole = map, open = windows.back();
      windows.pop_back();
      size_t own = open.sessionCount() - (windows.empty() ? 0 : 1);
      std::mt19937_64 rng(seed * 31 + k);
      std::vector<uint8_t> occupied(kWindowSide * kWindowSide * kWindowSide, 0);
      for (auto& o : occupied) o = rng() % 25 == 0;
      for (int i = 10; i < 15; ++i) {
        const SessionMap s = night(rng, occupied);
        whole.add(windowNightTime(i), s);
        whole.compact(TemporalMap::Relayout::kWhenMerged);
        open.add(windowNightTime(i), s);
        open.compact(TemporalMap::Relayout::kWhenMerged);
        if (++own == k) {
          windows.push_back(open);
          open = continuedWindow(open);
          own = 0;
        }
      }
      if (own > 0) windows.push_back(open);
      ASSERT_TRUE(sameHistory(joinWindows(windows), whole));
    }
  }
  EXPECT_THROW(windowsOf(TemporalMap(0.05), 2), UsageError);
  EXPECT_THROW(windowsOf(build(1, 2, 5).windows.front(), 0), UsageError);
}

TEST(WindowJoin, WindowsThatDoNotJoinAreRefused) {
  const Built b = build(5, 9, 3);
  ASSERT_EQ(b.windows.size(), 3u);
  EXPECT_THROW(joinWindows({}), UsageError);
  // Out of order, or one left out: the first session is not the one before.
  EXPECT_THROW(joinWindows({b.windows[0], b.windows[2]}), UsageError);
  EXPECT_THROW(joinWindows({b.windows[1], b.windows[0]}), UsageError);
  // Another criterion.
  ChangeCriterion other;
  other.probability_threshold = 0.2;
  const TemporalMap::Parts p1 = b.windows[1].parts();
  EXPECT_THROW(joinWindows({b.windows[0], TemporalMap::fromParts(0.05, other, p1, b.windows[1].sessions())}),
               UsageError);
  // A carried state that is not the state the window before ends with.
  TemporalMap::Parts changed = p1;
  const std::vector<int> levels = TemporalMap::listLevelsOf(changed.inner, changed.list_sizes.size());
  size_t at_entry = 0;
  for (size_t i = 0; i < changed.list_sizes.size(); at_entry += changed.list_sizes[i++]) {
    if (levels[i] == 0 && changed.entries[at_entry].session == 0 && changed.entries[at_entry].value.hits == 0) break;
  }
  ASSERT_LT(at_entry, changed.entries.size());
  changed.entries[at_entry].value = occupiedVoxelExact(4);
  const TemporalMap broken = TemporalMap::fromParts(0.05, {}, changed, b.windows[1].sessions());
  try {
    joinWindows({b.windows[0], broken, b.windows[2]});
    ADD_FAILURE() << "a changed carried state joined";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("window 1"), std::string::npos) << e.what();
  }
  // A later window that lacks a place observed before it, or carries a state into one no window
  // before it observed.
  SessionMap far(0.05);
  far.add(at(200, 200, 200), occupiedVoxelExact(2));
  TemporalMap wider = b.windows[0], narrower = b.windows[0];
  wider.add(windowNightTime(2) + 1.0, far);
  narrower.add(windowNightTime(2) + 1.0, SessionMap(0.05));
  try {
    joinWindows({wider, continuedWindow(narrower)});
    ADD_FAILURE() << "a window without a place observed before it joined";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
  }
  try {
    joinWindows({narrower, continuedWindow(wider)});
    ADD_FAILURE() << "a state carried into a place never observed joined";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("no window before it observed"), std::string::npos) << e.what();
  }
  // A free carried state of another length is the same state: it joins.
  changed = p1;
  for (auto& e : changed.entries) {
    if (e.session == 0 && e.value.hits == 0) e.value.length_m *= 1.5f;
  }
  EXPECT_TRUE(sameHistory(
      joinWindows({b.windows[0], TemporalMap::fromParts(0.05, {}, changed, b.windows[1].sessions()), b.windows[2]}),
      joinWindows(b.windows)));
}

}  // namespace
}  // namespace chronomap
