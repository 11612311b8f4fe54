// Static points: a box that stands in the room for a few frames and is gone in the others is
// dropped, the room is kept; the voxel rule on its own.

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace chronomap
