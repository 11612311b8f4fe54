#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/temporal/temporal_map.h"
#include "builders.h"

namespace chronomap {
namespace {

constexpr int kMapSide = 16;  // the test region: kMapSide^3 voxels from the map origin

using test::at;
using test::freeVoxel;
using test::occupiedVoxelExact;

// ---------------------------------------------------------------------------------------------
// The slow reference: a plain list of session maps, kept in time order.

struct Reference {
  std::vector<std::pair<double, SessionMap>> sessions;  // sorted by time
  ChangeCriterion criterion;

  void add(double t, const SessionMap& m) {
    auto it = std::find_if(sessions.begin(), sessions.end(), [&](const auto& s) { return s.first > t; });
    sessions.insert(it, {t, m});
  }
  void remove(double t) {
    sessions.erase(std::find_if(sessions.begin(), sessions.end(), [&](const auto& s) { return s.first == t; }));
  }
  /// The state of the most recent observation at or before t.
  VoxelState state(const VoxelKey& k, double t) const {
    VoxelState s = VoxelState::Unknown;
    for (const auto& [time, map] : sessions) {
      if (time > t) break;
      if (auto c = map.find(k)) s = c->state();
    }
    return s;
  }
  /// Observations in time order with a change under the criterion (the first one included).
  std::vector<std::pair<double, VoxelCounters>> chain(const VoxelKey& k) const {
    std::vector<std::pair<double, VoxelCounters>> out;
    for (const auto& [time, map] : sessions) {
      auto c = map.find(k);
      if (!c) continue;
      if (out.empty() || criterion.differs(out.back().second, *c)) out.emplace_back(time, *c);
    }
    return out;
  }
};

// A world of kMapSide^3 voxels, mostly free, whose occupied voxels drift from session to session.
struct World {
  std::vector<uint8_t> occupied = std::vector<uint8_t>(kMapSide * kMapSide * kMapSide, 0);
  void init(std::mt19937_64& rng) {
    for (auto& o : occupied) o = rng() % 10 == 0;
  }
  void change(std::mt19937_64& rng, int flips) {
    for (int i = 0; i < flips; ++i) occupied[rng() % occupied.size()] ^= 1;
  }
};

// One session: an observed box (sometimes everything), a few holes, some noise, optionally
// compressed. Lengths are binary fractions so that splitting and summing stay exact.
SessionMap randomSession(std::mt19937_64& rng, const World& world) {
  SessionMap m(0.05);
  int lo[3], hi[3];
  const bool everything = rng() % 3 == 0;
  for (int a = 0; a < 3; ++a) {
    lo[a] = everything ? 0 : static_cast<int>(rng() % 8);
    hi[a] = everything ? kMapSide : lo[a] + 4 + static_cast<int>(rng() % (kMapSide - lo[a] - 3));
  }
  const bool holes = rng() % 2 == 0;
  for (int z = lo[2]; z < hi[2]; ++z) {
    for (int y = lo[1]; y < hi[1]; ++y) {
      for (int x = lo[0]; x < hi[0]; ++x) {
        if (holes && rng() % 10 == 0) continue;
        bool occ = world.occupied[(z * kMapSide + y) * kMapSide + x] != 0;
        if (rng() % 40 == 0) occ = !occ;  // sensor noise
        VoxelCounters c;
        if (occ) {
          c = occupiedVoxelExact(1 + static_cast<uint32_t>(rng() % 3), static_cast<uint8_t>(rng() % 256));
        } else if (rng() % 50 == 0) {
          c = freeVoxel(4.0f);  // free, but with a hit: never compressed
          c.hits = 1;
          c.red = c.green = c.blue = 50;
        } else {
          c = freeVoxel(0.125f * static_cast<float>(1 + rng() % 4));
        }
        m.add(at(x, y, z), c);
      }
    }
  }
  if (rng() % 2 == 0) m.compressFree();
  return m;
}

void expectStatesMatch(const TemporalMap& map, const Reference& ref, double t) {
  const SessionMap snap = map.snapshot(t);
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        ASSERT_EQ(snap.stateOf(at(x, y, z)), ref.state(at(x, y, z), t)) << "voxel " << x << "," << y << "," << z
                                                                         << " at t=" << t;
      }
    }
  }
}

// Histories: same times and states as the reference's chain; counters too when `exact`.
void expectHistoriesMatch(const TemporalMap& map, const Reference& ref, bool exact) {
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        const auto h = map.history(at(x, y, z));
        const auto c = ref.chain(at(x, y, z));
        ASSERT_EQ(h.size(), c.size()) << "voxel " << x << "," << y << "," << z;
        for (size_t i = 0; i < h.size(); ++i) {
          ASSERT_EQ(h[i].time_s, c[i].first);
          ASSERT_EQ(h[i].counters.state(), c[i].second.state());
          if (exact) {
            ASSERT_EQ(h[i].counters, c[i].second) << "voxel " << x << "," << y << "," << z << " entry " << i;
          }
        }
      }
    }
  }
}

void expectChangeCountsMatch(const TemporalMap& map, const Reference& ref, double t0, double t1) {
  std::map<VoxelKey, uint32_t> counted;
  map.forEachChangeCount(t0, t1, [&](const VoxelKey& k, int level, uint32_t n) {
    const int side = 1 << level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          counted[{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy), static_cast<uint16_t>(k.z + dz)}] = n;
        }
      }
    }
  });
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        const auto c = ref.chain(at(x, y, z));
        uint32_t expected = 0;
        for (size_t i = 1; i < c.size(); ++i) expected += c[i].first > t0 && c[i].first <= t1;
        const auto it = counted.find(at(x, y, z));
        ASSERT_EQ(it == counted.end() ? 0u : it->second, expected) << "voxel " << x << "," << y << "," << z;
      }
    }
  }
}

double sessionTime(int i) { return 1000.0 + 100.0 * i; }

// Replaces one of the n sessions (the world changed) and removes the next, in the map and the
// reference alike.
void replaceOneRemoveAnother(std::mt19937_64& rng, World& world, int n, TemporalMap& map, Reference& ref) {
  world.change(rng, 200);
  const SessionMap replacement = randomSession(rng, world);
  const int replaced = static_cast<int>(rng() % static_cast<uint64_t>(n));
  map.add(sessionTime(replaced), replacement, AddSettings{true, ""});
  ref.remove(sessionTime(replaced));
  ref.add(sessionTime(replaced), replacement);
  const int removed = (replaced + 1) % n;
  map.remove(sessionTime(removed));
  ref.remove(sessionTime(removed));
}

