// Consensus maps (thesis §2.2): the sum of what every session reports, of a list of maps or of a
// 4D map's snapshots, and bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "chronomap/align/consensus.h"
#include "chronomap/core/error.h"
#include "chronomap/temporal/temporal_map.h"
#include "builders.h"

using namespace chronomap;
using test::at;
using test::nearlyEqual;

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
