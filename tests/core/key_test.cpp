#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <map>
#include <cmath>
#include <optional>
#include <random>
#include <utility>
#include <unordered_map>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/error.h"
#include "chronomap/core/key.h"
#include "chronomap/core/key_ball.h"
#include "chronomap/core/voxel_table.h"

namespace chronomap {
namespace {

TEST(Morton, RoundTripsRandomKeys) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> d(0, 65535);
  for (int i = 0; i < 100000; ++i) {
    const VoxelKey k{static_cast<uint16_t>(d(rng)), static_cast<uint16_t>(d(rng)), static_cast<uint16_t>(d(rng))};
    EXPECT_EQ(mortonDecode(mortonEncode(k)), k);
  }
}

TEST(Morton, InterleavesXLowest) {
  EXPECT_EQ(mortonEncode({1, 0, 0}), 1u);
  EXPECT_EQ(mortonEncode({0, 1, 0}), 2u);
  EXPECT_EQ(mortonEncode({0, 0, 1}), 4u);
  EXPECT_EQ(mortonEncode({2, 0, 0}), 8u);
  EXPECT_EQ(mortonEncode({65535, 65535, 65535}), (uint64_t{1} << 48) - 1);
}

TEST(VoxelTable, HoldsWhatAnUnorderedMapHoldsThroughGrowthAndClears) {
  // The registration's fast table against the std::unordered_map it replaced: the same random
  // mix of insertions (clustered codes, as a surface's are, and repeats), lookups of present
  // and absent codes, and clears that keep the memory.
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> near(0, 40), op(0, 9);
  VoxelTable<uint32_t> table;
  std::unordered_map<uint64_t, uint32_t> reference;
  const auto code = [&] {
    return mortonEncode(VoxelKey{static_cast<uint16_t>(32000 + near(rng)), static_cast<uint16_t>(32000 + near(rng)),
                                 static_cast<uint16_t>(32760 + near(rng) / 8)});
  };
  for (int round = 0; round < 3; ++round) {
    for (int i = 0; i < 20000; ++i) {
      const uint64_t c = code();
      if (op(rng) < 6) {
        ++table.tryEmplace(c, 10);
        ++reference.try_emplace(c, 10).first->second;
      } else {
        const uint32_t* found = table.find(c);
        const auto expected = reference.find(c);
        ASSERT_EQ(found != nullptr, expected != reference.end());
        if (found) {
          EXPECT_EQ(*found, expected->second);
        }
        EXPECT_EQ(table.contains(c), found != nullptr);
      }
    }
    ASSERT_EQ(table.size(), reference.size());
    size_t visited = 0;
    table.forEach([&](uint64_t c, uint32_t v) {
      ++visited;
      const auto expected = reference.find(c);
      ASSERT_NE(expected, reference.end());
      EXPECT_EQ(v, expected->second);
    });
    EXPECT_EQ(visited, reference.size());
    table.clear();
    reference.clear();
    EXPECT_TRUE(table.empty());
    EXPECT_EQ(table.find(code()), nullptr);
  }
}

TEST(ForEachKeyWithin, VisitsEveryVoxelOfTheCubeWithinTheRadiusInOrderAndFewOthers) {
  // The registration's filter against the whole cube it replaced, tested exactly as the
  // registration tests after it: centres (box false) or boxes (box true) within the radius.
  std::mt19937 rng(3);
  for (const double res : {0.05, 0.0001}) {
    const KeyGrid grid(res);
    std::uniform_real_distribution<double> coordinate(-1000.0 * res, 1000.0 * res);
    size_t visited_total = 0, cube_total = 0;
    for (int trial = 0; trial < 400; ++trial) {
      const Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
      const double radius = std::array<double, 5>{1.0, 1.5, 2.0, 3.7, 8.0}[trial % 5];
      const bool box = trial % 2 == 1;
      std::vector<VoxelKey> visited;
      ASSERT_TRUE(forEachKeyWithin(grid, p, radius, box, [&](const VoxelKey& k) { visited.push_back(k); }));
      const VoxelKey k = *grid.keyOf(p);
      const int r = static_cast<int>(std::ceil(radius));
      const double r2 = radius * res * radius * res;
      std::vector<VoxelKey> cube;  // z, y, x ascending, as visited
      for (int dz = -r; dz <= r; ++dz) {
        for (int dy = -r; dy <= r; ++dy) {
          for (int dx = -r; dx <= r; ++dx) cube.push_back(*offsetKey(k, dx, dy, dz));
        }
      }
      size_t next = 0;  // the visited keys, a subsequence of the cube
      for (const VoxelKey& n : cube) {
        const bool seen = next < visited.size() && visited[next] == n;
        if (seen) ++next;
        double d2 = 0.0;
        if (box) {
          const Eigen::Vector3d lo = grid.cornerOf(n) - p, hi = lo + Eigen::Vector3d::Constant(res);
          for (int a = 0; a < 3; ++a) {
            const double gap = lo[a] > 0.0 ? lo[a] : (hi[a] < 0.0 ? -hi[a] : 0.0);
            d2 += gap * gap;
          }
        } else {
          d2 = (grid.centerOf(n) - p).squaredNorm();
        }
        if (d2 <= r2) {
          EXPECT_TRUE(seen) << "left out a voxel " << std::sqrt(d2) / res << " voxels away, radius " << radius;
        }
      }
      EXPECT_EQ(next, visited.size()) << "visited a key outside the cube or out of order";
      visited_total += visited.size();
      cube_total += cube.size();
    }
    // The point of it: most of the cube is never visited.
    EXPECT_LT(visited_total, cube_total * 2 / 3);
  }
  // Outside the grid: nothing.
  EXPECT_FALSE(forEachKeyWithin(KeyGrid(0.05), Eigen::Vector3d(1e9, 0, 0), 2.0, false, [](const VoxelKey&) {}));
}

TEST(ForEachFoundWithin, FindsWhatLookingUpEachVisitedVoxelFindsInTheSameOrder) {
  // The batched, prefetched lookups against one lookup per visited voxel.
  std::mt19937 rng(5);
  const KeyGrid grid(0.05);
  VoxelTable<uint32_t> table;
  std::uniform_int_distribution<int> offset(-12, 12);
  for (uint32_t i = 0; i < 4000; ++i) {
    table.tryEmplace(mortonEncode(*offsetKey(VoxelKey{32768, 32768, 32768}, offset(rng), offset(rng), offset(rng))), i);
  }
  std::uniform_real_distribution<double> coordinate(-0.6, 0.6);
  size_t found_total = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
    const double radius = std::array<double, 4>{1.0, 2.0, 3.7, 8.0}[trial % 4];
    const bool box = trial % 2 == 1;
    // Every other key (by its x) is refused, so that `keep` matters too.
    const auto keep = [](const VoxelKey& k) { return k.x % 2 == 0; };
    std::vector<std::pair<VoxelKey, uint32_t>> expected, found;
    const bool inside = forEachKeyWithin(grid, p, radius, box, [&](const VoxelKey& k) {
      if (!keep(k)) return;
      if (const uint32_t* v = table.find(mortonEncode(k))) expected.emplace_back(k, *v);
    });
    EXPECT_EQ(forEachFoundWithin(table, grid, p, radius, box, keep,
                                 [&](const VoxelKey& k, uint32_t v) { found.emplace_back(k, v); }),
              inside);
    EXPECT_EQ(found, expected) << trial;
    found_total += found.size();
  }
  EXPECT_GT(found_total, 10000u);  // many voxels found, and batches of 32 filled many times
  EXPECT_FALSE(forEachFoundWithin(table, grid, Eigen::Vector3d(1e9, 0, 0), 2.0, false,
                                  [](const VoxelKey&) { return true; }, [](const VoxelKey&, uint32_t) {}));
}