// ---------------------------------------------------------------------------------------------
// Analytic cases.

// memoryUse() splits memoryBytes() part by part: the parts sum to it, with free list records,
// arena room and hit parts (after a replace and a removal) and after compaction.
TEST(TemporalMap, MemoryUseSumsToMemoryBytes) {
  std::mt19937_64 rng(27);
  World world;
  world.init(rng);
  TemporalMap map(0.05);
  Reference ref;
  auto sum = [](const TemporalMap::MemoryUse& m) {
    return m.inner + m.lists + m.entries + m.hit_parts + m.slack + m.coarse + m.sessions + m.change_masks;
  };
  constexpr int kSessions = 6;
  for (int i = 0; i < kSessions; ++i) {
    world.change(rng, 200);
    const SessionMap s = randomSession(rng, world);
    map.add(sessionTime(i), s);
    ref.add(sessionTime(i), s);
    EXPECT_EQ(sum(map.memoryUse()), map.memoryBytes()) << "after session " << i;
  }
  replaceOneRemoveAnother(rng, world, kSessions, map, ref);
  const TemporalMap::MemoryUse m = map.memoryUse();
  EXPECT_GT(m.entries, 0u);
  EXPECT_GT(m.hit_parts, 0u);
  EXPECT_GT(m.sessions, 0u);
  EXPECT_EQ(sum(m), map.memoryBytes());
  map.compact();
  EXPECT_EQ(sum(map.memoryUse()), map.memoryBytes());
}

TEST(TemporalMap, OnlyChangesCreateEntries) {
  TemporalMap map(0.05);
  SessionMap a(0.05), b(0.05), c(0.05);
  a.add(at(1, 1, 1), occupiedVoxelExact(2));
  a.add(at(2, 1, 1), freeVoxel(0.25f));
  b.add(at(1, 1, 1), occupiedVoxelExact(3));  // still occupied: no entry
  b.add(at(2, 1, 1), occupiedVoxelExact(1));  // free -> occupied: one entry
  map.add(10, a);
  const size_t nodes_after_a = map.counts().nodes();
  map.add(20, b);
  EXPECT_EQ(map.counts().nodes(), nodes_after_a + 1) << "a changed leaf adds exactly one node";
  EXPECT_EQ(map.sessions()[1].nodes_added, 1);
  map.add(30, c);  // observed nothing
  EXPECT_EQ(map.sessions()[2].nodes_added, 0);

  EXPECT_EQ(map.snapshot(5).leafCount(), 0u);
  EXPECT_EQ(map.snapshot(10).stateOf(at(2, 1, 1)), VoxelState::Free);
  EXPECT_EQ(map.snapshot(19.9).stateOf(at(2, 1, 1)), VoxelState::Free);
  EXPECT_EQ(map.snapshot(20).stateOf(at(2, 1, 1)), VoxelState::Occupied);
  EXPECT_EQ(map.snapshot(1e9).stateOf(at(2, 1, 1)), VoxelState::Occupied);
  EXPECT_EQ(map.snapshot(1e9).stateOf(at(3, 1, 1)), VoxelState::Unknown);
  // The unchanged voxel keeps the counters of the observation that set its state.
  EXPECT_EQ(*map.snapshot(25).find(at(1, 1, 1)), occupiedVoxelExact(2));

  const auto h = map.history(at(2, 1, 1));
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[0].time_s, 10);
  EXPECT_EQ(h[0].counters.state(), VoxelState::Free);
  EXPECT_EQ(h[1].time_s, 20);
  EXPECT_EQ(h[1].counters, occupiedVoxelExact(1));
  EXPECT_TRUE(map.history(at(9, 9, 9)).empty());
}

// The evidence rule (ChangeCriterion::min_free_length_m, min_hits): a grazing ray does not end
// an occupied state, a stray hit does not end a free one, and one or two hits do not make a shift;
// clear evidence still does, and without the rule every state change counts.
TEST(TemporalMap, WeakObservationsDoNotChangeAStateUnderTheEvidenceRule) {
  ChangeCriterion rule;
  rule.min_free_length_m = 0.025;
  rule.min_hits = 2;
  auto shifted = [](uint32_t hits, float offset) {
    VoxelCounters v = occupiedVoxelExact(hits);
    v.offset[0] = offset * static_cast<float>(hits);  // mean offset `offset` voxels along x
    return v;
  };
  const VoxelKey wall = at(1, 1, 1), space = at(2, 1, 1), thin = at(3, 1, 1), surface = at(4, 1, 1);
  auto sessions = [&](bool strong) {
    std::vector<SessionMap> out(2, SessionMap(0.05));
    out[0].add(wall, occupiedVoxelExact(4));
    out[0].add(space, freeVoxel(0.25f));
    out[0].add(thin, shifted(1, -0.4f));
    out[0].add(surface, shifted(strong ? 3 : 1, -0.4f));
    out[1].add(wall, freeVoxel(strong ? 0.05f : 0.01f));   // seen through, or grazed (10 mm)
    out[1].add(space, occupiedVoxelExact(strong ? 2 : 1));  // an object, or one stray hit
    out[1].add(thin, shifted(strong ? 2 : 1, 0.4f));        // moved 0.8 voxel: two hits, or one
    out[1].add(surface, shifted(strong ? 3 : 1, 0.4f));
    return out;
  };
  for (const bool strong : {false, true}) {
    TemporalMap with(0.05, rule), without(0.05);
    for (const TemporalMap* m : {&with, &without}) {
      TemporalMap& map = const_cast<TemporalMap&>(*m);
      const std::vector<SessionMap> s = sessions(strong);
      map.add(10, s[0]);
      map.add(20, s[1]);
    }
    for (const VoxelKey& k : {wall, space, surface}) {
      EXPECT_EQ(without.history(k).size(), 2u) << "without the rule every change counts";
    }
    if (strong) {
      for (const VoxelKey& k : {wall, space, surface}) EXPECT_EQ(with.history(k).size(), 2u) << "clear evidence";
      // Two hits on one side, one on the other: the shift test needs two on both.
      EXPECT_EQ(with.history(thin).size(), 1u);
      EXPECT_EQ(with.snapshot(20).stateOf(wall), VoxelState::Free);
      EXPECT_EQ(with.snapshot(20).stateOf(space), VoxelState::Occupied);
    } else {
      for (const VoxelKey& k : {wall, space, surface, thin}) EXPECT_EQ(with.history(k).size(), 1u) << "weak evidence";
      EXPECT_EQ(with.snapshot(20).stateOf(wall), VoxelState::Occupied);  // the state before stays
      EXPECT_EQ(with.snapshot(20).stateOf(space), VoxelState::Free);
      EXPECT_EQ(*with.snapshot(20).find(wall), occupiedVoxelExact(4));
    }
  }
  // In time order only: an earlier session, removing or replacing one before the last, refused
  // with the map unchanged; the last one may be replaced or removed.
  TemporalMap ordered(0.05, rule);
  const std::vector<SessionMap> s = sessions(true);
  ordered.add(10, s[0]);
  ordered.add(20, s[1]);
  const TemporalMap kept = ordered;
  EXPECT_THROW(ordered.add(5, s[1]), UsageError);
  EXPECT_THROW(ordered.add(10, s[1], {true, ""}), UsageError);
  EXPECT_THROW(ordered.remove(10), UsageError);
  EXPECT_TRUE(ordered == kept);
  ordered.add(20, s[0], {true, ""});
  EXPECT_EQ(ordered.sessionCount(), 2u);
  ordered.remove(20);
  EXPECT_EQ(ordered.sessionCount(), 1u);
  // min_hits 1 is the rule off: the same criterion as 0.
  ChangeCriterion one;
  one.min_hits = 1;
  EXPECT_TRUE(TemporalMap(0.05, one).criterion() == ChangeCriterion{});

  ChangeCriterion bad = rule;
  bad.min_free_length_m = -1.0;
  EXPECT_THROW(bad.validate(), UsageError);
  bad.min_free_length_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(bad.validate(), UsageError);
  bad = rule;
  bad.min_hits = 2000000;
  EXPECT_THROW(bad.validate(), UsageError);
}

