#include <gtest/gtest.h>

#include <limits>
#include <map>

#include "chronomap/analysis/change_frequency.h"
#include "chronomap/core/error.h"
#include "builders.h"

namespace chronomap {
namespace {

using test::at;

constexpr double kInf = std::numeric_limits<double>::infinity();

// The slow reference: every slot list of the map (no skipping by the change summaries), its
// entries after the first counted when their session's time lies in (from, to], cubes expanded.
std::map<VoxelKey, uint32_t> referenceCounts(const TemporalMap& map, double from, double to) {
  std::map<VoxelKey, uint32_t> out;
  map.forEachList([&](const VoxelKey& k, int level, std::span<const TemporalMap::Entry> entries) {
    uint32_t n = 0;
    for (size_t i = 1; i < entries.size(); ++i) {
      const double t = map.sessions()[entries[i].session].time_s;
      if (t > from && t <= to) ++n;
    }
    if (n == 0) return;
    const int side = 1 << level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          out[VoxelKey{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy),
                       static_cast<uint16_t>(k.z + dz)}] += n;
        }
      }
    }
  });
  return out;
}

TEST(ChangeFrequency, CountsEachVoxelsStateChanges) {
  // Voxel a: free, occupied, free, occupied (3 changes); voxel b: occupied throughout (none).
  TemporalMap map(0.05);
  for (int s = 0; s < 4; ++s) {
    SessionMap m(0.05);
    m.add(at(1, 1, 1), s % 2 ? test::occupiedVoxel(Rgb{200, 0, 0}) : test::freeVoxel());
    m.add(at(5, 1, 1), test::occupiedVoxel(Rgb{0, 200, 0}));
    map.add(10.0 * (s + 1), m);
  }
  const ChangeFrequency all = changeFrequency(map, -kInf, kInf, 1);
  ASSERT_EQ(all.voxels.size(), 1u);
  EXPECT_EQ(all.voxels[0].key, at(1, 1, 1));
  EXPECT_EQ(all.voxels[0].count, 3u);
  EXPECT_EQ(all.max_count, 3u);
  ASSERT_EQ(all.histogram.size(), 4u);
  EXPECT_EQ(all.histogram[3], 1u);
  EXPECT_EQ(all.changedVoxels(), 1u);
  // Only the changes after t = 20: the sessions at 30 and 40.
  const ChangeFrequency late = changeFrequency(map, 20.0, kInf, 1);
  ASSERT_EQ(late.voxels.size(), 1u);
  EXPECT_EQ(late.voxels[0].count, 2u);
  // A least count above every voxel's lists none, but the histogram still counts them.
  const ChangeFrequency busy = changeFrequency(map, -kInf, kInf, 4);
  EXPECT_TRUE(busy.voxels.empty());
  EXPECT_EQ(busy.max_count, 0u);
  EXPECT_EQ(busy.changedVoxels(), 1u);
  EXPECT_EQ(changeHistogram(map, -kInf, kInf), all.histogram);
}

TEST(ChangeFrequency, MatchesTheFullWalkOnRandomMaps) {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    TemporalMap map(0.05);
    for (int s = 0; s < 6; ++s) map.add(100.0 * s, test::randomSessionMap(seed * 31 + s, 16, 0.3));
    for (const auto& [from, to] : {std::pair{-kInf, kInf}, std::pair{100.0, 400.0}, std::pair{250.0, 260.0}}) {
      const auto expected = referenceCounts(map, from, to);
      const ChangeFrequency f = changeFrequency(map, from, to, 1);
      std::map<VoxelKey, uint32_t> got;
      for (const VoxelChangeCount& v : f.voxels) got[v.key] += v.count;
      EXPECT_EQ(got, expected) << "seed " << seed << ", (" << from << ", " << to << "]";
      uint64_t listed = 0;
      for (size_t n = 1; n < f.histogram.size(); ++n) listed += f.histogram[n];
      EXPECT_EQ(listed, expected.size());
    }
  }
}

TEST(ChangeFrequency, RefusesAnEmptyIntervalAndZeroChanges) {
  const TemporalMap map(0.05);
  EXPECT_THROW(changeFrequency(map, 0.0, 1.0, 0), UsageError);
  EXPECT_THROW(changeFrequency(map, 2.0, 1.0, 1), UsageError);
  EXPECT_TRUE(changeFrequency(map, -kInf, kInf, 1).voxels.empty());
}

}  // namespace
}  // namespace chronomap
