// Consensus maps and re-alignment (thesis §2.2): hand-built cases with known answers, a dense
// reference on random maps, and bad input.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/align/register.h"
#include "chronomap/core/error.h"
#include "chronomap/temporal/temporal_map.h"
#include "test_support.h"

using namespace chronomap;

namespace {

VoxelKey at(int x, int y, int z) {
  return VoxelKey{static_cast<uint16_t>(kKeyOrigin + x), static_cast<uint16_t>(kKeyOrigin + y),
                  static_cast<uint16_t>(kKeyOrigin + z)};
}

VoxelCounters freeVoxel(float length = 0.05f) {
  VoxelCounters c;
  c.length_m = length;
  return c;
}

VoxelCounters occupiedVoxel(Rgb color, uint32_t hits = 10) {
  VoxelCounters c;
  c.length_m = 0.025f * static_cast<float>(hits);
  c.hits = hits;
  c.red = color.r * hits;
  c.green = color.g * hits;
  c.blue = color.b * hits;
  return c;
}

// A 16 x 16 wall in the plane x = wall_x, seen from -x: free voxels x = 4 .. wall_x - 1, the wall
// occupied with a colour per (y, z); nothing behind it.
Rgb wallColor(int y, int z) {
  return Rgb{static_cast<uint8_t>(16 * y), static_cast<uint8_t>(16 * z), 128};
}

SessionMap wallSession(int wall_x) {
  SessionMap m(0.05);
  for (int z = 0; z < 16; ++z) {
    for (int y = 0; y < 16; ++y) {
      for (int x = 4; x < wall_x; ++x) m.add(at(x, y, z), freeVoxel());
      m.add(at(wall_x, y, z), occupiedVoxel(wallColor(y, z)));
    }
  }
  return m;
}

bool nearlyEqual(const VoxelCounters& a, const VoxelCounters& b) {
  return std::abs(a.length_m - b.length_m) <= 1e-5f * std::max(1.0f, std::abs(a.length_m)) && a.hits == b.hits &&
         a.red == b.red && a.green == b.green && a.blue == b.blue;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// SessionMap building blocks

TEST(SessionMapMerge, SumsCountersAndSpreadsCompressedNodesEvenly) {
  SessionMap coarse(0.05), fine(0.05);
  coarse.addCube(at(0, 0, 0), 2, freeVoxel(6.4f));  // 64 voxels, 0.1 m each
  fine.add(at(1, 2, 3), occupiedVoxel({10, 20, 30}, 4));
  fine.add(at(5, 0, 0), freeVoxel(0.5f));  // outside the cube
  SessionMap sum = coarse;
  sum.merge(fine);
  for (int z = 0; z < 4; ++z) {
    for (int y = 0; y < 4; ++y) {
      for (int x = 0; x < 4; ++x) {
        VoxelCounters expected = freeVoxel(0.1f);
        if (x == 1 && y == 2 && z == 3) expected += occupiedVoxel({10, 20, 30}, 4);
        ASSERT_TRUE(sum.find(at(x, y, z)));
        EXPECT_TRUE(nearlyEqual(*sum.find(at(x, y, z)), expected)) << x << y << z;
      }
    }
  }
  EXPECT_EQ(sum.find(at(5, 0, 0))->length_m, 0.5f);
  EXPECT_FALSE(sum.find(at(6, 0, 0)));
  // The other way round gives the same voxels.
  SessionMap other = fine;
  other.merge(coarse);
  for (int x = 0; x < 6; ++x) EXPECT_TRUE(nearlyEqual(*sum.find(at(x, 0, 0)), *other.find(at(x, 0, 0))));
}

TEST(SessionMapMerge, MergingAMapIntoItselfDoublesIt) {
  SessionMap m = test::randomSessionMap(3, 8);
  const SessionMap before = m;
  m.merge(m);
  before.forEachLeaf([&](const LeafView& l) {
    VoxelCounters twice = l.counters;
    twice += l.counters;
    const auto leaf = m.findLeaf(l.key);
    ASSERT_TRUE(leaf);
    EXPECT_EQ(leaf->level, l.level);
    EXPECT_EQ(leaf->counters, twice);
  });
}

TEST(SessionMapAssign, SetsAndForgetsVoxelsInsideCompressedNodes) {
  SessionMap m(0.05);
  m.addCube(at(0, 0, 0), 3, freeVoxel(51.2f));  // 512 voxels of 0.1 m
  m.assign(at(3, 3, 3), occupiedVoxel({1, 2, 3}));
  m.assign(at(4, 4, 4), std::nullopt);
  EXPECT_EQ(m.stateOf(at(3, 3, 3)), VoxelState::Occupied);
  EXPECT_EQ(m.stateOf(at(4, 4, 4)), VoxelState::Unknown);
  EXPECT_FLOAT_EQ(m.find(at(0, 0, 0))->length_m, 0.1f);
  EXPECT_FLOAT_EQ(m.find(at(7, 7, 7))->length_m, 0.1f);
  const SessionMapCounts c = m.counts();
  EXPECT_EQ(c.occupied_voxels, 1u);
  EXPECT_EQ(c.free_voxels, 510u);
  // Forgetting the only voxel of a branch leaves no empty inner nodes after compression.
  SessionMap single(0.05);
  single.add(at(9, 9, 9), occupiedVoxel({1, 1, 1}));
  single.assign(at(9, 9, 9), std::nullopt);
  single.compressFree();
  EXPECT_EQ(single.innerCount(), 1u);
  EXPECT_EQ(single.leafCount(), 0u);
}

TEST(SessionMapAddCube, RejectsBadCubes) {
  SessionMap m(0.05);
  EXPECT_THROW(m.addCube(at(1, 0, 0), 1, freeVoxel()), UsageError);  // not aligned
  EXPECT_THROW(m.addCube(at(0, 0, 0), kTreeDepth, freeVoxel()), UsageError);
  EXPECT_THROW(m.addCube(at(0, 0, 0), 2, occupiedVoxel({1, 1, 1})), UsageError);  // hits above unit level
  m.addCube(at(0, 0, 0), 2, VoxelCounters{});  // an unobserved cube adds nothing
  EXPECT_TRUE(m.empty());
}

// ---------------------------------------------------------------------------------------------
// Consensus

TEST(Consensus, IsTheSumOfWhatEveryMapReports) {
  std::vector<SessionMap> maps;
  for (uint64_t seed = 1; seed <= 4; ++seed) maps.push_back(test::randomSessionMap(seed, 12, 0.2));
  const SessionMap avg = consensus(std::span<const SessionMap>(maps));
  for (int z = -1; z < 13; ++z) {
    for (int y = -1; y < 13; ++y) {
      for (int x = -1; x < 13; ++x) {
        std::optional<VoxelCounters> expected;
        for (const auto& m : maps) {
          if (const auto c = m.find(at(x, y, z))) {
            if (!expected) expected = VoxelCounters{};
            *expected += *c;
          }
        }
        const auto got = avg.find(at(x, y, z));
        ASSERT_EQ(got.has_value(), expected.has_value());
        if (got) {
          EXPECT_TRUE(nearlyEqual(*got, *expected));
        }
      }
    }
  }
}

TEST(Consensus, OfA4DMapIsTheSumOfItsSnapshotsAtTheSessionTimes) {
  std::vector<SessionMap> maps;
  for (uint64_t seed = 10; seed < 16; ++seed) maps.push_back(test::randomSessionMap(seed, 10, 0.3));
  TemporalMap map(0.05);
  for (size_t i = 0; i < maps.size(); ++i) map.add(100.0 * static_cast<double>(i + 1), maps[i]);
  for (auto [t0, t1] : {std::pair{100.0, 600.0}, {150.0, 450.0}, {300.0, 300.0}, {0.0, 1e9}}) {
    std::vector<SessionMap> snapshots;
    for (double t : map.times()) {
      if (t >= t0 && t <= t1) snapshots.push_back(map.snapshot(t));
    }
    const SessionMap got = consensus(map, t0, t1);
    const SessionMap expected = consensus(std::span<const SessionMap>(snapshots));
    for (int z = 0; z < 10; ++z) {
      for (int y = 0; y < 10; ++y) {
        for (int x = 0; x < 10; ++x) {
          const auto a = got.find(at(x, y, z)), b = expected.find(at(x, y, z));
          ASSERT_EQ(a.has_value(), b.has_value()) << t0 << " " << t1;
          if (a) {
            EXPECT_TRUE(nearlyEqual(*a, *b)) << x << y << z;
          }
        }
      }
    }
  }
  EXPECT_TRUE(consensus(map, 700.0, 800.0).empty());
}

TEST(Consensus, RejectsBadInput) {
  EXPECT_THROW(consensus(std::span<const SessionMap>()), UsageError);
  std::vector<SessionMap> mixed;
  mixed.emplace_back(0.05);
  mixed.emplace_back(0.1);
  EXPECT_THROW(consensus(std::span<const SessionMap>(mixed)), UsageError);
  const SessionMap* none[] = {nullptr};
  EXPECT_THROW(consensus(std::span<const SessionMap* const>(none)), UsageError);
  TemporalMap map(0.05);
  EXPECT_THROW(consensus(map, 2.0, 1.0), UsageError);
  EXPECT_THROW(consensus(map, std::nan(""), 1.0), UsageError);
}

// ---------------------------------------------------------------------------------------------
// The score

TEST(RealignScore, MatchesItsFormula) {
  RealignSettings s;
  s.epsilon = 0.01;
  EXPECT_DOUBLE_EQ(realignScore(2.0, 0.5, 0.25, s), 1.0 / (2.0 * 0.5 * 0.25));
  s.weight_distance = 2.0;
  s.weight_probability = 0.0;
  EXPECT_DOUBLE_EQ(realignScore(2.0, 0.5, 0.25, s), 1.0 / (4.0 * 0.5));
  s.weight_color = 3.0;
  EXPECT_DOUBLE_EQ(realignScore(1.5, 0.2, 0.9, s), 1.0 / (2.25 * 0.008));
  EXPECT_DOUBLE_EQ(colorDistance({0, 0, 0}, {255, 255, 255}), std::sqrt(3.0));
  EXPECT_DOUBLE_EQ(colorDistance({10, 20, 30}, {10, 20, 30}), 0.0);
  EXPECT_DOUBLE_EQ(colorDistance({0, 51, 0}, {0, 0, 0}), 0.2);
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
  EXPECT_THROW(bad([](auto& s) { s.weight_color = -0.5; }).validate(), UsageError);
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
SessionMap randomColoredMap(std::mt19937_64& rng, int side) {
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
    for (int i = 0; i < 3; ++i) maps.push_back(randomColoredMap(rng, side));
    const SessionMap avg = consensus(std::span<const SessionMap>(maps));
    RealignSettings s;
    s.move = trial % 2 ? RealignSettings::Move::Swap : RealignSettings::Move::Transfer;
    s.alpha = std::vector<double>{0.0, 20.0, 300.0}[trial % 3];
    s.max_distance_voxels = std::vector<double>{1.0, 1.75, 2.0, 3.0}[(trial / 3) % 4];
    s.consensus_occupied_above = trial % 5 == 0 ? 0.99 : 0.5;
    s.weight_color = trial % 7 == 0 ? 2.0 : 1.0;
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

// ---------------------------------------------------------------------------------------------
// Registration to the consensus

namespace {

// A closed room (floor z = 0, four walls 1 m high, 2 x 2 m inside) sampled every 1 cm and moved
// by `t`: occupied voxels where the points fall.
SessionMap room(const Eigen::Isometry3d& t) {
  SessionMap m(0.05);
  const KeyGrid& g = m.grid();
  auto hit = [&](double x, double y, double z) {
    if (const auto k = g.keyOf(t * Eigen::Vector3d(x, y, z))) m.add(*k, occupiedVoxel({100, 100, 100}, 1));
  };
  for (double a = 0.005; a < 2.0; a += 0.01) {
    for (double b = 0.005; b < 2.0; b += 0.01) hit(a, b, 0.0126);
    for (double z = 0.005; z < 1.0; z += 0.01) {
      hit(0.0126, a, z);
      hit(2.0126, a, z);
      hit(a, 0.0126, z);
      hit(a, 2.0126, z);
    }
  }
  return m;
}

}  // namespace

TEST(RegisterToConsensus, FindsAShiftOfOneVoxel) {
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0.05, -0.05, 0.0);
  const SessionMap truth = room(Eigen::Isometry3d::Identity());
  const SessionMap shifted = room(shift);
  for (bool yaw_only : {true, false}) {
    RegisterSettings settings;
    settings.yaw_only = yaw_only;
    RegisterReport report;
    const Eigen::Isometry3d t = registerToConsensus(shifted, truth, settings, &report);
    EXPECT_NEAR(t.translation().x(), -0.05, 0.006) << yaw_only;
    EXPECT_NEAR(t.translation().y(), 0.05, 0.006);
    EXPECT_NEAR(t.translation().z(), 0.0, 0.006);
    EXPECT_LT(Eigen::AngleAxisd(t.linear()).angle(), 0.01);
    EXPECT_GT(report.points, 1000u);
    EXPECT_GT(report.mean_shift_before_m, 0.03);
    EXPECT_LT(report.mean_shift_after_m, 0.01);
  }
  // Planar: x, y and heading only. A shift with a vertical part: the horizontal part is found,
  // the vertical one left exactly as it is.
  Eigen::Isometry3d up = shift;
  up.translation().z() = 0.05;
  RegisterSettings planar;
  planar.planar = true;
  const Eigen::Isometry3d tp = registerToConsensus(room(up), truth, planar);
  EXPECT_NEAR(tp.translation().x(), -0.05, 0.006);
  EXPECT_NEAR(tp.translation().y(), 0.05, 0.006);
  EXPECT_NEAR(tp.translation().z(), 0.0, 1e-9);
  EXPECT_LT(Eigen::AngleAxisd(tp.linear()).angle(), 0.01);
  EXPECT_NEAR(registerToConsensus(room(up), truth).translation().z(), -0.05, 0.006);  // not planar: found
  // The same map needs no correction; nothing in reach gives the identity.
  EXPECT_LT(registerToConsensus(truth, truth).translation().norm(), 1e-9);
  SessionMap far_away(0.05);
  far_away.add(at(500, 500, 500), occupiedVoxel({1, 1, 1}));
  EXPECT_TRUE(registerToConsensus(far_away, truth).isApprox(Eigen::Isometry3d::Identity()));
}

TEST(RegisterToConsensus, RejectsBadSettings) {
  RegisterSettings s;
  s.radius_voxels = 0.5;
  EXPECT_THROW(s.validate(), UsageError);
  s = {};
  s.max_iterations = 0;
  EXPECT_THROW(s.validate(), UsageError);
  s = {};
  s.min_step_m = std::nan("");
  EXPECT_THROW(s.validate(), UsageError);
  EXPECT_THROW(registerToConsensus(SessionMap(0.05), SessionMap(0.1)), UsageError);
}

TEST(RegisterSessions, BringsTheOddSessionToTheOthersAndReintegratesIt) {
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0.05, 0.0, 0.0);
  const std::vector<Eigen::Isometry3d> poses = {Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(),
                                                Eigen::Isometry3d::Identity(), shift};
  std::vector<SessionMap> sessions;
  for (const auto& p : poses) sessions.push_back(room(p));
  std::atomic<size_t> calls = 0;  // sessions are integrated again in parallel
  std::vector<RegisterReport> reports;
  const auto corrections = registerSessions(
      sessions,
      [&](size_t k, const PoseCorrection& c) {
        ++calls;
        EXPECT_EQ(c.model, CorrectionModel::World);
        return room(c.motion * poses[k]);
      },
      3, {}, &reports);
  EXPECT_EQ(calls, 3 * poses.size());
  ASSERT_EQ(corrections.size(), poses.size());
  // Any correction that puts the shifted walls back into the others' voxels is exact at this
  // resolution: x in (-0.0626, -0.0126) m.
  EXPECT_GT(corrections[3].motion.translation().x(), -0.0626);
  EXPECT_LT(corrections[3].motion.translation().x(), -0.0126);
  EXPECT_EQ(sessions[3], sessions[0]);
  for (size_t k = 0; k < 3; ++k) EXPECT_LT(corrections[k].motion.translation().norm(), 0.02);
  EXPECT_EQ(sessions[3], room(corrections[3].motion * shift));  // the re-integrated map replaced it
  EXPECT_GT(reports[3].mean_shift_before_m, reports[3].mean_shift_after_m);
  std::vector<SessionMap> none;
  EXPECT_THROW(registerSessions(none, {}, 1), UsageError);
  EXPECT_THROW(registerSessions(sessions, {}, 0), UsageError);
  RegisterSettings per_pose;
  per_pose.model = CorrectionModel::PerPose;
  EXPECT_THROW(registerSessions(sessions, {}, 1, per_pose), UsageError);  // no sensor positions
}

namespace {

// A hall 20 x 4 m (walls 1 m high, pillars of 0.3 m every 4 m along both long walls) seen from
// sensors every 0.5 m along its middle, each seeing the surfaces within 3 m. With a per-pose
// error every sensor sees its surroundings turned by `yaw` about itself and moved by `offset`,
// as a robot that localises with a heading and position offset does.
struct Hall {
  std::vector<Eigen::Vector3d> surface;  // samples every 2 cm
  std::vector<Eigen::Vector3d> sensors;  // true positions
  Hall() {
    auto box = [&](double x0, double y0, double x1, double y1) {
      for (double z = 0.01; z < 1.0; z += 0.02) {
        for (double x = x0; x <= x1; x += 0.02) {
          surface.emplace_back(x, y0, z);
          surface.emplace_back(x, y1, z);
        }
        for (double y = y0; y <= y1; y += 0.02) {
          surface.emplace_back(x0, y, z);
          surface.emplace_back(x1, y, z);
        }
      }
    };
    box(0.0, 0.0, 20.0, 4.0);
    for (double x = 2.0; x < 20.0; x += 4.0) {
      box(x, 0.0, x + 0.3, 0.3);
      box(x + 1.0, 3.7, x + 1.3, 4.0);
    }
    for (double x = 0.01; x < 20.0; x += 0.02) {
      for (double y = 0.01; y < 4.0; y += 0.02) surface.emplace_back(x, y, 0.0);
    }
    for (double x = 1.0; x <= 19.0; x += 0.5) sensors.emplace_back(x, 2.0, 0.5);
  }
  SessionMap seen(double yaw, const Eigen::Vector3d& offset) const {
    SessionMap m(0.05);
    const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (const Eigen::Vector3d& c : sensors) {
      for (const Eigen::Vector3d& p : surface) {
        if ((p - c).squaredNorm() > 9.0) continue;
        if (const auto k = m.grid().keyOf(c + offset + r * (p - c))) m.add(*k, occupiedVoxel({100, 100, 100}, 1));
      }
    }
    return m;
  }
  std::vector<Eigen::Vector3d> estimatedSensors(const Eigen::Vector3d& offset) const {
    std::vector<Eigen::Vector3d> out = sensors;
    for (auto& c : out) c += offset;
    return out;
  }
};

}  // namespace

TEST(RegisterToConsensus, PerPoseFindsAHeadingOffsetThatNoRigidMotionUndoes) {
  const Hall hall;
  const double yaw = 0.5 * std::numbers::pi / 180.0;  // 0.5 degrees: 8.7 cm at 10 m from a pivot
  const Eigen::Vector3d offset(0.04, -0.03, 0.0);
  const SessionMap truth = hall.seen(0.0, Eigen::Vector3d::Zero());
  const SessionMap session = hall.seen(yaw, offset);
  const std::vector<Eigen::Vector3d> believed = hall.estimatedSensors(offset);
  RegisterSettings settings;
  settings.max_points = 5000;  // enough for 3 degrees of freedom; keeps the sanitizer runs short
  settings.model = CorrectionModel::PerPose;
  RegisterReport per_pose;
  const Eigen::Isometry3d t = registerToConsensus(session, truth, settings, &per_pose, believed);
  // The correction turns every pose back by the heading error and moves it back by the offset,
  // the latter to within the voxels' quantisation: the walls lie on voxel boundaries, so every
  // shift that puts them back into the truth's voxels fits (y in [0.03, 0.08) here).
  const Eigen::AngleAxisd turn(t.linear());
  const double per_pose_yaw = turn.angle() * (turn.axis().z() < 0 ? -1.0 : 1.0);
  EXPECT_NEAR(per_pose_yaw, -yaw, 0.1 * std::numbers::pi / 180.0);
  EXPECT_NEAR(t.translation().x(), -offset.x(), 0.05);
  EXPECT_GE(t.translation().y(), 0.03 - 1e-9);
  EXPECT_LT(t.translation().y(), 0.08);
  EXPECT_NEAR(t.translation().z(), 0.0, 0.01);
  EXPECT_LT(per_pose.mean_shift_after_m, 0.5 * per_pose.mean_shift_before_m);
  // Corrected that way, the session's sensors see the truth's voxels again.
  const PoseCorrection c{t, CorrectionModel::PerPose};
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = believed[10];
  const Eigen::Isometry3d fixed = c.apply(pose);
  EXPECT_LT((fixed.translation() - hall.sensors[10]).norm(), 0.05);
  EXPECT_LT(Eigen::AngleAxisd(fixed.linear()).angle(), 0.1 * std::numbers::pi / 180.0);
  // One rigid motion of the whole session cannot turn the sensors back: turning the hall about
  // one point would move its far end by 8 cm, so the World fit keeps the heading error (and
  // with it the sensors' surroundings turned by up to 2.6 cm at 3 m) and fits worse.
  settings.model = CorrectionModel::World;
  RegisterReport world;
  const Eigen::Isometry3d tw = registerToConsensus(session, truth, settings, &world);
  EXPECT_LT(Eigen::AngleAxisd(tw.linear()).angle(), 0.25 * yaw);
  EXPECT_GT(world.mean_shift_after_m, per_pose.mean_shift_after_m);
  // PerPose needs the positions; they must be finite.
  settings.model = CorrectionModel::PerPose;
  EXPECT_THROW(registerToConsensus(session, truth, settings), UsageError);
  std::vector<Eigen::Vector3d> bad = believed;
  bad[3].x() = std::nan("");
  EXPECT_THROW(registerToConsensus(session, truth, settings, nullptr, bad), UsageError);
}

TEST(PoseCorrection, ComposesAndAppliesPerModel) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(10.0, 0.0, 0.5);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  m.translation() = Eigen::Vector3d(1.0, 2.0, 0.0);
  // World: the map frame turns about its origin, so the sensor moves from (10, 0) to (1, 12).
  const Eigen::Isometry3d w = PoseCorrection{m, CorrectionModel::World}.apply(pose);
  EXPECT_TRUE(w.translation().isApprox(Eigen::Vector3d(1.0, 12.0, 0.5)));
  // Per pose: the sensor turns in place and moves by the translation.
  const Eigen::Isometry3d p = PoseCorrection{m, CorrectionModel::PerPose}.apply(pose);
  EXPECT_TRUE(p.translation().isApprox(Eigen::Vector3d(11.0, 2.0, 0.5)));
  EXPECT_TRUE(p.linear().isApprox(m.linear()));
  // Composition equals applying one after the other, for both models.
  Eigen::Isometry3d m2 = Eigen::Isometry3d::Identity();
  m2.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  m2.translation() = Eigen::Vector3d(-0.5, 0.25, 2.0);
  for (CorrectionModel model : {CorrectionModel::World, CorrectionModel::PerPose}) {
    const PoseCorrection a{m, model}, b{m2, model};
    EXPECT_TRUE(a.then(b).apply(pose).isApprox(b.apply(a.apply(pose)), 1e-12));
  }
  EXPECT_THROW((PoseCorrection{m, CorrectionModel::World}.then(PoseCorrection{m2, CorrectionModel::PerPose})),
               UsageError);
  EXPECT_TRUE(PoseCorrection{}.isIdentity());
}

namespace {

// The hall, turned by 7 degrees against the voxel grid (so that its walls cross the voxels at
// every fraction and the maps show shifts smaller than a voxel), seen by a robot whose position
// estimate wanders during the session: frame j is taken at the true sensor position (the
// surfaces within 3 m as its points) but believed `offsetOf(j)` away, an error of up to 3 cm
// that changes smoothly along the hall.
struct DriftingHall {
  Hall hall = turned(Hall());
  static Hall turned(Hall h) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear() = Eigen::AngleAxisd(7.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    t.translation() = Eigen::Vector3d(0.013, 0.021, 0.0126);
    for (auto& p : h.surface) p = t * p;
    for (auto& c : h.sensors) c = t * c;
    return h;
  }
  FrameVector frames = FrameVector({});
  FrameVector true_frames = FrameVector({});
  static Eigen::Vector3d offsetOf(size_t j, size_t n) {
    const double u = static_cast<double>(j) / static_cast<double>(n - 1);
    return {0.03 * std::sin(2.0 * std::numbers::pi * u), 0.06 * u - 0.03, 0.0};
  }
  DriftingHall() {
    std::vector<Frame> believed, truth;
    const size_t n = hall.sensors.size();
    for (size_t j = 0; j < n; ++j) {
      Frame f;
      for (const Eigen::Vector3d& p : hall.surface) {
        // Every other sample: 4 cm apart, still several per voxel.
        if ((p - hall.sensors[j]).squaredNorm() <= 9.0 && (&p - hall.surface.data()) % 2 == 0) {
          f.cloud.points.push_back((p - hall.sensors[j]).cast<float>());
        }
      }
      f.cloud.width = static_cast<uint32_t>(f.cloud.points.size());
      f.T_world_sensor.translation() = hall.sensors[j];
      truth.push_back(f);
      f.T_world_sensor.translation() += offsetOf(j, n);
      believed.push_back(std::move(f));
    }
    frames = FrameVector(std::move(believed));
    true_frames = FrameVector(std::move(truth));
  }
  // Occupied voxels where the points of `source` land with its poses corrected by `c`.
  static SessionMap seen(const FrameSource& source, const PoseCorrection& c = {}) {
    SessionMap m(0.05);
    for (size_t i = 0; i < source.size(); ++i) {
      const Frame f = source.load(i);
      const Eigen::Isometry3d pose = c.apply(f.T_world_sensor, i);
      for (const Eigen::Vector3f& q : f.cloud.points) {
        if (const auto k = m.grid().keyOf(pose * q.cast<double>())) m.add(*k, occupiedVoxel({100, 100, 100}, 1));
      }
    }
    return m;
  }
  // Mean distance of the corrected sensor positions from the true ones.
  double meanError(const PoseCorrection& c) const {
    double sum = 0.0;
    for (size_t j = 0; j < frames.size(); ++j) {
      sum += (c.apply(frames.poseOf(j), j).translation() - hall.sensors[j]).norm();
    }
    return sum / static_cast<double>(frames.size());
  }
};

}  // namespace

TEST(FitDrift, FollowsAPositionErrorThatWandersAlongTheSession) {
  const DriftingHall d;
  const SessionMap truth = DriftingHall::seen(d.true_frames);
  const SessionMap session = DriftingHall::seen(d.frames);
  const RegistrationTarget target(truth);
  RegisterSettings settings;
  settings.drift_knot_frames = 4;  // 2 m of hall between knots
  RegisterReport report;
  const std::vector<Eigen::Isometry3d> drift = fitDrift(d.frames, session, target, settings, &report);
  ASSERT_EQ(drift.size(), d.frames.size());
  const PoseCorrection corrected{Eigen::Isometry3d::Identity(), CorrectionModel::World, drift};
  const double before = d.meanError({}), after = d.meanError(corrected);
  EXPECT_GT(before, 0.025);
  EXPECT_LT(after, 0.5 * before) << "before " << before << " after " << after;
  EXPECT_LT(report.mean_shift_after_m, report.mean_shift_before_m);
  EXPECT_GT(report.points, d.frames.size() * 50);
  // The headings stay as they were (the error has none).
  for (const auto& c : drift) EXPECT_LT(Eigen::AngleAxisd(c.linear()).angle(), 0.2 * std::numbers::pi / 180.0);
  // One rigid motion cannot follow the error: it changes sign along the hall.
  RegisterSettings rigid;
  const Eigen::Isometry3d t = registerToConsensus(session, target, rigid);
  EXPECT_GT(d.meanError({t, CorrectionModel::World, {}}), 1.5 * after);
  // A session that agrees with the target needs no drift correction.
  const std::vector<Eigen::Isometry3d> none = fitDrift(d.true_frames, truth, target, settings);
  for (const auto& c : none) EXPECT_LT(c.translation().norm(), 0.006);
  // Bad settings and mismatched resolutions are refused.
  settings.drift_knot_frames = 0;
  EXPECT_THROW(fitDrift(d.frames, session, target, settings), UsageError);
  settings.drift_knot_frames = 4;
  settings.drift_per_frame_m = 0.0;
  EXPECT_THROW(fitDrift(d.frames, session, target, settings), UsageError);
  settings.drift_per_frame_m = 0.002;
  EXPECT_THROW(fitDrift(d.frames, SessionMap(0.1), target, settings), UsageError);
  // No frames: nothing to correct.
  EXPECT_TRUE(fitDrift(FrameVector({}), session, target, settings).empty());
}

TEST(RegistrationTarget, AddsThePointsThatFallIntoItsSurface) {
  SessionMap consensus(0.05);
  consensus.add(at(100, 100, 100), occupiedVoxel({1, 1, 1}, 5));
  RegistrationTarget target(consensus);
  const Eigen::Vector3d centre = consensus.grid().centerOf(at(100, 100, 100));
  Frame f;
  f.T_world_sensor.translation() = centre - Eigen::Vector3d(1.0, 0.0, 0.0);
  // Two points in the surface voxel, one in a free neighbour, one beyond the range, one NaN.
  for (const Eigen::Vector3d& w : {Eigen::Vector3d(centre + Eigen::Vector3d(0.01, 0.02, -0.01)),
                                   Eigen::Vector3d(centre + Eigen::Vector3d(-0.01, 0.0, 0.01)),
                                   Eigen::Vector3d(centre + Eigen::Vector3d(0.05, 0.0, 0.0))}) {
    f.cloud.points.push_back((w - f.T_world_sensor.translation()).cast<float>());
  }
  f.cloud.points.push_back(Eigen::Vector3f(5.0f, 0.0f, 0.0f));
  f.cloud.points.push_back(Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f));
  target.addPoints(FrameVector({f}), 3.0);
  ASSERT_EQ(target.points().size(), 1u);
  const Eigen::Vector4d sum = target.points().begin()->second;
  EXPECT_EQ(sum.w(), 2.0);
  EXPECT_TRUE((sum.head<3>() / 2.0).isApprox(centre + Eigen::Vector3d(0.0, 0.01, 0.0), 1e-6));
}

