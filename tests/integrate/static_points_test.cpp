// Static points: a box that stands in the room for a few frames and is gone in the others is
// dropped, the room is kept; the voxel rule on its own.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

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

}  // namespace
}  // namespace chronomap
