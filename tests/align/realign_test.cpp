// Re-alignment (thesis §2.2): the score, hand-built cases with known answers, a dense reference on
// random maps, and bad input.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <span>
#include <vector>

#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/core/error.h"
#include "chronomap/temporal/temporal_map.h"
#include "builders.h"

using namespace chronomap;
using test::at;
using test::freeVoxel;
using test::occupiedVoxel;
using test::wallSession;

// ---------------------------------------------------------------------------------------------
// The score

TEST(RealignScore, MatchesItsFormula) {
  RealignSettings s;
  s.epsilon = 0.01;
  EXPECT_DOUBLE_EQ(realignScore(2.0, 0.5, 0.25, s), 1.0 / (2.0 * 0.5 * 0.25));
  s.weight_distance = 2.0;
  s.weight_probability = 0.0;
  EXPECT_DOUBLE_EQ(realignScore(2.0, 0.5, 0.25, s), 1.0 / (4.0 * 0.5));
  s.weight_colour = 3.0;
  EXPECT_DOUBLE_EQ(realignScore(1.5, 0.2, 0.9, s), 1.0 / (2.25 * 0.008));
  EXPECT_DOUBLE_EQ(colourDistance({0, 0, 0}, {255, 255, 255}), std::sqrt(3.0));
  EXPECT_DOUBLE_EQ(colourDistance({10, 20, 30}, {10, 20, 30}), 0.0);
  EXPECT_DOUBLE_EQ(colourDistance({0, 51, 0}, {0, 0, 0}), 0.2);
}

TEST(RealignScore, IsFiniteForIdenticalVoxelsAndZeroDistance) {
  RealignSettings s;
  s.epsilon = 0.01;
  EXPECT_DOUBLE_EQ(realignScore(1.0, 0.0, 0.0, s), 1.0 / (1.0 * 0.01 * 0.01));
  EXPECT_DOUBLE_EQ(realignScore(0.0, 0.0, 0.0, s), 1.0 / (0.01 * 0.01 * 0.01));
  const VoxelCounters v = occupiedVoxel({50, 60, 70});
  EXPECT_TRUE(std::isfinite(realignScore(v, v, 1.0, s)));
  EXPECT_DOUBLE_EQ(realignScore(v, v, 1.0, s), 1e4);
}

TEST(RealignSettings, RejectsBadValues) {
  auto bad = [](auto change) {
    RealignSettings s;
    change(s);
    return s;
  };
  EXPECT_THROW(bad([](auto& s) { s.alpha = -1; }).validate(), UsageError);
  EXPECT_THROW(bad([](auto& s) { s.alpha = std::nan(""); }).validate(), UsageError);
  EXPECT_THROW(bad([](auto& s) { s.epsilon = 0; }).validate(), UsageError);
  EXPECT_THROW(bad([](auto& s) { s.max_distance_voxels = 9; }).validate(), UsageError);
  EXPECT_THROW(bad([](auto& s) { s.weight_colour = -0.5; }).validate(), UsageError);
  EXPECT_THROW(bad([](auto& s) { s.consensus_occupied_above = 1.0; }).validate(), UsageError);
  EXPECT_THROW(bad([](auto& s) { s.consensus_occupied_above = 0.2; }).validate(), UsageError);
  EXPECT_NO_THROW(RealignSettings{}.validate());
  EXPECT_THROW(realign(SessionMap(0.05), SessionMap(0.1)), UsageError);
}

// ---------------------------------------------------------------------------------------------
// Re-alignment on hand-built maps

TEST(Realign, MovesASessionShiftedByOneVoxelBackCompletely) {
  for (auto move : {RealignSettings::Move::Transfer, RealignSettings::Move::Swap}) {
    std::vector<SessionMap> maps;
    for (int i = 0; i < 5; ++i) maps.push_back(wallSession(10));
    maps.push_back(wallSession(11));  // localisation error: one voxel too far
    const SessionMap avg = consensus(std::span<const SessionMap>(maps));
    RealignSettings settings;
    settings.move = move;
    RealignReport report;
    const SessionMap fixed = realign(maps.back(), avg, settings, &report);
    EXPECT_EQ(report.moved(), 256u);
    EXPECT_EQ(report.free_disagreeing, 256u);
    for (int z = 0; z < 16; ++z) {
      for (int y = 0; y < 16; ++y) {
        ASSERT_EQ(fixed.stateOf(at(10, y, z)), VoxelState::Occupied);
        EXPECT_EQ(*fixed.find(at(10, y, z)), *maps.back().find(at(11, y, z)));  // its own data, moved
        EXPECT_NE(fixed.stateOf(at(11, y, z)), VoxelState::Occupied);
      }
    }
    EXPECT_EQ(fixed.counts().occupied_voxels, 256u);
    // In the 4D map the re-aligned session is no change at all; as recorded, every wall voxel is.
    for (bool aligned : {false, true}) {
      TemporalMap map(0.05);
      map.add(1.0, maps[0]);
      map.add(2.0, aligned ? fixed : maps.back());
      size_t changes = 0;
      map.forEachChangeCount(1.0, 2.0, [&](const VoxelKey&, int, uint32_t n) { changes += n; });
      EXPECT_EQ(changes, aligned ? 0u : 256u) << (aligned ? "re-aligned" : "as recorded");
    }
  }
}