TEST(FitDrift, OnPointsFollowsTheErrorAcrossTheHallMoreClosely) {
  // The same wandering error, measured against the points of the true frames instead of voxel
  // centres. Across the hall (what its long walls show) the points follow it more closely;
  // along it only the pillars' small faces tell, about equally badly for both.
  const DriftingHall d;
  const SessionMap truth = DriftingHall::seen(d.true_frames);
  const SessionMap session = DriftingHall::seen(d.frames);
  RegistrationTarget target(truth);
  RegisterSettings settings;
  settings.drift_knot_frames = 4;
  const PoseCorrection on_voxels{Eigen::Isometry3d::Identity(), CorrectionModel::World,
                                 fitDrift(d.frames, session, target, settings)};
  target.addPoints(d.true_frames, settings.drift_max_range_m);
  settings.drift_points = true;
  settings.planar = true;
  RegisterReport report;
  const std::vector<Eigen::Isometry3d> drift = fitDrift(d.frames, session, target, settings, &report);
  const PoseCorrection on_points{Eigen::Isometry3d::Identity(), CorrectionModel::World, drift};
  // Mean error across the hall (it is turned by 7 degrees).
  const double turn = 7.0 * std::numbers::pi / 180.0;
  const Eigen::Vector3d across(-std::sin(turn), std::cos(turn), 0.0);
  auto acrossError = [&](const PoseCorrection& c) {
    double sum = 0.0;
    for (size_t j = 0; j < d.frames.size(); ++j) {
      sum += std::abs(across.dot(c.apply(d.frames.poseOf(j), j).translation() - d.hall.sensors[j]));
    }
    return sum / static_cast<double>(d.frames.size());
  };
  const double before = acrossError({}), voxels = acrossError(on_voxels), points = acrossError(on_points);
  // Measured: 17.6 mm before, 1.57 mm on voxels, 0.70 mm on points.
  EXPECT_GT(before, 0.01);
  EXPECT_LT(points, 0.001) << "on voxels " << voxels << ", on points " << points;
  EXPECT_LT(points, voxels);
  EXPECT_LT(d.meanError(on_points), 0.5 * d.meanError({}));
  EXPECT_GT(report.matched, d.frames.size() * 20);
  // Planar: no vertical part in any frame's correction.
  for (const auto& c : drift) EXPECT_EQ(c.translation().z(), 0.0);
  // The true frames against their own points need nothing (their own surface's pull cancels
  // what the neighbourhood of an edge does to the plane fit).
  for (const auto& c : fitDrift(d.true_frames, truth, target, settings)) EXPECT_LT(c.translation().norm(), 0.001);
}

