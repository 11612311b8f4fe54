#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "chronomap/analysis/segment.h"
#include "chronomap/core/error.h"

namespace chronomap {
namespace {

// Cells near the root's centre, so that components cross the largest octree boundaries.
constexpr int kSegBase = 32768 - 16;

ChangeCell cellAt(int x, int y, int z, int level = 0, ChangeKind kind = ChangeKind::Appeared, Rgb colour = {}) {
  ChangeCell c;
  c.key = VoxelKey{static_cast<uint16_t>(kSegBase + x), static_cast<uint16_t>(kSegBase + y), static_cast<uint16_t>(kSegBase + z)};
  c.level = static_cast<uint8_t>(level);
  c.kind = kind;
  c.colour = colour;
  c.value = 1.0f;
  return c;
}

DiffMap diffOf(std::vector<ChangeCell> cells, DiffMode mode = DiffMode::Hard) {
  DiffSettings s;
  s.mode = mode;
  return DiffMap::fromCells(0.05, s, std::move(cells));
}

size_t countWith(const DiffMap& d, Connectivity c) {
  SegmentSettings s;
  s.connectivity = c;
  return segment(d, s).components.size();
}

TEST(Segment, ConnectivityDecidesWhatTouches) {
  // Two voxels sharing a face, an edge, a vertex, or nothing. kSegBase + 15/16 straddles the
  // root's centre on every axis.
  const DiffMap face = diffOf({cellAt(15, 15, 15), cellAt(16, 15, 15)});
  const DiffMap edge = diffOf({cellAt(15, 15, 15), cellAt(16, 16, 15)});
  const DiffMap vertex = diffOf({cellAt(15, 15, 15), cellAt(16, 16, 16)});
  const DiffMap apart = diffOf({cellAt(15, 15, 15), cellAt(17, 15, 15)});
  EXPECT_EQ(countWith(face, Connectivity::Face), 1u);
  EXPECT_EQ(countWith(edge, Connectivity::Face), 2u);
  EXPECT_EQ(countWith(edge, Connectivity::Edge), 1u);
  EXPECT_EQ(countWith(vertex, Connectivity::Edge), 2u);
  EXPECT_EQ(countWith(vertex, Connectivity::Vertex), 1u);
  EXPECT_EQ(countWith(apart, Connectivity::Vertex), 2u);
  // The same inside one small node (kSegBase + 2/3 share a parent at level 1 on every axis).
  EXPECT_EQ(countWith(diffOf({cellAt(2, 2, 2), cellAt(3, 3, 3)}), Connectivity::Edge), 2u);
  EXPECT_EQ(countWith(diffOf({cellAt(2, 2, 2), cellAt(3, 3, 3)}), Connectivity::Vertex), 1u);
  EXPECT_EQ(countWith(diffOf({cellAt(2, 2, 2), cellAt(3, 3, 2)}), Connectivity::Edge), 1u);
}

TEST(Segment, BigCellsTouchSmallOnes) {
  // A level-2 cube (4 voxels a side) and a unit voxel touching its face, its edge, its corner.
  const ChangeCell cube = cellAt(4, 4, 4, 2);
  EXPECT_EQ(countWith(diffOf({cube, cellAt(8, 6, 5)}), Connectivity::Face), 1u);
  EXPECT_EQ(countWith(diffOf({cube, cellAt(8, 8, 5)}), Connectivity::Face), 2u);
  EXPECT_EQ(countWith(diffOf({cube, cellAt(8, 8, 5)}), Connectivity::Edge), 1u);
  EXPECT_EQ(countWith(diffOf({cube, cellAt(8, 8, 8)}), Connectivity::Edge), 2u);
  EXPECT_EQ(countWith(diffOf({cube, cellAt(3, 3, 3)}), Connectivity::Vertex), 1u);
}

TEST(Segment, ComponentRecordsAreExact) {
  // A 2x3x1 slab of appeared voxels and a vanished voxel next to it.
  std::vector<ChangeCell> cells;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 2; ++x) cells.push_back(cellAt(x, y, 0, 0, ChangeKind::Appeared, Rgb{100, 0, static_cast<uint8_t>(y == 0 ? 30 : 0)}));
  }
  cells.push_back(cellAt(2, 0, 0, 0, ChangeKind::Vanished, Rgb{0, 200, 0}));
  const DiffMap d = diffOf(cells);
  const Segmentation seg = segment(d);
  ASSERT_EQ(seg.components.size(), 2u) << "appeared and vanished never join";
  const Component& slab = seg.components[0];
  EXPECT_EQ(slab.id, 1u);
  EXPECT_EQ(slab.kind, ChangeKind::Appeared);
  EXPECT_EQ(slab.voxels, 6u);
  EXPECT_NEAR(slab.volume_m3, 6 * 0.05 * 0.05 * 0.05, 1e-12);
  const Eigen::Vector3d corner = d.grid().cornerOf(cells[0].key);
  EXPECT_TRUE(slab.bbox_min_m.isApprox(corner));
  EXPECT_TRUE(slab.bbox_max_m.isApprox(corner + Eigen::Vector3d(0.10, 0.15, 0.05)));
  EXPECT_TRUE(slab.centroid_m.isApprox(corner + Eigen::Vector3d(0.05, 0.075, 0.025)));
  EXPECT_EQ(slab.mean_colour, (Rgb{100, 0, 10}));
  EXPECT_EQ(seg.components[1].kind, ChangeKind::Vanished);
  EXPECT_EQ(seg.components[1].mean_colour, (Rgb{0, 200, 0}));
  EXPECT_EQ(componentDiff(d, slab).voxelCount(), 6u);
}

