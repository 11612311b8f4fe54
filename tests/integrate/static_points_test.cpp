// Static points: a box that stands in the room for a few frames and is gone in the others is
// dropped, the room is kept; the voxel rule on its own.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <set>

#include "chronomap/integrate/static_points.h"
#include "chronomap/sim/box_room.h"

namespace chronomap {
namespace {

TEST(StaticPoints, TheVoxelRuleNeedsEnoughFreeFramesAgainstTheOccupiedOnes) {
  StaticPointSettings s;
  s.min_free_frames = 2;
  s.min_free_ratio = 0.25;
  EXPECT_FALSE(isDynamicVoxel({10, 0}, s));
  EXPECT_FALSE(isDynamicVoxel({1, 1}, s));   // one free frame is not enough
  EXPECT_TRUE(isDynamicVoxel({3, 2}, s));
  EXPECT_FALSE(isDynamicVoxel({40, 9}, s));  // a surface grazed now and then: 9 < 0.25 * 40
  EXPECT_TRUE(isDynamicVoxel({40, 10}, s));
}

TEST(StaticPoints, ABoxThatLeavesIsDroppedAndTheRoomKept) {
  const BoxRoom room = defaultRoom();
  const PinholeCamera camera{80, 60, 65.625, 65.625, 39.5, 29.5};
  const Box visitor{{0.8, -0.3, 0.0}, {1.1, 0.2, 1.7}, {}};
  std::vector<Frame> frames;
  size_t inserted_total = 0, valid_total = 0;
  for (size_t i = 0; i < 8; ++i) {
    Frame f = renderFrame(room, camera, lookHorizontal({-0.5, 0.0, 1.2}, 0.1 * static_cast<double>(i) - 0.35), 0.0014, i);
    if (i < 2) {
      std::vector<uint8_t> inserted;
      inserted_total += insertBoxesByDepth(f, camera, {visitor}, inserted, 0.0014, 100 + i);
    }
    for (const auto& p : f.cloud.points) valid_total += p.allFinite() ? 1 : 0;
    frames.push_back(std::move(f));
  }
  const FrameVector source(std::move(frames));
  StaticPointSettings s;
  s.threads = 2;
  const StaticPointResult r = staticPoints(source, s);
  EXPECT_EQ(r.frames, 8u);
  EXPECT_EQ(r.points_in, 8u * 80 * 60);
  EXPECT_EQ(r.points_in - r.points_invalid, valid_total);
  ASSERT_GT(inserted_total, 200u);
  // The visitor's points go (most of them), the room's stay (nearly all).
  EXPECT_GE(static_cast<double>(r.points_dynamic), 0.9 * static_cast<double>(inserted_total));
  EXPECT_LE(static_cast<double>(r.points_dynamic), static_cast<double>(inserted_total) + 0.01 * static_cast<double>(valid_total));
  EXPECT_EQ(r.points.points.size(), valid_total - r.points_dynamic);
  for (const auto& p : r.points.points) {
    EXPECT_FALSE(visitor.min_m.x() + 0.05 < p.x() && p.x() < visitor.max_m.x() - 0.05 && p.z() > 0.1 && p.z() < 1.6 &&
                 visitor.min_m.y() < p.y() && p.y() < visitor.max_m.y());
  }
  // One thread gives the same points.
  s.threads = 1;
  const StaticPointResult one = staticPoints(source, s);
  EXPECT_EQ(one.points.points, r.points.points);
}

/// A sheet of points at x (metres), y in [y0, y1], z in [z0, z1], 2 cm apart, kept where `keep` says.
void addSheet(std::vector<Eigen::Vector3f>& out, float x, float y0, float y1, float z0, float z1,
              const std::function<bool(float, float)>& keep = {}) {
  for (float y = y0; y <= y1 + 1e-4f; y += 0.02f) {
    for (float z = z0; z <= z1 + 1e-4f; z += 0.02f) {
      if (!keep || keep(y, z)) out.emplace_back(x, y, z);
    }
  }
}

TEST(StaticPoints, ThePartsOfAPersonNeverSeenFreeGoWithThePartsThatWere) {
  // Frame 0: a person (a sheet at x = 1 m) in front of a wall at x = 2 m (the wall behind it
  // hidden). Frames 1-5: the person gone; the wall returns only its lower half behind where the
  // person stood (a window above), so only the person's lowest quarter is ever seen free.
  auto wallAt = [](bool lower_only) {
    std::vector<Eigen::Vector3f> points;
    addSheet(points, 2.0f, -1.0f, 1.0f, 0.0f, 1.0f,
             [&](float y, float z) { return std::abs(y) > 0.45f || (lower_only && z < 0.5f); });
    return points;
  };
  std::vector<Frame> frames(6);
  std::vector<Eigen::Vector3f> person;
  addSheet(person, 1.0f, -0.2f, 0.2f, 0.0f, 1.0f);
  for (size_t i = 0; i < frames.size(); ++i) {
    frames[i].cloud.points = wallAt(i > 0);
    if (i == 0) frames[i].cloud.points.insert(frames[i].cloud.points.end(), person.begin(), person.end());
    frames[i].cloud.width = static_cast<uint32_t>(frames[i].cloud.points.size());
  }
  const FrameVector source(std::move(frames));
  StaticPointSettings s;
  s.spread_steps = 0;
  const StaticPointResult alone = staticPoints(source, s);
  EXPECT_GT(alone.points_dynamic, 0u);
  EXPECT_LT(alone.points_dynamic, person.size() * 2 / 5);
  s.spread_steps = 30;
  s.spread_fraction = 0.3;
  const StaticPointResult spread = staticPoints(source, s);
  EXPECT_GE(spread.points_dynamic, person.size() * 95 / 100);
  EXPECT_LE(spread.points_dynamic, person.size());  // the wall stays
}

// spreadDynamic looks only at the neighbours of the voxels the step before added; the slow
// reference looks at every occupied voxel on every step. Random frames (a 6-voxel block, at the
// key space's corner every other time), random seeds, steps and fractions: the same sets.
std::vector<uint64_t> spreadReference(const std::vector<uint64_t>& occupied, std::vector<uint64_t> dynamic, int steps,
                                      double fraction) {
  const std::set<uint64_t> in_frame(occupied.begin(), occupied.end());
  std::set<uint64_t> moving(dynamic.begin(), dynamic.end());
  for (int step = 0; step < steps; ++step) {
    std::vector<uint64_t> grown;
    for (uint64_t code : occupied) {
      if (moving.count(code)) continue;
      const VoxelKey k = mortonDecode(code);
      int neighbours = 0, dynamic_neighbours = 0;
      for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int x = k.x + dx, y = k.y + dy, z = k.z + dz;
            if ((dx == 0 && dy == 0 && dz == 0) || x < 0 || y < 0 || z < 0) continue;
            const uint64_t n = mortonEncode({static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)});
            if (!in_frame.count(n)) continue;
            ++neighbours;
            dynamic_neighbours += moving.count(n) ? 1 : 0;
          }
        }
      }
      if (dynamic_neighbours > 0 && dynamic_neighbours >= fraction * neighbours) grown.push_back(code);
    }
    if (grown.empty()) break;
    moving.insert(grown.begin(), grown.end());
  }
  return {moving.begin(), moving.end()};
}

