// The dynamic-map benchmark's scores (hand-made clouds with known SA and DA, the fast lookup
// against the brute-force reference), walkers and boxes drawn in by depth.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "chronomap/core/error.h"
#include "chronomap/sim/box_room.h"
#include "chronomap/sim/dynamic_map.h"

namespace chronomap {
namespace {

PointCloud cloudOf(const std::vector<Eigen::Vector3f>& points) {
  PointCloud c;
  c.points = points;
  c.width = static_cast<uint32_t>(points.size());
  return c;
}

TEST(DynamicMapScores, HandMadeCloudsGiveTheKnownScores) {
  // Four static points, two dynamic, one with another label (counted in neither).
  const PointCloud truth = cloudOf({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {5, 0, 0}, {6, 0, 0}, {7, 0, 0}});
  const std::vector<float> labels = {0, 0, 0, 0, 1, 1, 2};
  // Within 0.05 m of static 0, 1 and 3 (0.03, 0.049, 0.042 m away), 0.051 m from static 2;
  // 0.01 m from dynamic 5 (kept: not removed); nothing near dynamic 6.
  const PointCloud map = cloudOf({{0, 0, 0.03f}, {1, 0, 0.049f}, {2, 0, 0.051f}, {3, 0.03f, 0.03f}, {5, 0, 0.01f},
                                  {7, 0, 0}});
  for (const StaticMapScores& s : {scoreStaticMap(truth, labels, map), scoreStaticMapBruteForce(truth, labels, map)}) {
    EXPECT_EQ(s.static_total, 4u);
    EXPECT_EQ(s.dynamic_total, 2u);
    EXPECT_EQ(s.unlabelled, 1u);
    EXPECT_EQ(s.static_kept, 3u);
    EXPECT_EQ(s.dynamic_removed, 1u);
    EXPECT_DOUBLE_EQ(s.staticAccuracy(), 0.75);
    EXPECT_DOUBLE_EQ(s.dynamicAccuracy(), 0.5);
    EXPECT_NEAR(s.associatedAccuracy(), std::sqrt(0.375), 1e-12);
    EXPECT_NEAR(s.harmonicAccuracy(), 0.6, 1e-12);
  }
  // An empty map removes everything: SA 0, DA 1, HA 0.
  const StaticMapScores none = scoreStaticMap(truth, labels, PointCloud{});
  EXPECT_EQ(none.staticAccuracy(), 0.0);
  EXPECT_EQ(none.dynamicAccuracy(), 1.0);
  EXPECT_EQ(none.harmonicAccuracy(), 0.0);
  EXPECT_THROW(scoreStaticMap(truth, {0, 1}, map), UsageError);
}

TEST(DynamicMapScores, TheHashLookupAgreesWithTheBruteForceReference) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  std::vector<Eigen::Vector3f> t, m;
  std::vector<float> labels;
  for (int i = 0; i < 1500; ++i) {
    t.emplace_back(u(rng), u(rng), u(rng));
    labels.push_back(i % 3 == 0 ? 1.0f : 0.0f);
    m.emplace_back(u(rng), u(rng), u(rng));
  }
  for (double radius : {0.02, 0.05, 0.1}) {
    const StaticMapScores fast = scoreStaticMap(cloudOf(t), labels, cloudOf(m), radius);
    const StaticMapScores slow = scoreStaticMapBruteForce(cloudOf(t), labels, cloudOf(m), radius);
    EXPECT_EQ(fast.static_kept, slow.static_kept) << radius;
    EXPECT_EQ(fast.dynamic_removed, slow.dynamic_removed) << radius;
    EXPECT_GT(slow.static_kept, 0u);
    EXPECT_LT(slow.static_kept, slow.static_total);
  }
}

TEST(DynamicMapSim, WalkersGoBackAndForthAndBoxesAreDrawnInByDepth) {
  Walker w;
  w.from_m = {0, 0, 0};
  w.to_m = {2, 0, 0};
  w.speed_mps = 1.0;
  EXPECT_NEAR(walkerBox(w, 0.5).min_m.x(), 0.5 - 0.225, 1e-12);
  EXPECT_NEAR(walkerBox(w, 3.0).min_m.x(), 1.0 - 0.225, 1e-12);  // 3 m walked: on the way back
  EXPECT_NEAR(walkerBox(w, 3.0).max_m.z(), 1.75, 1e-12);
  // A camera in the box room looking along +x at a box 1 m ahead: the box replaces the wall
  // (2.2 m ahead) in the middle of the image, and a box behind the wall is never drawn.
  PinholeCamera camera{40, 30, 26.25, 26.25, 19.5, 14.5};
  BoxRoom empty;
  empty.bounds = defaultRoom().bounds;
  Frame frame = renderFrame(empty, camera, lookHorizontal({0, 0, 1.2}, 0.0));
  std::vector<uint8_t> inserted;
  const Box near{{0.9, -0.2, 0.0}, {1.2, 0.2, 1.8}, {}};
  const Box behind{{3.0, -1, 0.0}, {3.5, 1, 1.8}, {}};
  const size_t replaced = insertBoxesByDepth(frame, camera, {near, behind}, inserted);
  EXPECT_GT(replaced, 20u);
  EXPECT_EQ(replaced, static_cast<size_t>(std::count(inserted.begin(), inserted.end(), 1)));
  const size_t centre = 14 * 40 + 19;
  EXPECT_EQ(inserted[centre], 1);
  EXPECT_NEAR(frame.cloud.points[centre].z(), 0.9f, 1e-4);
  EXPECT_EQ(inserted[0], 0);
}

}  // namespace
}  // namespace chronomap