TEST(TemporalMap, UnobservedSpaceIsNeverAChange) {
  TemporalMap map(0.05);
  SessionMap a(0.05), b(0.05);
  a.add(at(0, 0, 0), occupiedVoxelExact(1));
  b.add(at(5, 5, 5), freeVoxel(0.5f));
  map.add(1, a);
  map.add(2, b);
  EXPECT_EQ(map.snapshot(2).stateOf(at(0, 0, 0)), VoxelState::Occupied);
  size_t changed = 0;
  map.forEachChangeCount(0, 10, [&](const VoxelKey&, int, uint32_t) { ++changed; });
  EXPECT_EQ(changed, 0u);
}

TEST(TemporalMap, RejectsDuplicateTimesUnlessReplacing) {
  TemporalMap map(0.05);
  SessionMap a(0.05), b(0.05);
  a.add(at(0, 0, 0), occupiedVoxelExact(1));
  b.add(at(0, 0, 0), freeVoxel(1.0f));
  map.add(1, a);
  EXPECT_THROW(map.add(1, b), UsageError);
  EXPECT_EQ(map.snapshot(1).stateOf(at(0, 0, 0)), VoxelState::Occupied) << "a refused add changes nothing";
  const AddReport r = map.add(1, b, AddSettings{true, "b"});
  EXPECT_TRUE(r.replaced);
  EXPECT_EQ(map.sessionCount(), 1u);
  EXPECT_EQ(map.snapshot(1).stateOf(at(0, 0, 0)), VoxelState::Free);
  EXPECT_THROW(map.add(std::nan(""), a), UsageError);
  EXPECT_THROW(map.add(2, SessionMap(0.1)), UsageError);
  EXPECT_THROW(map.remove(3), UsageError);
}

TEST(TemporalMap, RefusesTimesNoCommandCouldName) {
  // A session at 1e300 s could be stored and never named again by `--time` (years 1 to 9999).
  TemporalMap map(0.05);
  SessionMap a(0.05);
  a.add(at(0, 0, 0), occupiedVoxelExact(1));
  for (double bad : {1e300, -1e300, kLatestTime_s + 1.0, kEarliestTime_s - 1.0}) {
    try {
      map.add(bad, a);
      ADD_FAILURE() << bad << " was stored";
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("lies outside the years 1 to 9999"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(map.sessionCount(), 0u);
  map.add(kEarliestTime_s, a);
  map.add(kLatestTime_s, a);
  EXPECT_EQ(map.times(), (std::vector<double>{kEarliestTime_s, kLatestTime_s}));
}

TEST(TemporalMap, ChangeInsideACompressedCubeRefinesIt) {
  SessionMap a(0.05);
  for (int z = 0; z < 8; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 8; ++x) a.add(at(x, y, z), freeVoxel(0.5f));
    }
  }
  a.compressFree();
  ASSERT_EQ(a.leafCount(), 1u);
  SessionMap b(0.05);
  b.add(at(3, 4, 5), occupiedVoxelExact(2));
  TemporalMap map(0.05);
  map.add(1, a);
  EXPECT_EQ(map.counts().entries, 1u) << "a compressed free cube is one entry";
  map.add(2, b);
  const SessionMap s1 = map.snapshot(1), s2 = map.snapshot(2);
  for (int z = 0; z < 8; ++z) {
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 8; ++x) {
        EXPECT_EQ(s1.stateOf(at(x, y, z)), VoxelState::Free);
        EXPECT_EQ(s2.stateOf(at(x, y, z)), x == 3 && y == 4 && z == 5 ? VoxelState::Occupied : VoxelState::Free);
        EXPECT_FLOAT_EQ(s1.find(at(x, y, z))->length_m, 0.5f);
      }
    }
  }
  const auto h = map.history(at(0, 0, 0));
  ASSERT_EQ(h.size(), 1u);
  EXPECT_GT(h[0].level, 0);
  EXPECT_FLOAT_EQ(h[0].counters.length_m, 0.5f);
  // Compaction cannot merge the refined cube back (one voxel differs), but keeps it exact.
  map.compact();
  EXPECT_EQ(map.snapshot(2).stateOf(at(3, 4, 5)), VoxelState::Occupied);
  EXPECT_EQ(map.snapshot(2).stateOf(at(3, 4, 4)), VoxelState::Free);
}