TEST(Segment, ColourToleranceAndMinimumSize) {
  // A row of 6 voxels: 3 red, 3 blue.
  std::vector<ChangeCell> cells;
  for (int x = 0; x < 6; ++x) cells.push_back(cellAt(x, 0, 0, 0, ChangeKind::Appeared, x < 3 ? Rgb{200, 0, 0} : Rgb{0, 0, 200}));
  cells.push_back(cellAt(10, 0, 0));
  const DiffMap d = diffOf(cells);
  SegmentSettings s;
  EXPECT_EQ(segment(d, s).components.size(), 2u);
  s.colour_tolerance = 50;
  EXPECT_EQ(segment(d, s).components.size(), 3u);
  s.min_voxels = 2;
  const Segmentation big = segment(d, s);
  EXPECT_EQ(big.components.size(), 2u);
  EXPECT_EQ(big.dropped, 1u);
  s.colour_tolerance = std::numeric_limits<double>::infinity();
  EXPECT_THROW(segment(d, s), UsageError);
  EXPECT_THROW(parseConnectivity("corner"), UsageError);
}

TEST(Segment, ContinuousDiffsAreCutAtMinValue) {
  std::vector<ChangeCell> cells;
  for (int x = 0; x < 5; ++x) {
    ChangeCell c = cellAt(x, 0, 0);
    c.value = x == 2 ? 0.2f : 0.8f;  // the middle one is weak: it splits the row
    cells.push_back(c);
  }
  const DiffMap d = diffOf(cells, DiffMode::Continuous);
  SegmentSettings s;
  EXPECT_EQ(segment(d, s).components.size(), 2u);
  s.min_value = 0.1;
  EXPECT_EQ(segment(d, s).components.size(), 1u);
}

TEST(Segment, EmptyDiffHasNoComponents) {
  EXPECT_TRUE(segment(DiffMap(0.05)).components.empty());
  EXPECT_TRUE(segmentByFloodFill(DiffMap(0.05)).components.empty());
}

// ---------------------------------------------------------------------------------------------
// Random sparse octrees against the flood fill.

