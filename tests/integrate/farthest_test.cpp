// The farthest point of a frame (src/integrate/farthest.h) against the scalar loop over Eigen's
// squaredNorm() it replaces: the same float, bit for bit, on random clouds with invalid points
// and at every length (the vector loop's tail and its two halves); stopping at the range gives
// the same reach.

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "integrate/farthest.h"

namespace chronomap {
namespace {

// The loop setUp() ran before: Eigen's squaredNorm, NaN and infinity left out.
float farthestByEigen(const std::vector<Eigen::Vector3f>& points) {
  float best = 0.0f;
  for (const Eigen::Vector3f& p : points) {
    const float r2 = p.squaredNorm();
    if (r2 > best && r2 <= std::numeric_limits<float>::max()) best = r2;
  }
  return best;
}

float farthestFast(const std::vector<Eigen::Vector3f>& points) {
  return integrate_detail::farthestSquaredNorm(points.empty() ? nullptr : points[0].data(), points.size());
}

TEST(Farthest, KnownPoints) {
  EXPECT_EQ(farthestFast({}), 0.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  std::vector<Eigen::Vector3f> points(11, Eigen::Vector3f(0.5f, 0.0f, 0.0f));
  points[3] = {1.0f, 2.0f, 2.0f};  // 9
  points[5] = {nan, 0.0f, 0.0f};
  points[6] = {inf, 0.0f, 0.0f};
  points[9] = {0.0f, 0.0f, 2e19f};  // its square overflows to infinity
  EXPECT_EQ(farthestFast(points), 9.0f);
  points[10] = {0.0f, -4.0f, 0.0f};  // in the scalar tail
  EXPECT_EQ(farthestFast(points), 16.0f);
  points[1] = {0.0f, 0.0f, -5.0f};  // in the second half of the vector loop's first step
  EXPECT_EQ(farthestFast(points), 25.0f);
  // Nothing valid.
  EXPECT_EQ(farthestFast(std::vector<Eigen::Vector3f>(9, Eigen::Vector3f(nan, nan, nan))), 0.0f);
}

TEST(Farthest, SameFloatAsTheScalarLoopOnRandomClouds) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(-6.0f, 6.0f);
  std::uniform_int_distribution<int> kind(0, 40);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (int trial = 0; trial < 400; ++trial) {
    const size_t n = static_cast<size_t>(trial < 40 ? trial : std::uniform_int_distribution<int>(0, 3000)(rng));
    std::vector<Eigen::Vector3f> points(n);
    for (Eigen::Vector3f& p : points) {
      p = {coord(rng), coord(rng), coord(rng)};
      switch (kind(rng)) {
        case 0: p.x() = nan; break;
        case 1: p.z() = -inf; break;
        case 2: p.y() = 3e19f; break;                            // overflows when squared
        case 3: p *= 1e-22f; break;                              // squares below float's normals
        case 4: p = {p.x(), std::nextafter(p.x(), 0.0f), -p.x()}; break;  // ties in rounding
        default: break;
      }
    }
    const float want = farthestByEigen(points), got = farthestFast(points);
    ASSERT_EQ(std::bit_cast<uint32_t>(got), std::bit_cast<uint32_t>(want))
        << "trial " << trial << ", " << n << " points";
  }
}

// What setUp() makes of it: the reach, the range when a point lies at it or beyond.
double reachOf(float farthest_sq, double range_m) {
  return std::min(range_m, std::sqrt(static_cast<double>(farthest_sq)));
}

TEST(Farthest, StoppingAtTheRangeGivesTheSameReach) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coord(-4.0f, 4.0f);
  std::uniform_real_distribution<double> range(0.5, 14.0);
  size_t stopped = 0, whole = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const size_t n = static_cast<size_t>(std::uniform_int_distribution<int>(0, 2000)(rng));
    std::vector<Eigen::Vector3f> points(n);
    for (Eigen::Vector3f& p : points) p = {coord(rng), coord(rng), coord(rng)};
    const double r = trial % 5 == 0 && n > 0 ? std::sqrt(static_cast<double>(points[n / 2].squaredNorm())) : range(rng);
    const float stop = integrate_detail::rangeStop(r);
    const float all = farthestByEigen(points);
    const float got = integrate_detail::farthestSquaredNorm(n ? points[0].data() : nullptr, n, stop);
    ASSERT_EQ(reachOf(got, r), reachOf(all, r)) << "trial " << trial;
    ASSERT_LE(got, all);
    if (got >= stop) {
      ++stopped;
    } else {
      ++whole;
      ASSERT_EQ(std::bit_cast<uint32_t>(got), std::bit_cast<uint32_t>(all)) << "trial " << trial;
    }
  }
  EXPECT_GT(stopped, 50u);  // both ways taken
  EXPECT_GT(whole, 50u);
}

TEST(Farthest, RangeStopIsTheLeastFloatAtTheRange) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> exponent(-3.0, 15.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const double r = std::pow(10.0, exponent(rng));
    const float stop = integrate_detail::rangeStop(r);
    ASSERT_GE(std::sqrt(static_cast<double>(stop)), r) << r;
    ASSERT_LT(std::sqrt(static_cast<double>(std::nextafter(stop, 0.0f))), r) << r;
  }
  EXPECT_EQ(integrate_detail::rangeStop(1e30), std::numeric_limits<float>::infinity());
  EXPECT_EQ(integrate_detail::rangeStop(std::numeric_limits<double>::max()), std::numeric_limits<float>::infinity());
  EXPECT_EQ(integrate_detail::rangeStop(3.0), 9.0f);
}

}  // namespace
}  // namespace chronomap