TEST(TemporalMap, SessionAddedBeforeLaterOnesRestoresTheirStates) {
  // t=1 occupied, t=3 occupied again (not stored: no change); t=2 arrives late saying free.
  SessionMap occ(0.05), fre(0.05);
  occ.add(at(0, 0, 0), occupiedVoxelExact(1));
  fre.add(at(0, 0, 0), freeVoxel(1.0f));
  TemporalMap map(0.05);
  map.add(1, occ);
  map.add(3, occ);
  EXPECT_EQ(map.history(at(0, 0, 0)).size(), 1u);
  const AddReport r = map.add(2, fre);
  EXPECT_TRUE(r.out_of_order);
  EXPECT_EQ(map.snapshot(1).stateOf(at(0, 0, 0)), VoxelState::Occupied);
  EXPECT_EQ(map.snapshot(2).stateOf(at(0, 0, 0)), VoxelState::Free);
  EXPECT_EQ(map.snapshot(3).stateOf(at(0, 0, 0)), VoxelState::Occupied);
  EXPECT_EQ(map.history(at(0, 0, 0)).size(), 3u);
  map.remove(2);
  EXPECT_EQ(map.history(at(0, 0, 0)).size(), 1u);
  EXPECT_EQ(map.snapshot(2).stateOf(at(0, 0, 0)), VoxelState::Occupied);
}

TEST(TemporalMap, CriterionThresholds) {
  ChangeCriterion c;
  EXPECT_FALSE(c.differs(occupiedVoxelExact(1, 0), occupiedVoxelExact(1, 255)));
  c.colour_distance = 100;
  EXPECT_TRUE(c.differs(occupiedVoxelExact(1, 0), occupiedVoxelExact(1, 255)));
  EXPECT_FALSE(c.differs(occupiedVoxelExact(1, 100), occupiedVoxelExact(1, 150)));
  EXPECT_FALSE(c.differs(freeVoxel(1.0f), freeVoxel(2.0f))) << "no colour without hits";
  ChangeCriterion p;
  p.probability_threshold = 0.2;
  VoxelCounters weak = freeVoxel(1.0f);
  weak.hits = 1;  // P = 0.63
  VoxelCounters strong = freeVoxel(0.25f);
  strong.hits = 4;  // P = 1 - e^-16
  EXPECT_TRUE(p.differs(weak, strong));
  EXPECT_FALSE(ChangeCriterion{}.differs(weak, strong));
  EXPECT_THROW((ChangeCriterion{-1.0, 0.0}.validate()), UsageError);
  EXPECT_THROW((ChangeCriterion{0.0, std::nan("")}.validate()), UsageError);
}

// ---------------------------------------------------------------------------------------------
// Property tests against the reference.

class TemporalProperty : public ::testing::TestWithParam<uint64_t> {};

TEST_P(TemporalProperty, InOrderSnapshotsHistoriesAndCountsMatchTheReference) {
  std::mt19937_64 rng(GetParam());
  World world;
  world.init(rng);
  TemporalMap map(0.05);
  Reference ref;
  const int n = 6 + static_cast<int>(rng() % 5);
  for (int i = 0; i < n; ++i) {
    world.change(rng, 60);
    const SessionMap s = randomSession(rng, world);
    map.add(sessionTime(i), s);
    ref.add(sessionTime(i), s);
  }
  for (int i = -1; i < n; ++i) expectStatesMatch(map, ref, sessionTime(i) + (i % 2 ? 0.0 : 50.0));
  expectHistoriesMatch(map, ref, /*exact=*/true);
  expectChangeCountsMatch(map, ref, 0, 1e9);
  expectChangeCountsMatch(map, ref, sessionTime(1), sessionTime(n - 2));
  // Snapshot counters are those of the last change, as the reference chain says (the exact
  // counters of free space: SnapshotsAtEveryTimeAreTheDenseModelInAnyOrder).
  const double t = sessionTime(n - 1);
  const SessionMap snap = map.snapshot(t);
  SessionMap checked(0.05);  // the snapshot's pools pass the reader's validation
  SessionMap::Pools pools = snap.pools();
  EXPECT_NO_THROW(checked.assignPools(std::move(pools.inner), std::move(pools.leaves)));
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        const auto c = ref.chain(at(x, y, z));
        const auto got = snap.find(at(x, y, z));
        ASSERT_EQ(got.has_value(), !c.empty());
        if (got && c.back().second.isKnownFreeWithoutHits()) {
          // Free space may be one compressed leaf (lengths summed): still free without hits.
          ASSERT_TRUE(got->isKnownFreeWithoutHits());
        } else if (got) {
          ASSERT_EQ(*got, c.back().second);
        }
      }
    }
  }
  // Compaction and re-layout change nothing that a query can see.
  TemporalMap compacted = map;
  compacted.compact();
  for (int i = 0; i < n; ++i) expectStatesMatch(compacted, ref, sessionTime(i));
  expectChangeCountsMatch(compacted, ref, 0, 1e9);
  EXPECT_LE(compacted.counts().nodes(), map.counts().nodes());
}

TEST_P(TemporalProperty, AnyInsertionOrderGivesTheSameStates) {
  std::mt19937_64 rng(GetParam() + 1000);
  World world;
  world.init(rng);
  std::vector<SessionMap> sessions;
  const int n = 6 + static_cast<int>(rng() % 4);
  for (int i = 0; i < n; ++i) {
    world.change(rng, 60);
    sessions.push_back(randomSession(rng, world));
  }
  std::vector<int> order(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) order[static_cast<size_t>(i)] = i;
  std::shuffle(order.begin(), order.end(), rng);
  TemporalMap map(0.05);
  Reference ref;
  for (int i : order) {
    map.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
    ref.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
  }
  for (int i = 0; i < n; ++i) expectStatesMatch(map, ref, sessionTime(i));
  expectHistoriesMatch(map, ref, /*exact=*/false);
  expectChangeCountsMatch(map, ref, 0, 1e9);
  expectChangeCountsMatch(map, ref, sessionTime(2), sessionTime(n - 1));

  // Replace one session, then remove another: still the reference's states.
  replaceOneRemoveAnother(rng, world, n, map, ref);
  for (int i = 0; i < n; ++i) expectStatesMatch(map, ref, sessionTime(i));
  expectHistoriesMatch(map, ref, /*exact=*/false);
}

TEST_P(TemporalProperty, ProbabilityCriterionMatchesTheReferenceChain) {
  std::mt19937_64 rng(GetParam() + 2000);
  World world;
  world.init(rng);
  ChangeCriterion criterion;
  criterion.probability_threshold = 0.1;
  criterion.colour_distance = 60;
  TemporalMap map(0.05, criterion);
  Reference ref;
  ref.criterion = criterion;
  for (int i = 0; i < 6; ++i) {
    world.change(rng, 40);
    const SessionMap s = randomSession(rng, world);
    map.add(sessionTime(i), s);
    ref.add(sessionTime(i), s);
  }
  expectHistoriesMatch(map, ref, /*exact=*/true);
  for (int i = 0; i < 6; ++i) expectStatesMatch(map, ref, sessionTime(i));
}

