#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "chronomap/core/error.h"
#include "chronomap/integrate/integrator.h"
#include "test_support.h"

namespace chronomap {
namespace {

/// An organized cloud of `w` x `h` pixels looking down +x: pixel (c, r) at range depth(c, r)
/// along its own direction (0: no depth, a NaN point).
template <typename Depth>
PointCloud depthCloud(uint32_t w, uint32_t h, Depth depth) {
  PointCloud cloud;
  cloud.width = w;
  cloud.height = h;
  for (uint32_t r = 0; r < h; ++r) {
    for (uint32_t c = 0; c < w; ++c) {
      const Eigen::Vector3f dir = Eigen::Vector3f(1.0f, 0.01f * (float(c) - w / 2.0f), 0.01f * (float(r) - h / 2.0f))
                                      .normalized();
      const float d = depth(c, r);
      cloud.points.push_back(d > 0 ? Eigen::Vector3f(d * dir)
                                   : Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
    }
  }
  return cloud;
}

/// The slow reference: every pair of valid pixels within one row and one column of each other.
std::vector<uint8_t> referenceMask(const PointCloud& cloud, double ratio) {
  const int w = static_cast<int>(cloud.width), h = static_cast<int>(cloud.height);
  std::vector<uint8_t> drop(cloud.size(), 0);
  const auto range = [&](int i) -> double {
    const Eigen::Vector3f& p = cloud.points[static_cast<size_t>(i)];
    return p.allFinite() && p.norm() > 0 ? p.norm() : 0.0;
  };
  for (int i = 0; i < w * h; ++i) {
    for (int j = 0; j < w * h; ++j) {
      if (i == j || std::abs(i % w - j % w) > 1 || std::abs(i / w - j / w) > 1) continue;
      const double a = range(i), b = range(j);
      if (a > 0 && b > 0 && std::abs(a - b) > ratio * a) drop[static_cast<size_t>(i)] = 1;
    }
  }
  return drop;
}

TEST(DepthEdges, AFlatWallKeepsEveryPoint) {
  const PointCloud wall = depthCloud(12, 9, [](uint32_t, uint32_t) { return 2.0f; });
  const std::vector<uint8_t> mask = depthEdgeMask(wall, 0.05);
  ASSERT_EQ(mask.size(), wall.size());
  for (uint8_t m : mask) EXPECT_EQ(m, 0);
}

TEST(DepthEdges, AStepLosesOnePixelOnEachSideAndAFlyingPixelBetween) {
  // Columns 0-4 at 1 m, column 5 a flying pixel at 2 m, columns 6-11 at 3 m.
  const PointCloud step = depthCloud(12, 6, [](uint32_t c, uint32_t) { return c < 5 ? 1.0f : c == 5 ? 2.0f : 3.0f; });
  const std::vector<uint8_t> mask = depthEdgeMask(step, 0.05);
  for (uint32_t r = 0; r < 6; ++r) {
    for (uint32_t c = 0; c < 12; ++c) {
      EXPECT_EQ(mask[r * 12 + c], c >= 4 && c <= 6 ? 1 : 0) << "column " << c << ", row " << r;
    }
  }
}

TEST(DepthEdges, MissingDepthIsNotAnEdgeAndUnorganizedCloudsAreLeftAlone) {
  // A hole (no depth) in a wall: its neighbours keep their points.
  const PointCloud holed = depthCloud(8, 8, [](uint32_t c, uint32_t r) { return c == 4 && r == 4 ? 0.0f : 2.0f; });
  for (uint8_t m : depthEdgeMask(holed, 0.05)) EXPECT_EQ(m, 0);
  PointCloud flat = depthCloud(8, 1, [](uint32_t c, uint32_t) { return c < 4 ? 1.0f : 3.0f; });
  EXPECT_TRUE(depthEdgeMask(flat, 0.05).empty());  // one row: not organized
  EXPECT_TRUE(depthEdgeMask(holed, 0.0).empty());  // off
  flat.height = 2;                                  // 8 x 2 != 8 points
  EXPECT_TRUE(depthEdgeMask(flat, 0.05).empty());
}

TEST(DepthEdges, MatchesTheSlowReferenceOnRandomDepthImages) {
  std::mt19937 rng(46);
  std::uniform_real_distribution<float> depth(0.5f, 4.0f);
  std::uniform_int_distribution<int> kind(0, 9);
  for (int trial = 0; trial < 60; ++trial) {
    const uint32_t w = 3 + rng() % 14, h = 2 + rng() % 10;
    // Patches of equal depth with holes and random steps.
    std::vector<float> d(w * h);
    float level = depth(rng);
    for (float& v : d) {
      const int k = kind(rng);
      if (k == 0) level = depth(rng);
      v = k == 1 ? 0.0f : level * (1.0f + 0.01f * (kind(rng) - 5) / 5.0f);
    }
    const PointCloud cloud = depthCloud(w, h, [&](uint32_t c, uint32_t r) { return d[r * w + c]; });
    for (double ratio : {0.015, 0.05, 0.2}) {  // away from the patches' 0.2% depth steps
      ASSERT_EQ(depthEdgeMask(cloud, ratio), referenceMask(cloud, ratio)) << "trial " << trial << ", ratio " << ratio;
    }
  }
}

TEST(DepthEdges, IntegrationDropsAFlyingPixelAndCountsIt) {
  // A wall 3 m away seen by 10 x 10 pixels, one of them flying halfway to it.
  const PointCloud cloud = depthCloud(10, 10, [](uint32_t c, uint32_t r) { return c == 5 && r == 5 ? 1.5f : 3.0f; });
  Frame frame;
  frame.cloud = cloud;
  frame.source = "flying pixel";
  const Eigen::Vector3f flying = cloud.points[5 * 10 + 5];
  for (double ratio : {0.0, 0.05}) {
    SessionMap map(0.05);
    IntegratorSettings s;
    s.max_range_m = 5.0;
    s.threads = 1;
    s.depth_edge_ratio = ratio;
    const IntegrationStats st = integrate(FrameVector({frame}), map, s);
    const VoxelKey key = *map.grid().keyOf(flying.cast<double>());
    const auto counters = map.find(key);
    EXPECT_EQ(st.points + st.pointsSkipped(), 100u);
    if (ratio == 0.0) {
      EXPECT_EQ(st.points_depth_edges, 0u);
      ASSERT_TRUE(counters.has_value());
      EXPECT_GT(counters->hits, 0u);
    } else {
      // The flying pixel, and the wall pixels around it that are compared with it.
      EXPECT_EQ(st.points_depth_edges, 9u);
      EXPECT_EQ(st.points_invalid, 0u);
      EXPECT_TRUE(!counters || counters->hits == 0u);
    }
  }
}

TEST(DepthEdges, ABadRatioIsAUsageError) {
  SessionMap map(0.05);
  IntegratorSettings s;
  s.depth_edge_ratio = -0.1;
  EXPECT_THROW(integrate(FrameVector({}), map, s), UsageError);
  s.depth_edge_ratio = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(integrate(FrameVector({}), map, s), UsageError);
}

}  // namespace
}  // namespace chronomap