TEST(Realign, LeavesAnObjectSeenInOneSessionWhereItIs) {
  // Forty sessions see the wall at x = 10; the last also sees a red box right in front of it
  // (x = 9), hiding the wall behind. With a strict consensus the box is free there, and the
  // wall voxels one step away are candidates, but their colour differs.
  std::vector<SessionMap> maps(40, wallSession(10));
  SessionMap with_box = wallSession(10);
  for (int z = 4; z < 8; ++z) {
    for (int y = 4; y < 8; ++y) {
      with_box.assign(at(9, y, z), occupiedVoxel({255, 0, 0}));
      with_box.assign(at(10, y, z), std::nullopt);  // hidden behind the box
    }
  }
  maps.push_back(with_box);
  const SessionMap avg = consensus(std::span<const SessionMap>(maps));
  for (double strict : {0.5, 0.999}) {
    RealignSettings settings;
    settings.consensus_occupied_above = strict;
    RealignReport report;
    const SessionMap fixed = realign(with_box, avg, settings, &report);
    for (int z = 4; z < 8; ++z) {
      for (int y = 4; y < 8; ++y) EXPECT_EQ(*fixed.find(at(9, y, z)), *with_box.find(at(9, y, z)));
    }
    EXPECT_EQ(report.moved(), 0u) << strict;
    if (strict > 0.5) {
      EXPECT_EQ(report.occupied_disagreeing, 16u);  // seen as disagreeing, and kept
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The dense reference

namespace {

// Plain loops over a side^3 grid: the two passes exactly as documented.
struct DenseRealign {
  int side;
  std::vector<std::optional<VoxelCounters>> session, avg;
  std::vector<VoxelKey> keys;  // grid cells in Morton order

  DenseRealign(const SessionMap& m, const SessionMap& c, int side_) : side(side_) {
    for (int z = 0; z < side; ++z) {
      for (int y = 0; y < side; ++y) {
        for (int x = 0; x < side; ++x) keys.push_back(at(x, y, z));
      }
    }
    std::sort(keys.begin(), keys.end(), [](auto& a, auto& b) { return mortonEncode(a) < mortonEncode(b); });
    for (const VoxelKey& k : keys) {
      session.push_back(m.find(k));
      avg.push_back(c.find(k));
    }
  }
  VoxelState state(const std::optional<VoxelCounters>& c) const { return c ? c->state() : VoxelState::Unknown; }

  std::vector<RealignMove> moves(const RealignSettings& s) const {
    const size_t n = keys.size();
    std::vector<bool> used(n, false);
    auto distance = [&](size_t i, size_t j) {
      const double dx = keys[i].x - keys[j].x, dy = keys[i].y - keys[j].y, dz = keys[i].z - keys[j].z;
      return std::sqrt(dx * dx + dy * dy + dz * dz);
    };
    auto avg_occupied = [&](size_t i) { return avg[i] && s.consensusOccupied(*avg[i]); };
    std::vector<RealignMove> out;
    for (size_t i = 0; i < n; ++i) {  // pass 1
      if (state(session[i]) != VoxelState::Occupied || !avg[i] || avg_occupied(i)) continue;
      double best = -1.0;
      size_t best_j = n;
      for (size_t j = 0; j < n; ++j) {
        if (j == i || used[j] || !avg_occupied(j) || distance(i, j) > s.max_distance_voxels) continue;
        if (s.move == RealignSettings::Move::Swap && state(session[j]) == VoxelState::Occupied) continue;
        const double score = realignScore(*session[i], *avg[j], distance(i, j), s);
        if (score > best) best = score, best_j = j;
      }
      if (best_j < n && best > s.alpha) {
        out.push_back({keys[i], keys[best_j], best, true});
        used[i] = used[best_j] = true;
      }
    }
    for (size_t i = 0; i < n; ++i) {  // pass 2
      if (state(session[i]) != VoxelState::Free || !avg_occupied(i) || used[i]) continue;
      double best = -1.0;
      size_t best_j = n;
      for (size_t j = 0; j < n; ++j) {
        if (j == i || used[j] || state(session[j]) != VoxelState::Occupied || distance(i, j) > s.max_distance_voxels) {
          continue;
        }
        const double score = realignScore(*session[j], *avg[i], distance(i, j), s);
        if (score > best) best = score, best_j = j;
      }
      if (best_j < n && best > s.alpha) {
        out.push_back({keys[best_j], keys[i], best, false});
        used[i] = used[best_j] = true;
      }
    }
    return out;
  }

  // The session after the moves, cell by cell.
  std::vector<std::optional<VoxelCounters>> apply(const std::vector<RealignMove>& moves,
                                                  const RealignSettings& s) const {
    std::vector<std::optional<VoxelCounters>> out = session;
    auto index = [&](const VoxelKey& k) {
      return size_t(std::find(keys.begin(), keys.end(), k) - keys.begin());
    };
    for (const RealignMove& m : moves) {
      const size_t from = index(m.from), to = index(m.to);
      if (s.move == RealignSettings::Move::Swap) {
        out[to] = session[from];
        out[from] = session[to];
      } else {
        VoxelCounters moved = *session[from];
        if (state(session[to]) == VoxelState::Occupied) moved += *session[to];
        out[to] = moved;
        out[from].reset();
      }
    }
    return out;
  }
};

// A random map over side^3 voxels with colours from a small palette, so that ties and close
// matches happen.
SessionMap randomColouredMap(std::mt19937_64& rng, int side) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Rgb palette[] = {{200, 30, 30}, {205, 30, 30}, {30, 200, 30}, {30, 30, 200}};
  SessionMap m(0.05);
  for (int z = 0; z < side; ++z) {
    for (int y = 0; y < side; ++y) {
      for (int x = 0; x < side; ++x) {
        const double r = u(rng);
        if (r < 0.25) continue;
        if (r < 0.55) {
          m.add(at(x, y, z), occupiedVoxel(palette[rng() % 4], 1 + static_cast<uint32_t>(rng() % 6)));
        } else {
          m.add(at(x, y, z), freeVoxel(0.05f * static_cast<float>(1 + rng() % 4)));
        }
      }
    }
  }
  m.compressFree();
  return m;
}

}  // namespace

TEST(Realign, EqualsTheDenseReferenceOnRandomMaps) {
  std::mt19937_64 rng(7);
  const int side = 6;
  size_t total_moves = 0, transfer_moves = 0;
  for (int trial = 0; trial < 120; ++trial) {
    std::vector<SessionMap> maps;
    for (int i = 0; i < 3; ++i) maps.push_back(randomColouredMap(rng, side));
    const SessionMap avg = consensus(std::span<const SessionMap>(maps));
    RealignSettings s;
    s.move = trial % 2 ? RealignSettings::Move::Swap : RealignSettings::Move::Transfer;
    s.alpha = std::vector<double>{0.0, 20.0, 300.0}[trial % 3];
    s.max_distance_voxels = std::vector<double>{1.0, 1.75, 2.0, 3.0}[(trial / 3) % 4];
    s.consensus_occupied_above = trial % 5 == 0 ? 0.99 : 0.5;
    s.weight_colour = trial % 7 == 0 ? 2.0 : 1.0;
    RealignReport report;
    const SessionMap fixed = realign(maps[0], avg, s, &report);
    const DenseRealign dense(maps[0], avg, side);
    const std::vector<RealignMove> expected = dense.moves(s);
    ASSERT_EQ(report.moves, expected) << "trial " << trial;
    total_moves += expected.size();
    if (s.move == RealignSettings::Move::Transfer) transfer_moves += expected.size();
    // Voxels with hits carry exactly the expected counters; free space may have been compressed
    // again (a compressed node reads as its even share), so its total length is compared.
    const auto cells = dense.apply(expected, s);
    double free_got = 0.0, free_expected = 0.0;
    for (size_t i = 0; i < dense.keys.size(); ++i) {
      const auto got = fixed.find(dense.keys[i]);
      ASSERT_EQ(dense.state(got), dense.state(cells[i])) << "trial " << trial << " cell " << i;
      if (got && got->hits > 0) {
        EXPECT_EQ(*got, *cells[i]);
      } else if (got) {
        free_got += got->length_m;
        free_expected += cells[i]->length_m;
      }
    }
    EXPECT_NEAR(free_got, free_expected, 1e-4 * free_expected);
  }
  EXPECT_GT(total_moves, 500u);  // the property was exercised
  EXPECT_GT(transfer_moves, 200u);
}
