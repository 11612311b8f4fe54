// Long runs: hundreds of small sessions appended to one 4D map. Memory must grow with the
// changes stored (plus a small record per session), and every snapshot must stay correct.

#include <gtest/gtest.h>

#include <random>

#include "chronomap/temporal/temporal_map.h"

namespace chronomap {
namespace {

constexpr int kSoakSide = 16;
constexpr uint16_t kSoakBase = 32768;

VoxelKey soakKey(int i) {
  return {static_cast<uint16_t>(kSoakBase + i % kSoakSide), static_cast<uint16_t>(kSoakBase + (i / kSoakSide) % kSoakSide),
          static_cast<uint16_t>(kSoakBase + i / (kSoakSide * kSoakSide))};
}

SessionMap observe(const std::vector<uint8_t>& world) {
  SessionMap m(0.05);
  std::vector<VoxelKey> keys;
  std::vector<VoxelCounters> values;
  for (int i = 0; i < kSoakSide * kSoakSide * kSoakSide; ++i) {
    VoxelCounters c;
    c.length_m = 0.125f;
    if (world[static_cast<size_t>(i)]) c.hits = 2;
    keys.push_back(soakKey(i));
    values.push_back(c);
  }
  m.addMany(keys, values);
  m.compressFree();
  return m;
}

TEST(TemporalSoak, HundredsOfSessionsGrowWithTheChangesOnly) {
  std::mt19937_64 rng(11);
  const int n = kSoakSide * kSoakSide * kSoakSide;
  std::vector<uint8_t> world(static_cast<size_t>(n), 0);
  for (auto& w : world) w = rng() % 20 == 0;
  TemporalMap map(0.05);
  std::vector<std::vector<uint8_t>> states;  // the world as observed after each session
  const int sessions = 400;
  const int flips = 25;
  size_t bytes_after_warmup = 0, entries_after_warmup = 0;
  for (int s = 0; s < sessions; ++s) {
    // Every fourth session nothing changes; otherwise `flips` voxels change state.
    if (s > 0 && s % 4 != 0) {
      for (int k = 0; k < flips; ++k) world[rng() % world.size()] ^= 1;
    }
    map.add(100.0 * s, observe(world));
    states.push_back(world);
    if (s == 9) {
      bytes_after_warmup = map.memoryBytes();
      entries_after_warmup = map.counts().entries;
    }
    // The latest snapshot is the world as it is.
    if (s % 50 == 0 || s == sessions - 1) {
      const SessionMap snap = map.snapshot(100.0 * s);
      for (int i = 0; i < n; ++i) {
        ASSERT_EQ(snap.stateOf(soakKey(i)) == VoxelState::Occupied, world[static_cast<size_t>(i)] != 0) << s << " " << i;
      }
    }
  }
  // Every past snapshot, spot-checked at 40 times, is still the world of its time.
  for (int check = 0; check < 40; ++check) {
    const int s = static_cast<int>(rng() % sessions);
    const SessionMap snap = map.snapshot(100.0 * s + 50.0);
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(snap.stateOf(soakKey(i)) == VoxelState::Occupied, states[static_cast<size_t>(s)][static_cast<size_t>(i)] != 0);
    }
  }
  const size_t entries = map.counts().entries - entries_after_warmup;
  const size_t bytes = map.memoryBytes() - bytes_after_warmup;
  const double per_change = static_cast<double>(bytes) / static_cast<double>(entries);
  std::cout << sessions << " sessions: " << map.counts().nodes() << " nodes, " << map.memoryBytes() << " bytes; after "
            << "the first 10: " << entries << " entries stored in " << bytes << " bytes (" << per_change
            << " per change, per-session records included)\n";
  // About 25 changes per changing session; a change costs an entry (24 bytes, in a list block
  // that may be half empty) plus refinement of compressed cubes around it.
  EXPECT_LT(per_change, 200.0);
  EXPECT_GT(entries, static_cast<size_t>(0.5 * flips * (sessions - 10) * 3 / 4));

  // Sessions that change nothing cost only their record (time, counts, coverage).
  const size_t before = map.memoryBytes(), nodes_before = map.counts().nodes();
  for (int s = sessions; s < sessions + 100; ++s) map.add(100.0 * s, observe(world));
  EXPECT_EQ(map.counts().nodes(), nodes_before);
  const double per_session = static_cast<double>(map.memoryBytes() - before) / 100.0;
  std::cout << "100 sessions without change: " << per_session << " bytes each\n";
  EXPECT_LT(per_session, 256.0);
}

}  // namespace
}  // namespace chronomap
