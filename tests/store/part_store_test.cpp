// The streaming build's spill store: what goes in comes out, per cube, in the order added,
// whether it was held or spilled, and the store never holds more than its limit.

#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <random>
#include <vector>

#include "chronomap/store/part_store.h"
#include "test_support.h"

namespace chronomap {
namespace {

SessionPart partOf(uint32_t i) {
  SessionPart p;
  p.session = i % 7;
  p.x = static_cast<uint16_t>(i);
  p.y = static_cast<uint16_t>(i * 3);
  p.z = static_cast<uint16_t>(i * 5);
  p.level = static_cast<uint8_t>(i % 3);
  p.counters.hits = i;
  p.counters.length_m = 0.25f * static_cast<float>(i);
  return p;
}

bool same(const SessionPart& a, const SessionPart& b) {
  return a.session == b.session && a.x == b.x && a.y == b.y && a.z == b.z && a.level == b.level &&
         a.counters.hits == b.counters.hits && a.counters.length_m == b.counters.length_m;
}

TEST(PartStore, GivesBackEveryPartOfACubeInTheOrderAddedHeldOrSpilled) {
  for (const size_t limit : {size_t{0}, sizeof(SessionPart) * 5, sizeof(SessionPart) * 64}) {
    test::TempDir tmp;
    const std::filesystem::path folder = tmp / "parts";
    std::map<int, std::vector<SessionPart>> expected;
    std::mt19937 rng(7);
    PartStoreStats stats;
    {
      PartStore store(folder, limit);
      for (uint32_t i = 0; i < 400; ++i) {
        const int c = static_cast<int>(rng() % 6);
        const Cube cube{VoxelKey{static_cast<uint16_t>(c * 16), 0, 0}, 4};
        store.add(cube, partOf(i));
        expected[c].push_back(partOf(i));
        if (limit != 0) {
          EXPECT_LE(store.stats().peak_bytes, limit);
        }
      }
      EXPECT_EQ(store.cubes().size(), expected.size());
      for (auto& [c, parts] : expected) {
        const std::vector<SessionPart> got = store.take(Cube{VoxelKey{static_cast<uint16_t>(c * 16), 0, 0}, 4});
        ASSERT_EQ(got.size(), parts.size()) << "limit " << limit << " cube " << c;
        for (size_t k = 0; k < got.size(); ++k) EXPECT_TRUE(same(got[k], parts[k])) << k;
        // Taken parts leave the store.
        EXPECT_TRUE(store.take(Cube{VoxelKey{static_cast<uint16_t>(c * 16), 0, 0}, 4}).empty());
      }
      stats = store.stats();
    }
    if (limit == sizeof(SessionPart) * 5) {
      EXPECT_GT(stats.spills, 70u);  // 400 parts, at most 5 held
      EXPECT_EQ(stats.spilled_bytes % sizeof(SessionPart), 0u);
    }
    if (limit == 0) {
      EXPECT_EQ(stats.spills, 0u);
    }
    // The spill folder goes with the store.
    EXPECT_FALSE(std::filesystem::exists(folder));
  }
}

}  // namespace
}  // namespace chronomap
