// Fast mode's bundle-ray lanes (src/integrate/bundle_rays.h) against the single-ray DDA of
// ray.h: one ray alone makes exactly the DDA's cells and lengths; many rays make the same sums
// up to the order of float additions; the AVX2 and portable lanes make the same calls.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "chronomap/integrate/ray.h"
#include "integrate/bundle_rays.h"

namespace chronomap {
namespace {

struct Ray {
  double o[3], end[3];
  float weight;
};

// Cells are indexed in a 256^3 grid with lo = 0: index x + 256 y + 65536 z.
constexpr int64_t kLo[3] = {0, 0, 0};
constexpr int64_t kStride[3] = {1, 256, 65536};

int64_t indexOf(int64_t x, int64_t y, int64_t z) { return x * kStride[0] + y * kStride[1] + z * kStride[2]; }

using Calls = std::vector<std::pair<int64_t, float>>;

Calls castLanes(const std::vector<Ray>& rays, bool simd) {
  Calls calls;
  size_t i = 0;
  detail::castBundleLanes(
      [&](detail::LaneRay& r) {
        if (i >= rays.size()) return false;
        r = detail::laneRay(rays[i].o, rays[i].end, rays[i].weight, kLo, kStride);
        ++i;
        return true;
      },
      [&](int64_t c, float v) { calls.emplace_back(c, v); }, simd);
  return calls;
}

/// The reference: ray.h's DDA, one ray after another, weight * length per cell.
Calls castOneByOne(const std::vector<Ray>& rays) {
  Calls calls;
  for (const Ray& r : rays) {
    traverseRay(r.o, r.end, [&](int64_t x, int64_t y, int64_t z, double len, bool) {
      calls.emplace_back(indexOf(x, y, z), r.weight * static_cast<float>(len));
    });
  }
  return calls;
}

/// Random rays from points inside the grid to voxel centres at most `reach` voxels away.
std::vector<Ray> randomRays(uint32_t seed, size_t n, int reach) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(100.0, 156.0);
  std::uniform_int_distribution<int> off(-reach, reach);
  std::uniform_int_distribution<int> weight(1, 40);
  std::vector<Ray> rays(n);
  for (Ray& r : rays) {
    for (int a = 0; a < 3; ++a) {
      r.o[a] = pos(rng);
      r.end[a] = std::floor(r.o[a]) + off(rng) + 0.5;
    }
    r.weight = static_cast<float>(weight(rng));
  }
  return rays;
}

std::map<int64_t, double> sums(const Calls& calls) {
  std::map<int64_t, double> out;
  for (const auto& [c, v] : calls) out[c] += v;
  return out;
}

TEST(BundleLanes, OneRayAloneIsExactlyTheSingleRayDda) {
  const std::vector<Ray> rays = randomRays(7, 3000, 60);
  for (const Ray& r : rays) {
    for (bool simd : {false, true}) {
      const Calls lanes = castLanes({r}, simd);
      const Calls ref = castOneByOne({r});
      ASSERT_EQ(lanes, ref) << "simd=" << simd;
    }
  }
}

TEST(BundleLanes, KnownRays) {
  // Along +x from the middle of cell (2,3,4) to the centre of (6,3,4): 0.5, 1, 1, 1, 0.5 (x2).
  const Ray along{{2.5, 3.5, 4.5}, {6.5, 3.5, 4.5}, 2.0f};
  const Calls a = castLanes({along}, true);
  ASSERT_EQ(a.size(), 5u);
  const float expect[5] = {1.0f, 2.0f, 2.0f, 2.0f, 1.0f};
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(a[k].first, indexOf(2 + k, 3, 4));
    EXPECT_FLOAT_EQ(a[k].second, expect[k]);
  }
  // Through cell corners: the crossings of all three axes tie; x goes first, then y, then z,
  // as in ray.h. Four cells per corner passed, lengths summing to the ray's length.
  const Ray diagonal{{0.5, 0.5, 0.5}, {3.5, 3.5, 3.5}, 1.0f};
  const Calls d = castLanes({diagonal}, true);
  ASSERT_EQ(d.size(), 10u);
  EXPECT_EQ(d[1].first, indexOf(1, 0, 0));
  EXPECT_EQ(d[2].first, indexOf(1, 1, 0));
  EXPECT_EQ(d[3].first, indexOf(1, 1, 1));
  double total = 0;
  for (const auto& c : d) total += c.second;
  EXPECT_NEAR(total, 3.0 * std::sqrt(3.0), 1e-5);
  // Origin and end in one cell: one call with the whole length.
  const Ray inside{{5.2, 5.9, 5.1}, {5.5, 5.5, 5.5}, 3.0f};
  const Calls s = castLanes({inside}, true);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].first, indexOf(5, 5, 5));
  EXPECT_FLOAT_EQ(s[0].second, 3.0f * static_cast<float>(std::sqrt(0.09 + 0.16 + 0.16)));
}

TEST(BundleLanes, ManyRaysSumLikeTheSingleRayDda) {
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    // Short reaches make rays of very different lengths and many without crossings.
    const std::vector<Ray> rays = randomRays(seed, 500, seed % 2 ? 3 : 60);
    const Calls lanes = castLanes(rays, true);
    const Calls ref = castOneByOne(rays);
    // Every (cell, value) call is the reference's, in another order.
    Calls a = lanes, b = ref;
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    ASSERT_EQ(a, b) << "seed " << seed;
    const auto sa = sums(lanes), sb = sums(ref);
    ASSERT_EQ(sa.size(), sb.size());
    for (const auto& [c, v] : sb) EXPECT_NEAR(sa.at(c), v, 1e-9 * (1.0 + v));
  }
}

TEST(BundleLanes, VectorAndPortableLanesMakeTheSameCalls) {
  if (!detail::avx2Lanes()) {
    std::printf("this CPU has no AVX2: both runs take the portable lanes\n");
  }
  for (uint32_t seed = 1; seed <= 10; ++seed) {
    const std::vector<Ray> rays = randomRays(100 + seed, 1000, seed % 3 ? 60 : 2);
    EXPECT_EQ(castLanes(rays, true), castLanes(rays, false)) << "seed " << seed;
  }
  EXPECT_TRUE(castLanes({}, true).empty());
}

}  // namespace
}  // namespace chronomap