TEST(RegisterSessions, CorrectsDriftFromTheFramesAndReintegrates) {
  const DriftingHall d;
  // Two sessions with the true poses and the drifting one.
  const std::vector<const FrameSource*> sources = {&d.true_frames, &d.true_frames, &d.frames};
  std::vector<SessionMap> sessions;
  for (const FrameSource* s : sources) sessions.push_back(DriftingHall::seen(*s));
  RegisterSettings settings;
  settings.max_points = 5000;
  settings.drift_knot_frames = 4;
  settings.drift_rounds = 1;
  const auto reintegrate = [&](size_t k, const PoseCorrection& c) { return DriftingHall::seen(*sources[k], c); };
  const auto frames = [&](size_t k) -> std::unique_ptr<FrameSource> {
    return std::make_unique<FrameVector>(static_cast<const FrameVector*>(sources[k])->frames());
  };
  const auto corrections = registerSessions(sessions, reintegrate, 1, settings, nullptr, {}, frames);
  ASSERT_EQ(corrections.size(), 3u);
  ASSERT_EQ(corrections[2].per_frame.size(), d.frames.size());
  // (The consensus holds the drifting session too, so this is less exact than against the truth.)
  EXPECT_LT(d.meanError(corrections[2]), 0.65 * d.meanError({}));
  EXPECT_EQ(sessions[2], DriftingHall::seen(d.frames, corrections[2]));  // re-integrated with it
  // Drift needs the frames.
  EXPECT_THROW(registerSessions(sessions, reintegrate, 1, settings), UsageError);
}

