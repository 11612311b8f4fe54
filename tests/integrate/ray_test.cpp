// The DDA against two slow references: exact clipping of the segment against every voxel of its
// bounding box, and dense sampling along the segment.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include "chronomap/integrate/ray.h"

namespace chronomap {
namespace {

using Cell = std::tuple<int64_t, int64_t, int64_t>;

std::map<Cell, double> dda(const double o[3], const double p[3], Cell* last_cell = nullptr, int* lasts = nullptr) {
  std::map<Cell, double> out;
  traverseRay(o, p, [&](int64_t x, int64_t y, int64_t z, double len, bool last) {
    out[{x, y, z}] += len;
    if (last) {
      if (last_cell) *last_cell = {x, y, z};
      if (lasts) ++*lasts;
    }
  });
  return out;
}

/// Exact reference: clip the segment against each voxel box of its bounding box.
std::map<Cell, double> clipReference(const double o[3], const double p[3]) {
  std::map<Cell, double> out;
  const double d[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
  const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  int64_t lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = static_cast<int64_t>(std::floor(std::min(o[a], p[a])));
    hi[a] = static_cast<int64_t>(std::floor(std::max(o[a], p[a])));
  }
  for (int64_t x = lo[0]; x <= hi[0]; ++x) {
    for (int64_t y = lo[1]; y <= hi[1]; ++y) {
      for (int64_t z = lo[2]; z <= hi[2]; ++z) {
        const int64_t c[3] = {x, y, z};
        double t0 = 0.0, t1 = 1.0;
        for (int a = 0; a < 3; ++a) {
          if (d[a] == 0.0) {
            if (o[a] < c[a] || o[a] >= c[a] + 1) t1 = -1.0;
            continue;
          }
          double ta = (c[a] - o[a]) / d[a], tb = (c[a] + 1 - o[a]) / d[a];
          if (ta > tb) std::swap(ta, tb);
          t0 = std::max(t0, ta);
          t1 = std::min(t1, tb);
        }
        if (t1 > t0) out[{x, y, z}] = (t1 - t0) * len;
      }
    }
  }
  return out;
}

TEST(Ray, AxisAlignedRayHasKnownLengths) {
  const double o[3] = {0.5, 0.5, 0.5}, p[3] = {4.25, 0.5, 0.5};
  Cell last;
  auto r = dda(o, p, &last);
  ASSERT_EQ(r.size(), 5u);
  EXPECT_NEAR((r[{0, 0, 0}]), 0.5, 1e-12);
  for (int x = 1; x <= 3; ++x) EXPECT_NEAR((r[{x, 0, 0}]), 1.0, 1e-12);
  EXPECT_NEAR((r[{4, 0, 0}]), 0.25, 1e-12);
  EXPECT_EQ(last, (Cell{4, 0, 0}));
}

TEST(Ray, NegativeDirectionAndSingleVoxel) {
  const double o[3] = {3.5, 2.2, 1.1}, p[3] = {0.25, 2.2, 1.1};
  auto r = dda(o, p);
  EXPECT_EQ(r.size(), 4u);
  EXPECT_NEAR((r[{0, 2, 1}]), 0.75, 1e-12);
  EXPECT_NEAR((r[{3, 2, 1}]), 0.5, 1e-12);
  const double q[3] = {3.9, 2.2, 1.1};
  auto single = dda(o, q);
  ASSERT_EQ(single.size(), 1u);
  EXPECT_NEAR((single[{3, 2, 1}]), 0.4, 1e-12);
}

TEST(Ray, DiagonalLengthsSumToTheRayLength) {
  const double o[3] = {0.5, 0.5, 0.5}, p[3] = {3.5, 3.5, 3.5};
  Cell last;
  auto r = dda(o, p, &last);
  double sum = 0.0;
  for (auto& [cell, len] : r) {
    sum += len;
    if (len > 1e-9) {  // every voxel with a real segment lies on the diagonal
      EXPECT_EQ(std::get<0>(cell), std::get<1>(cell));
      EXPECT_EQ(std::get<1>(cell), std::get<2>(cell));
    }
  }
  EXPECT_NEAR(sum, 3.0 * std::sqrt(3.0), 1e-12);
  EXPECT_NEAR((r[{1, 1, 1}]), std::sqrt(3.0), 1e-9);
  EXPECT_EQ(last, (Cell{3, 3, 3}));
}

TEST(Ray, ZeroLengthRayVisitsItsVoxelOnce) {
  const double o[3] = {1.5, 1.5, 1.5};
  int lasts = 0;
  auto r = dda(o, o, nullptr, &lasts);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(lasts, 1);
  EXPECT_EQ((r[{1, 1, 1}]), 0.0);
}

class RandomRays : public ::testing::TestWithParam<int> {};

TEST_P(RandomRays, MatchExactClippingReference) {
  std::mt19937_64 rng(static_cast<uint64_t>(GetParam()));
  std::uniform_real_distribution<double> pos(100.0, 120.0), dir(-1.0, 1.0), len(0.0, 15.0);
  for (int i = 0; i < 1000; ++i) {
    double o[3], p[3], d[3];
    for (int a = 0; a < 3; ++a) o[a] = pos(rng);
    double n = 0;
    for (int a = 0; a < 3; ++a) {
      d[a] = dir(rng);
      n += d[a] * d[a];
    }
    const double l = len(rng);
    for (int a = 0; a < 3; ++a) p[a] = o[a] + d[a] / std::sqrt(n) * l;
    if (i % 10 == 0) p[1] = o[1];  // some rays in axis planes
    Cell last;
    int lasts = 0;
    auto fast = dda(o, p, &last, &lasts);
    auto ref = clipReference(o, p);
    EXPECT_EQ(lasts, 1);
    EXPECT_EQ(last, (Cell{static_cast<int64_t>(std::floor(p[0])), static_cast<int64_t>(std::floor(p[1])),
                          static_cast<int64_t>(std::floor(p[2]))}));
    const double tol = 1e-9 * (1.0 + l);
    double sum = 0.0;
    for (auto& [cell, v] : fast) {
      sum += v;
      auto it = ref.find(cell);
      const double expected = it == ref.end() ? 0.0 : it->second;
      EXPECT_NEAR(v, expected, tol) << "ray " << i;
    }
    for (auto& [cell, v] : ref) {
      if (v > tol) {
        EXPECT_TRUE(fast.count(cell)) << "ray " << i << " missed a voxel with length " << v;
      }
    }
    double true_len = 0;
    for (int a = 0; a < 3; ++a) true_len += (p[a] - o[a]) * (p[a] - o[a]);
    EXPECT_NEAR(sum, std::sqrt(true_len), tol);
  }
}

TEST_P(RandomRays, MatchDenseSamplingReference) {
  std::mt19937_64 rng(static_cast<uint64_t>(GetParam()) + 77);
  std::uniform_real_distribution<double> pos(-20.0, 20.0), off(-8.0, 8.0);
  constexpr int kSamples = 4000;
  for (int i = 0; i < 500; ++i) {
    double o[3], p[3];
    for (int a = 0; a < 3; ++a) {
      o[a] = pos(rng);
      p[a] = o[a] + off(rng);
    }
    auto fast = dda(o, p);
    std::map<Cell, double> sampled;
    double l = 0;
    for (int a = 0; a < 3; ++a) l += (p[a] - o[a]) * (p[a] - o[a]);
    l = std::sqrt(l);
    for (int s = 0; s < kSamples; ++s) {
      const double t = (s + 0.5) / kSamples;
      Cell c{static_cast<int64_t>(std::floor(o[0] + t * (p[0] - o[0]))),
             static_cast<int64_t>(std::floor(o[1] + t * (p[1] - o[1]))),
             static_cast<int64_t>(std::floor(o[2] + t * (p[2] - o[2])))};
      sampled[c] += l / kSamples;
    }
    const double tol = 2.0 * l / kSamples + 1e-9;
    for (auto& [cell, v] : sampled) EXPECT_NEAR(fast[cell], v, tol) << "ray " << i;
    for (auto& [cell, v] : fast) EXPECT_NEAR(sampled[cell], v, tol) << "ray " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, RandomRays, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace chronomap