TEST(KeyGrid, KeyOfEqualsFlooringTheKeySpaceCoordinate) {
  // keyOf truncates instead of calling floor: the same keys, and the same points refused.
  std::mt19937 rng(7);
  for (const double res : {0.05, 0.0001, 1000.0}) {
    const KeyGrid g(res);
    std::uniform_real_distribution<double> coordinate(-1.2 * g.halfExtent_m(), 1.2 * g.halfExtent_m());
    std::uniform_real_distribution<double> near(-3.0 * res, 3.0 * res);
    for (int i = 0; i < 20000; ++i) {
      Eigen::Vector3d p(coordinate(rng), near(rng), i % 2 ? near(rng) : -g.halfExtent_m() + near(rng));
      if (i % 7 == 0) p.y() = std::nextafter(0.0, i % 14 == 0 ? 1.0 : -1.0);
      std::optional<VoxelKey> reference = VoxelKey{};
      const Eigen::Vector3d u = g.toKeySpace(p);
      uint16_t* out[3] = {&reference->x, &reference->y, &reference->z};
      for (int a = 0; a < 3 && reference; ++a) {
        const double f = std::floor(u[a]);
        if (!(f >= 0.0 && f < kKeysPerAxis)) {
          reference.reset();
        } else {
          *out[a] = static_cast<uint16_t>(f);
        }
      }
      EXPECT_EQ(g.keyOf(p), reference) << p.transpose();
    }
  }
}