INSTANTIATE_TEST_SUITE_P(Seeds, TemporalProperty, ::testing::Range<uint64_t>(0, 12));

TEST(TemporalMap, PartsRoundTripAndRejectBrokenParts) {
  std::mt19937_64 rng(7);
  World world;
  world.init(rng);
  TemporalMap map(0.05);
  for (int i = 0; i < 5; ++i) {
    world.change(rng, 50);
    map.add(sessionTime(i), randomSession(rng, world));
  }
  map.compact();
  std::vector<SessionRecord> records = map.sessions();
  const TemporalMap back = TemporalMap::fromParts(0.05, {}, map.parts(), records);
  EXPECT_TRUE(back == map);

  auto broken = map.parts();
  broken.entries[0].session = 99;
  EXPECT_THROW(TemporalMap::fromParts(0.05, {}, broken, records), FormatError);
  broken = map.parts();
  broken.inner[0][0] = 12345678;
  EXPECT_THROW(TemporalMap::fromParts(0.05, {}, broken, records), FormatError);
  broken = map.parts();
  broken.list_sizes.back() += 1;
  EXPECT_THROW(TemporalMap::fromParts(0.05, {}, broken, records), FormatError);
  auto unordered = records;
  std::swap(unordered[0], unordered[1]);
  EXPECT_THROW(TemporalMap::fromParts(0.05, {}, map.parts(), unordered), FormatError);
}


// ---------------------------------------------------------------------------------------------
// Coarse entries: a snapshot is the dense per-voxel model at that time, compressed.

// The slow model: every voxel of the test region read from its history at `t` (the entry valid
// then), as unit voxels, then compressed as every session map is.
SessionMap denseSnapshot(const TemporalMap& map, double t) {
  SessionMap dense(map.resolution_m());
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        std::optional<VoxelCounters> value;
        for (const HistoryEntry& e : map.history(at(x, y, z))) {
          if (e.time_s > t) break;
          value = e.counters;
        }
        if (value) dense.add(at(x, y, z), *value);
      }
    }
  }
  dense.compressFree();
  return dense;
}

// Bit for bit: the same pools, leaf by leaf, in the same layout.
void expectSnapshotIsDenseCompressed(const TemporalMap& map, double t) {
  const SessionMap snap = map.snapshot(t);
  const SessionMap dense = denseSnapshot(map, t);
  const SessionMap::Pools a = snap.pools(), b = dense.pools();
  ASSERT_EQ(a.inner, b.inner) << "t=" << t;
  ASSERT_EQ(a.leaves.size(), b.leaves.size()) << "t=" << t;
  for (size_t i = 0; i < a.leaves.size(); ++i) ASSERT_EQ(a.leaves[i], b.leaves[i]) << "leaf " << i << " t=" << t;
}

// Every session time, and times between, before and after them.
void expectEverySnapshotMatches(const TemporalMap& map, const Reference& ref) {
  const std::vector<double> times = map.times();
  std::vector<double> probes{times.front() - 1.0, times.back() + 1.0};
  for (double t : times) {
    probes.push_back(t);
    probes.push_back(t + 1.0);
  }
  for (double t : probes) {
    expectSnapshotIsDenseCompressed(map, t);
    expectStatesMatch(map, ref, t);
  }
}

// A 16^3 cube of free voxels (each `length`), compressed, with an optional occupied voxel.
SessionMap freeCube(float length, std::optional<VoxelKey> occupied = std::nullopt) {
  SessionMap m(0.05);
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        const VoxelKey k = at(x, y, z);
        m.add(k, occupied && k == *occupied ? occupiedVoxelExact(3) : freeVoxel(length));
      }
    }
  }
  m.compressFree();
  return m;
}

TEST(TemporalMap, ACubeUniformAgainIsReadFromItsCoarseEntry) {
  TemporalMap map(0.05);
  map.add(sessionTime(0), freeCube(0.25f));
  // A box stands in a different place in each of the next sessions: the cube is refined to
  // unit voxels in several places.
  for (int i = 1; i <= 4; ++i) map.add(sessionTime(i), freeCube(0.25f, at(3 * i, 2 * i + 1, i)));
  map.add(sessionTime(5), freeCube(0.25f));  // all free again
  const size_t slots = map.counts().slots;
  ASSERT_GT(slots, 50u) << "the boxes refined the cube";

  TemporalMap::SnapshotVisits busy, clear;
  const SessionMap s4 = map.snapshot(sessionTime(4), &busy);
  const SessionMap s5 = map.snapshot(sessionTime(5), &clear);
  EXPECT_EQ(s4.stateOf(at(12, 9, 4)), VoxelState::Occupied);
  EXPECT_EQ(s4.stateOf(at(9, 7, 3)), VoxelState::Free);
  // At t4 only the eighths around t4's box are read list by list; where the earlier boxes
  // stood, the cubes read free again and come from their coarse entries.
  EXPECT_GT(busy.lists, 0u);
  EXPECT_LT(busy.lists, slots / 2);
  EXPECT_EQ(busy.coarse, 2u) << "the octants of the boxes at t1, t2 (one octant) and t3";
  // At t5 the whole 16^3 cube reads free: one coarse entry, no list, only the root path.
  EXPECT_EQ(clear.lists, 0u);
  EXPECT_EQ(clear.coarse, 1u);
  EXPECT_EQ(clear.inner, static_cast<size_t>(kTreeDepth - 4));
  ASSERT_EQ(s5.leafCount(), 1u);
  EXPECT_TRUE(s5 == freeCube(0.25f)) << "all lengths were equal: the cube as the session saw it";
  EXPECT_EQ(s5.stateOf(at(12, 9, 4)), VoxelState::Free);
  // Histories are as before: only changes, at the voxel.
  const auto h = map.history(at(12, 9, 4));
  ASSERT_EQ(h.size(), 3u);
  EXPECT_EQ(h[1].counters.state(), VoxelState::Occupied);
  EXPECT_EQ(h[2].time_s, sessionTime(5));
  EXPECT_EQ(h[2].counters.state(), VoxelState::Free);
  EXPECT_EQ(map.history(at(0, 0, 0)).size(), 1u);

  // A session inserted before t5 with another box: at its time the cube is not uniform; t5 and
  // later are still one coarse entry. Removing it again restores the coarse entry at its time.
  const double between = sessionTime(4) + 50.0;
  map.add(between, freeCube(0.25f, at(1, 1, 1)));
  EXPECT_EQ(map.snapshot(between).stateOf(at(1, 1, 1)), VoxelState::Occupied);
  EXPECT_EQ(map.snapshot(between).stateOf(at(12, 9, 4)), VoxelState::Free) << "t4's box is gone by then";
  map.snapshot(sessionTime(5), &clear);
  EXPECT_EQ(clear.coarse, 1u);
  EXPECT_EQ(clear.lists, 0u);
  map.remove(between);
  EXPECT_EQ(map.snapshot(sessionTime(4) + 60.0).stateOf(at(12, 9, 4)), VoxelState::Occupied)
      << "t4's box stands until t5 again";
  EXPECT_EQ(map.snapshot(sessionTime(5), &clear).leafCount(), 1u);
  EXPECT_EQ(clear.coarse, 1u);
  // Replacing t5 by a session with a box: no coarse entry at t5 any more.
  map.add(sessionTime(5), freeCube(0.25f, at(15, 15, 15)), AddSettings{true, ""});
  const SessionMap replaced = map.snapshot(sessionTime(5), &clear);
  EXPECT_GT(replaced.leafCount(), 1u);
  EXPECT_GT(clear.lists, 0u);
  EXPECT_EQ(replaced.stateOf(at(15, 15, 15)), VoxelState::Occupied);
  EXPECT_EQ(replaced.stateOf(at(12, 9, 4)), VoxelState::Free);
  for (int i = 0; i <= 5; ++i) expectSnapshotIsDenseCompressed(map, sessionTime(i));
}

