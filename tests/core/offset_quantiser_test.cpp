// The hit-position quantiser: its rounding without a library call against std::round.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "chronomap/core/offset_quantiser.h"

namespace chronomap {
namespace {

TEST(OffsetQuantiser, RoundsAsTheLibraryDoes) {
  // Halves, their neighbours either side and whole numbers, both signs, then random values.
  for (int i = -300; i <= 300; ++i) {
    for (const double base : {i + 0.5, static_cast<double>(i)}) {
      for (const double x : {base, std::nextafter(base, -1e9), std::nextafter(base, 1e9)}) {
        ASSERT_EQ(roundHalfAway(x), std::round(x)) << x;
      }
    }
  }
  EXPECT_EQ(roundHalfAway(0.49999999999999994), 0.0);  // the case trunc(x + 0.5) gets wrong
  EXPECT_EQ(roundHalfAway(-0.0), 0.0);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> any(-2147483648.0, 2147483648.0);
  for (int i = 0; i < 100000; ++i) {
    const double x = i % 2 ? any(rng) : any(rng) * 1e-7;
    ASSERT_EQ(roundHalfAway(x), std::round(x)) << x;
  }
}

TEST(OffsetQuantiser, BytesMatchTheReference) {
  // The reference: round(mean * 254) with std::round, clamped to -127..127, plus 127.
  auto reference = [](float sum, uint32_t hits) {
    if (hits == 0) return 127;
    const double q = std::round(static_cast<double>(sum) / hits * 254.0);
    return static_cast<int>(std::clamp(q, -127.0, 127.0) + 127);
  };
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<float> mean(-0.6f, 0.6f);
  for (int i = 0; i < 200000; ++i) {
    const uint32_t hits = 1 + static_cast<uint32_t>(rng() % (i % 3 ? 10 : 100000));
    const float sum = mean(rng) * static_cast<float>(hits);
    ASSERT_EQ(quantiseOffset(sum, hits), reference(sum, hits)) << sum << " over " << hits;
  }
  // Every byte's own offset (and the sums at the halves between bytes) comes back to it.
  for (int q = 0; q <= 254; ++q) {
    for (const uint32_t hits : {1u, 3u, 1000u}) {
      const float sum = dequantiseOffset(static_cast<uint8_t>(q), hits);
      EXPECT_EQ(quantiseOffset(sum, hits), reference(sum, hits));
      EXPECT_EQ(quantiseOffset(sum, hits), q);
    }
  }
  EXPECT_EQ(quantiseOffset(0.0f, 0), 127);
  EXPECT_EQ(quantiseOffset(1e30f, 1), 254);
  EXPECT_EQ(quantiseOffset(-1e30f, 1), 0);
}

}  // namespace
}  // namespace chronomap