TEST(StaticPoints, TheSpreadEqualsTheSlowReferenceOnRandomFrames) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  size_t grew = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const uint16_t base = trial % 2 ? 0 : 1000;
    const double density = 0.3 + 0.6 * unit(random), seeds = 0.05 + 0.3 * unit(random);
    std::vector<uint64_t> occupied, dynamic;
    for (uint16_t z = 0; z < 6; ++z) {
      for (uint16_t y = 0; y < 6; ++y) {
        for (uint16_t x = 0; x < 6; ++x) {
          if (unit(random) >= density) continue;
          const uint64_t code =
              mortonEncode({static_cast<uint16_t>(base + x), static_cast<uint16_t>(base + y), static_cast<uint16_t>(base + z)});
          occupied.push_back(code);
          if (unit(random) < seeds) dynamic.push_back(code);
        }
      }
    }
    std::sort(occupied.begin(), occupied.end());
    std::sort(dynamic.begin(), dynamic.end());
    const int steps = static_cast<int>(random() % 6);
    const double fraction = std::vector<double>{0.0, 0.3, 0.5, 0.7, 1.0}[random() % 5];
    const std::vector<uint64_t> fast = spreadDynamic(occupied, dynamic, steps, fraction);
    ASSERT_EQ(fast, spreadReference(occupied, dynamic, steps, fraction))
        << "trial " << trial << ", " << steps << " steps, fraction " << fraction;
    grew += fast.size() > dynamic.size() ? 1 : 0;
  }
  EXPECT_GT(grew, 50u) << "the random frames must exercise the spread";
}

}  // namespace
}  // namespace chronomap