TEST(TemporalMap, CoarseLengthsSumTheVoxelsValidThen) {
  // Voxels free with different lengths: the coarse leaf holds their sum (what compressFree()
  // makes of the expanded snapshot), and every voxel still reads free.
  TemporalMap map(0.05);
  map.add(sessionTime(0), freeCube(0.25f));
  map.add(sessionTime(1), freeCube(0.5f, at(5, 5, 5)));
  map.add(sessionTime(2), freeCube(0.125f));
  const SessionMap s2 = map.snapshot(sessionTime(2));
  ASSERT_EQ(s2.leafCount(), 1u);
  // 4095 voxels kept 0.25 (0.5 confirmed free: not a change), the one that changed back 0.125.
  EXPECT_EQ(s2.pools().leaves[0].length_m, 4095 * 0.25f + 0.125f);
  EXPECT_EQ(s2.stateOf(at(5, 5, 5)), VoxelState::Free);
  expectSnapshotIsDenseCompressed(map, sessionTime(2));
}

TEST_P(TemporalProperty, SnapshotsAtEveryTimeAreTheDenseModelInAnyOrder) {
  std::mt19937_64 rng(GetParam() + 3000);
  World world;
  world.init(rng);
  std::vector<SessionMap> sessions;
  const int n = 7 + static_cast<int>(rng() % 4);
  for (int i = 0; i < n; ++i) {
    // Often a quiet session: the world as it was, so cubes turn uniform again.
    if (rng() % 2 == 0) world.change(rng, 60);
    sessions.push_back(randomSession(rng, world));
  }
  std::vector<int> order(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) order[static_cast<size_t>(i)] = i;
  if (GetParam() % 3 != 0) std::shuffle(order.begin(), order.end(), rng);  // a third in time order
  TemporalMap map(0.05);
  Reference ref;
  for (int i : order) {
    map.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
    ref.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
    expectSnapshotIsDenseCompressed(map, sessionTime(i));
  }
  expectEverySnapshotMatches(map, ref);
  expectHistoriesMatch(map, ref, /*exact=*/GetParam() % 3 == 0);

  // Replace one session (with a changed world), remove another, add one more in the middle.
  replaceOneRemoveAnother(rng, world, n, map, ref);
  const SessionMap late = randomSession(rng, world);
  map.add(sessionTime(n / 2) + 30.0, late);
  ref.add(sessionTime(n / 2) + 30.0, late);
  expectEverySnapshotMatches(map, ref);
  expectHistoriesMatch(map, ref, /*exact=*/false);

  // Compaction and the parts round trip (what files hold) rebuild the same coarse entries.
  TemporalMap compacted = map;
  compacted.compact();
  const TemporalMap back = TemporalMap::fromParts(0.05, {}, compacted.parts(), compacted.sessions());
  for (double t : map.times()) {
    TemporalMap::SnapshotVisits va, vb;
    const SessionMap a = compacted.snapshot(t, &va), b = back.snapshot(t, &vb);
    ASSERT_EQ(a.innerPool(), b.innerPool());
    ASSERT_TRUE(a == b);
    EXPECT_EQ(va.inner, vb.inner);
    EXPECT_EQ(va.coarse, vb.coarse);
    expectSnapshotIsDenseCompressed(back, t);
  }
}


// Re-laying the pools out in memory (relayout(), and add() on its own) moves nodes, never answers.

void expectSameAnswers(const TemporalMap& a, const TemporalMap& b) {
  ASSERT_EQ(a.times(), b.times());
  std::vector<double> probes{a.times().front() - 1.0};
  for (double t : a.times()) {
    probes.push_back(t);
    probes.push_back(t + 1.0);
  }
  for (double t : probes) {
    TemporalMap::SnapshotVisits va, vb;
    const SessionMap sa = a.snapshot(t, &va), sb = b.snapshot(t, &vb);
    ASSERT_TRUE(test::samePools(sa, sb)) << "t=" << t;
    EXPECT_EQ(va.inner, vb.inner);
    EXPECT_EQ(va.lists, vb.lists);
    EXPECT_EQ(va.coarse, vb.coarse);
  }
  for (int z = 0; z < kMapSide; ++z) {
    for (int y = 0; y < kMapSide; ++y) {
      for (int x = 0; x < kMapSide; ++x) {
        const auto ha = a.history(at(x, y, z)), hb = b.history(at(x, y, z));
        ASSERT_EQ(ha.size(), hb.size());
        for (size_t i = 0; i < ha.size(); ++i) {
          ASSERT_EQ(ha[i].time_s, hb[i].time_s);
          ASSERT_EQ(ha[i].level, hb[i].level);
          ASSERT_EQ(ha[i].counters, hb[i].counters);
        }
      }
    }
  }
  auto changes = [](const TemporalMap& m, double t0, double t1) {
    std::vector<std::tuple<VoxelKey, int, uint32_t>> out;
    m.forEachChangeCount(t0, t1, [&](const VoxelKey& k, int level, uint32_t n) { out.emplace_back(k, level, n); });
    return out;
  };
  EXPECT_EQ(changes(a, 0, 1e9), changes(b, 0, 1e9));
  if (a.times().size() >= 2) {
    EXPECT_EQ(changes(a, a.times()[1], a.times().back()), changes(b, b.times()[1], b.times().back()));
  }
  EXPECT_TRUE(a == b);
  EXPECT_EQ(a.counts().nodes(), b.counts().nodes());
}