// Clusters of unit voxels and some aligned cubes (levels 1 and 2), two kinds, a few colours,
// in a 32^3 region around the root's centre.
DiffMap randomDiff(std::mt19937_64& rng) {
  std::set<std::array<int, 3>> used;
  std::vector<ChangeCell> cells;
  const Rgb palette[3] = {{200, 30, 30}, {190, 40, 40}, {20, 20, 220}};
  auto free_block = [&](int x, int y, int z, int side) {
    for (int dz = 0; dz < side; ++dz)
      for (int dy = 0; dy < side; ++dy)
        for (int dx = 0; dx < side; ++dx)
          if (used.count({x + dx, y + dy, z + dz})) return false;
    return true;
  };
  auto take = [&](int x, int y, int z, int level) {
    const int side = 1 << level;
    if (!free_block(x, y, z, side)) return;
    for (int dz = 0; dz < side; ++dz)
      for (int dy = 0; dy < side; ++dy)
        for (int dx = 0; dx < side; ++dx) used.insert({x + dx, y + dy, z + dz});
    const ChangeKind kind = rng() % 4 == 0 ? ChangeKind::Vanished : ChangeKind::Appeared;
    cells.push_back(cellAt(x, y, z, level, kind, palette[rng() % 3]));
  };
  const int cubes = static_cast<int>(rng() % 4);
  for (int i = 0; i < cubes; ++i) {
    const int level = 1 + static_cast<int>(rng() % 2), side = 1 << level;
    take(static_cast<int>(rng() % (32 / side)) * side, static_cast<int>(rng() % (32 / side)) * side,
         static_cast<int>(rng() % (32 / side)) * side, level);
  }
  const int clusters = 1 + static_cast<int>(rng() % 5);
  for (int c = 0; c < clusters; ++c) {
    int x = static_cast<int>(rng() % 32), y = static_cast<int>(rng() % 32), z = static_cast<int>(rng() % 32);
    const int n = 1 + static_cast<int>(rng() % 25);
    for (int i = 0; i < n; ++i) {
      take(x, y, z, 0);
      // A random step to a face, edge or vertex neighbour, sometimes a jump.
      x = std::clamp(x + static_cast<int>(rng() % 3) - 1 + (rng() % 9 == 0 ? 2 : 0), 0, 31);
      y = std::clamp(y + static_cast<int>(rng() % 3) - 1, 0, 31);
      z = std::clamp(z + static_cast<int>(rng() % 3) - 1, 0, 31);
    }
  }
  return diffOf(cells);
}

std::vector<std::vector<uint32_t>> partition(const Segmentation& s) {
  std::vector<std::vector<uint32_t>> p;
  for (const Component& c : s.components) p.push_back(c.cells);
  return p;
}

TEST(Segment, EqualsFloodFillOnThousandsOfRandomOctrees) {
  std::mt19937_64 rng(2024);
  size_t merged_differently = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const DiffMap d = randomDiff(rng);
    std::vector<size_t> counts;
    for (Connectivity c : {Connectivity::Face, Connectivity::Edge, Connectivity::Vertex}) {
      for (double tolerance : {-1.0, 20.0}) {
        SegmentSettings s;
        s.connectivity = c;
        s.colour_tolerance = tolerance;
        const Segmentation fast = segment(d, s);
        const Segmentation slow = segmentByFloodFill(d, s);
        ASSERT_EQ(partition(fast), partition(slow)) << "trial " << trial << " " << toString(c) << " tolerance "
                                                    << tolerance;
        // Components keep exactly the input's cells, each once.
        std::vector<uint32_t> all;
        for (const Component& comp : fast.components) all.insert(all.end(), comp.cells.begin(), comp.cells.end());
        std::sort(all.begin(), all.end());
        ASSERT_EQ(all.size(), d.cells().size());
        for (size_t i = 0; i < all.size(); ++i) ASSERT_EQ(all[i], i);
        counts.push_back(fast.components.size());
      }
    }
    // More connectivity never splits more; a tolerance never merges more.
    ASSERT_GE(counts[0], counts[2]);
    ASSERT_GE(counts[2], counts[4]);
    ASSERT_LE(counts[0], counts[1]);
    merged_differently += counts[0] != counts[4];
  }
  EXPECT_GT(merged_differently, 300u) << "the random octrees exercise edge and vertex contacts";
}

}  // namespace
}  // namespace chronomap