TEST(PoseCorrection, PerFramePartsApplyByIndexAndCompose) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(10.0, 0.0, 0.5);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  Eigen::Isometry3d f0 = Eigen::Isometry3d::Identity(), f1 = Eigen::Isometry3d::Identity();
  f0.translation() = Eigen::Vector3d(0.0, 0.5, 0.0);
  f1.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const PoseCorrection c{m, CorrectionModel::World, {f0, f1}};
  EXPECT_TRUE(c.apply(pose, 0).translation().isApprox(Eigen::Vector3d(11.0, 0.5, 0.5)));
  // Frame 1 turns about its own (corrected) position.
  EXPECT_TRUE(c.apply(pose, 1).translation().isApprox(Eigen::Vector3d(11.0, 0.0, 0.5)));
  EXPECT_TRUE(c.apply(pose, 1).linear().isApprox(f1.linear()));
  EXPECT_THROW(c.apply(pose, 2), UsageError);
  EXPECT_FALSE(c.isIdentity());
  EXPECT_FALSE((PoseCorrection{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f0}}.isIdentity()));
  // A motion, then per-frame parts, then more per-frame parts: the same as one after the other.
  const PoseCorrection rigid{m, CorrectionModel::World, {}};
  const PoseCorrection drift{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f0, f1}};
  const PoseCorrection more{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f1, f0}};
  const PoseCorrection all = rigid.then(drift).then(more);
  for (size_t i = 0; i < 2; ++i) {
    const Eigen::Isometry3d step = more.apply(drift.apply(rigid.apply(pose, i), i), i);
    EXPECT_TRUE(all.apply(pose, i).isApprox(step, 1e-12)) << i;
  }
  // A motion cannot follow per-frame parts; per-frame parts of different lengths do not combine.
  EXPECT_THROW(drift.then(rigid), UsageError);
  EXPECT_THROW(drift.then(PoseCorrection{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f0}}), UsageError);
}