TEST_P(TemporalProperty, RelayoutChangesNoAnswer) {
  std::mt19937_64 rng(GetParam() + 4000);
  World world;
  world.init(rng);
  const int n = 8;
  std::vector<SessionMap> sessions;
  for (int i = 0; i < n; ++i) {
    if (rng() % 2 == 0) world.change(rng, 60);
    sessions.push_back(randomSession(rng, world));
  }
  std::vector<int> order(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) order[static_cast<size_t>(i)] = i;
  if (GetParam() % 2 != 0) std::shuffle(order.begin(), order.end(), rng);
  // `map` re-lays itself out when add() decides; `relaid` is re-laid out after every change.
  TemporalMap map(0.05), relaid(0.05);
  Reference ref;
  for (int i : order) {
    map.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
    relaid.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
    ref.add(sessionTime(i), sessions[static_cast<size_t>(i)]);
    relaid.relayout();
    TemporalMap copy = map;
    copy.relayout();
    expectSameAnswers(map, copy);
  }
  EXPECT_GT(map.relayouts(), 0u) << "add() re-laid the pools out on its own";
  EXPECT_GE(relaid.relayouts(), static_cast<size_t>(n));
  expectSameAnswers(map, relaid);
  // Later changes land in re-laid pools as in the others: replace one session, remove another.
  world.change(rng, 200);
  const SessionMap replacement = randomSession(rng, world);
  const int replaced = static_cast<int>(rng() % static_cast<uint64_t>(n)), removed = (replaced + 1) % n;
  for (TemporalMap* m : {&map, &relaid}) {
    m->add(sessionTime(replaced), replacement, AddSettings{true, ""});
    m->remove(sessionTime(removed));
  }
  ref.remove(sessionTime(replaced));
  ref.add(sessionTime(replaced), replacement);
  ref.remove(sessionTime(removed));
  relaid.relayout();
  expectSameAnswers(map, relaid);
  expectEverySnapshotMatches(relaid, ref);
}

// compact(Relayout::kWhenMerged), for a map about to be written: the same parts (what a file
// holds) and answers as compact(), re-laid out only when lists were merged.
TEST_P(TemporalProperty, CompactingWithoutARelayoutGivesTheSameParts) {
  std::mt19937_64 rng(GetParam() + 6000);
  World world;
  world.init(rng);
  TemporalMap map(0.05);
  size_t skipped = 0, merged = 0;
  for (int i = 0; i < 8; ++i) {
    if (rng() % 2 == 0) world.change(rng, 60);
    // Among random sessions, free space not compressed in the session map (a length per
    // voxel), which compaction merges where a cube's voxels share their sessions.
    SessionMap uneven(0.05);
    for (int z = 0; z < kMapSide; ++z) {
      for (int y = 0; y < kMapSide; ++y) {
        for (int x = 0; x < kMapSide; ++x) uneven.add(at(x, y, z), freeVoxel(0.1f + 0.01f * static_cast<float>(rng() % 8)));
      }
    }
    map.add(sessionTime(i), i % 3 == 0 ? uneven : randomSession(rng, world));
    TemporalMap relaid = map, kept = map;
    const size_t relayouts = kept.relayouts();
    const size_t removed = relaid.compact();
    ASSERT_EQ(kept.compact(TemporalMap::Relayout::kWhenMerged), removed);
    (removed == 0 ? skipped : merged) += 1;
    EXPECT_EQ(kept.relayouts(), relayouts + (removed == 0 ? 0 : 1));
    EXPECT_TRUE(kept.isCompact());
    const TemporalMap::Parts a = relaid.parts(), b = kept.parts();
    ASSERT_EQ(a.inner, b.inner) << "after session " << i;
    ASSERT_EQ(a.list_sizes, b.list_sizes);
    ASSERT_EQ(a.entries.size(), b.entries.size());
    for (size_t k = 0; k < a.entries.size(); ++k) {
      ASSERT_EQ(a.entries[k].session, b.entries[k].session);
      ASSERT_EQ(a.entries[k].value, b.entries[k].value);
    }
    expectSameAnswers(relaid, kept);
    map = std::move(kept);  // the next session lands in pools that were not re-laid out
  }
  EXPECT_GT(skipped, 0u);
  EXPECT_GT(merged, 0u);
}

TEST(TemporalMap, PartsInThePlainDepthFirstOrderReadTheSame) {
  // Files written before the two-layer order hold the pools plainly depth first: re-lay a map's
  // parts that way and read them back: the same map, the same snapshots bit for bit.
  std::mt19937_64 rng(11);
  World world;
  world.init(rng);
  TemporalMap map(0.05);
  for (int i = 0; i < 8; ++i) {
    if (i % 2 == 0) world.change(rng, 80);
    map.add(sessionTime(i), i % 3 == 2 ? freeCube(0.25f) : randomSession(rng, world));
  }
  map.compact();
  const TemporalMap::Parts layered = map.parts();
  TemporalMap::Parts plain;
  std::vector<uint64_t> offsets;
  uint64_t at_entry = 0;
  for (uint32_t n : layered.list_sizes) {
    offsets.push_back(at_entry);
    at_entry += n;
  }
  auto copy = [&](auto&& self, uint32_t node) -> void {
    const auto me = static_cast<uint32_t>(plain.inner.size());
    plain.inner.emplace_back();
    for (int slot = 0; slot < 8; ++slot) {
      const TemporalMap::Ref r = layered.inner[node][static_cast<size_t>(slot)];
      if (r == TemporalMap::kEmpty) {
        plain.inner[me][static_cast<size_t>(slot)] = r;
      } else if (r & TemporalMap::kListBit) {
        const uint32_t list = r & ~TemporalMap::kListBit;
        plain.inner[me][static_cast<size_t>(slot)] = static_cast<uint32_t>(plain.list_sizes.size()) | TemporalMap::kListBit;
        plain.list_sizes.push_back(layered.list_sizes[list]);
        for (uint32_t k = 0; k < layered.list_sizes[list]; ++k) plain.entries.push_back(layered.entries[offsets[list] + k]);
      } else {
        plain.inner[me][static_cast<size_t>(slot)] = static_cast<uint32_t>(plain.inner.size());
        self(self, r);
      }
    }
  };
  copy(copy, 0);
  ASSERT_FALSE(plain.inner == layered.inner) << "the map has shadowed subtrees, laid out last";
  const TemporalMap back = TemporalMap::fromParts(0.05, {}, plain, map.sessions());
  EXPECT_TRUE(back == map);
  for (double t : map.times()) {
    const SessionMap a = back.snapshot(t), b = map.snapshot(t);
    ASSERT_EQ(a.innerPool(), b.innerPool());
    ASSERT_TRUE(a == b);
  }
}

}  // namespace
}  // namespace chronomap