TEST(ForEachKeyInCube, VisitsTheCubeInOrderAndStopsAtTheKeySpace) {
  const VoxelKey centre{100, 200, 300};
  for (int r : {0, 1, 3}) {
    std::vector<VoxelKey> seen;
    forEachKeyInCube(centre, r, [&](const VoxelKey& k) { seen.push_back(k); });
    ASSERT_EQ(seen.size(), static_cast<size_t>((2 * r + 1) * (2 * r + 1) * (2 * r + 1))) << r;
    size_t i = 0;
    for (int dz = -r; dz <= r; ++dz)
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx, ++i) {
          const VoxelKey want{static_cast<uint16_t>(100 + dx), static_cast<uint16_t>(200 + dy),
                              static_cast<uint16_t>(300 + dz)};
          EXPECT_EQ(seen[i], want) << r << " " << i;
        }
  }
  // At the corner of the key space only the octant inside: 2 x 2 x 2 of the 27 at r = 1.
  size_t corner = 0;
  forEachKeyInCube(VoxelKey{0, 0, 0}, 1, [&](const VoxelKey& k) {
    ++corner;
    EXPECT_TRUE(k.x <= 1 && k.y <= 1 && k.z <= 1);
  });
  EXPECT_EQ(corner, 8u);
}

TEST(KeyGrid, MapsPointsToVoxelsAroundTheOrigin) {
  KeyGrid g(0.05);
  EXPECT_EQ(*g.keyOf({0.0, 0.0, 0.0}), (VoxelKey{32768, 32768, 32768}));
  EXPECT_EQ(*g.keyOf({-0.001, 0.049, 0.051}), (VoxelKey{32767, 32768, 32769}));
  const Eigen::Vector3d c = g.centerOf(VoxelKey{32768, 32767, 32770});
  EXPECT_NEAR(c.x(), 0.025, 1e-12);
  EXPECT_NEAR(c.y(), -0.025, 1e-12);
  EXPECT_NEAR(c.z(), 0.125, 1e-12);
  EXPECT_EQ(*g.keyOf(c), (VoxelKey{32768, 32767, 32770}));
}

TEST(KeyGrid, RejectsPointsOutsideTheMapAndNaN) {
  KeyGrid g(0.05);
  EXPECT_FALSE(g.keyOf({1700.0, 0, 0}).has_value());  // half extent is 1638.4 m
  EXPECT_FALSE(g.keyOf({0, -1700.0, 0}).has_value());
  EXPECT_FALSE(g.keyOf({std::nan(""), 0, 0}).has_value());
  EXPECT_TRUE(g.keyOf({1638.0, 0, 0}).has_value());
}