namespace chronomap {
namespace {

TEST(Coverage, KnowsWhichCubesASessionSaw) {
  SessionMap m(0.05);
  for (int z = 0; z < 4; ++z) {
    for (int y = 0; y < 4; ++y) {
      for (int x = 0; x < 4; ++x) m.add(at(x, y, z), freeVoxel(0.5f));
    }
  }
  m.add(at(9, 9, 9), occupiedVoxelExact(1));
  m.compressFree();
  const Coverage c(m);
  EXPECT_EQ(c.voxelCount(), 65u);
  const CoverageIndex index(c);
  EXPECT_EQ(index.overlap(at(0, 0, 0), 2), CoverageIndex::Overlap::Full);
  EXPECT_EQ(index.overlap(at(0, 0, 0), 3), CoverageIndex::Overlap::Partial);
  EXPECT_EQ(index.overlap(at(4, 0, 0), 2), CoverageIndex::Overlap::None);
  EXPECT_TRUE(index.contains(at(9, 9, 9)));
  EXPECT_FALSE(index.contains(at(9, 9, 8)));
  size_t pos = 0;
  EXPECT_TRUE(Coverage::decodeFrom(c.encoded(), pos) == c);
  EXPECT_EQ(pos, c.encoded().size());
  EXPECT_THROW(Coverage::fromRanges({5, 3}), FormatError);
  EXPECT_THROW(Coverage::fromRanges({0, 4, 4, 8}), FormatError) << "touching ranges are not canonical";
  std::vector<uint8_t> truncated(c.encoded().begin(), c.encoded().end() - 1);
  pos = 0;
  EXPECT_THROW(Coverage::decodeFrom(truncated, pos), FormatError);
}

/// The slow reference decode: the numbers read as they come (any length), the ranges rebuilt
/// and encoded again; accepted only when that encoding is the bytes read.
std::optional<Coverage> referenceDecode(const std::vector<uint8_t>& bytes) {
  size_t pos = 0;
  auto number = [&]() -> std::optional<uint64_t> {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (pos >= bytes.size()) return std::nullopt;
      const uint8_t b = bytes[pos++];
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) return v;
    }
    return std::nullopt;
  };
  const auto n = number();
  if (!n || *n > bytes.size()) return std::nullopt;
  std::vector<uint64_t> ranges;
  uint64_t end = 0;
  for (uint64_t i = 0; i < *n; ++i) {
    const auto gap = number(), length = number();
    if (!gap || !length || *gap > (uint64_t{1} << 60) || *length > (uint64_t{1} << 60)) return std::nullopt;
    ranges.push_back(end + *gap);
    ranges.push_back(end + *gap + *length);
    end = ranges.back();
  }
  try {
    Coverage c = Coverage::fromRanges(ranges);
    if (c.encoded() != std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(pos))) {
      return std::nullopt;
    }
    return c;
  } catch (const FormatError&) {
    return std::nullopt;
  }
}

TEST(Coverage, DecodeAcceptsExactlyTheCanonicalEncodings) {
  std::mt19937 random(7);
  for (int trial = 0; trial < 2000; ++trial) {
    // A valid encoding of random ranges, then (most trials) one byte changed, dropped or added.
    std::vector<uint64_t> ranges;
    uint64_t at_code = std::uniform_int_distribution<uint64_t>(0, 3)(random);
    const int count = std::uniform_int_distribution<int>(0, 6)(random);
    for (int i = 0; i < count; ++i) {
      at_code += std::uniform_int_distribution<uint64_t>(i == 0 ? 0 : 1, 300)(random);
      const uint64_t length = std::uniform_int_distribution<uint64_t>(1, 70000)(random);
      ranges.push_back(at_code);
      ranges.push_back(at_code + length);
      at_code += length;
    }
    std::vector<uint8_t> bytes = Coverage::fromRanges(ranges).encoded();
    const int edit = std::uniform_int_distribution<int>(0, 4)(random);
    const size_t where = std::uniform_int_distribution<size_t>(0, bytes.size() - 1)(random);
    const uint8_t value = static_cast<uint8_t>(std::uniform_int_distribution<int>(0, 255)(random));
    if (edit == 1) bytes[where] = value;
    if (edit == 2) bytes.erase(bytes.begin() + static_cast<std::ptrdiff_t>(where));
    if (edit == 3) bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(where), value);
    if (edit == 4) bytes[where] = static_cast<uint8_t>(bytes[where] | 0x80);
    const std::optional<Coverage> expected = referenceDecode(bytes);
    size_t pos = 0;
    std::optional<Coverage> got;
    try {
      got = Coverage::decodeFrom(bytes, pos);
    } catch (const FormatError&) {
    }
    ASSERT_EQ(got.has_value(), expected.has_value()) << "trial " << trial;
    if (got) {
      EXPECT_TRUE(*got == *expected) << "trial " << trial;
      EXPECT_EQ(got->voxelCount(), expected->voxelCount());
      EXPECT_EQ(pos, got->encoded().size());
    }
  }
}

// chronomap prints times to the millisecond; a printed time given back names its session, also
// when the session's own time lies a fraction of a millisecond after it (the demo's office:
// `diff MAP@T5 MAP@T6` with the printed times compared sessions 4 and 5).
TEST(TemporalMap, APrintedTimeNamesItsSession) {
  TemporalMap map(0.05);
  const double t1 = 1330601575.1434, t2 = 1330697774.3704;
  map.add(t1, test::randomSessionMap(1, 8, 0.2));
  map.add(t2, test::randomSessionMap(2, 8, 0.2));
  EXPECT_EQ(map.rankAtOrBefore(parseTime(formatTime(t1))), 0u);
  EXPECT_EQ(map.rankAtOrBefore(parseTime(formatTime(t2))), 1u);
  EXPECT_LT(parseTime(formatTime(t2)), t2);
  EXPECT_EQ(map.rankAtOrBefore(t2 - 0.002), 0u) << "two milliseconds before is before";
  EXPECT_FALSE(map.rankAtOrBefore(t1 - 0.002));
}

}  // namespace
}  // namespace chronomap