TEST(KeyGrid, RejectsBadResolutions) {
  EXPECT_THROW(KeyGrid(0.0), UsageError);
  EXPECT_THROW(KeyGrid(-0.1), UsageError);
  EXPECT_THROW(KeyGrid(std::nan("")), UsageError);
}

TEST(VoxelCounters, StatesFollowTheDefinition) {
  VoxelCounters c;
  EXPECT_EQ(c.state(), VoxelState::Unknown);  // never traversed
  c.length_m = 0.2f;
  EXPECT_EQ(c.state(), VoxelState::Free);  // traversed, no hit
  EXPECT_DOUBLE_EQ(c.probability(), 0.0);
  c.hits = 1;  // P = 1 - exp(-5)
  EXPECT_NEAR(c.probability(), 1.0 - std::exp(-5.0), 1e-6);
  EXPECT_EQ(c.state(), VoxelState::Occupied);
  c.length_m = 2.0f;  // P = 1 - exp(-0.5) = 0.393
  EXPECT_EQ(c.state(), VoxelState::Free);
  c.length_m = 1.0f / std::log(2.0f) * 1.0001f;  // P just below 0.5
  EXPECT_EQ(c.state(), VoxelState::Free);
  c.length_m = 1.0f / std::log(2.0f) * 0.999f;  // just above
  EXPECT_EQ(c.state(), VoxelState::Occupied);
  VoxelCounters end_on_face;
  end_on_face.hits = 1;  // a ray that ended exactly on the entry face
  EXPECT_EQ(end_on_face.state(), VoxelState::Occupied);
}

TEST(VoxelCounters, MeanColourRounds) {
  VoxelCounters c;
  c.hits = 3;
  c.red = 255 * 3;
  c.green = 10;  // 3.33 -> 3
  c.blue = 11;   // 3.67 -> 4
  EXPECT_EQ(c.meanColour(), (Rgb{255, 3, 4}));
}

// Walking every voxel of a random set with forEachLaterNeighbour visits each touching pair of
// the set exactly once (the slow reference: every pair of the set, touching when no axis
// differs by more than one), at the key space's edges too.
TEST(Neighbours, LaterNeighboursVisitEachTouchingPairOnce) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const int base = trial % 2 == 0 ? 0 : kKeysPerAxis - 4;  // half the sets at the far corner
    std::vector<VoxelKey> set;
    std::uniform_int_distribution<int> d(0, 3);
    for (int i = 0; i < 24; ++i) {
      const VoxelKey v{static_cast<uint16_t>(base + d(rng)), static_cast<uint16_t>(base + d(rng)),
                       static_cast<uint16_t>(base + d(rng))};
      if (std::find(set.begin(), set.end(), v) == set.end()) set.push_back(v);
    }
    std::map<std::pair<uint64_t, uint64_t>, int> expected, seen;
    for (size_t i = 0; i < set.size(); ++i) {
      for (size_t j = i + 1; j < set.size(); ++j) {
        const VoxelKey a = set[i], b = set[j];
        if (std::abs(a.x - b.x) <= 1 && std::abs(a.y - b.y) <= 1 && std::abs(a.z - b.z) <= 1) {
          expected[std::minmax(mortonEncode(a), mortonEncode(b))] = 1;
        }
      }
    }
    for (const VoxelKey& v : set) {
      forEachLaterNeighbour(v, [&](const VoxelKey& n) {
        if (std::find(set.begin(), set.end(), n) != set.end()) ++seen[std::minmax(mortonEncode(v), mortonEncode(n))];
      });
    }
    EXPECT_EQ(seen, expected) << "trial " << trial;
  }
}

}  // namespace
}  // namespace chronomap
