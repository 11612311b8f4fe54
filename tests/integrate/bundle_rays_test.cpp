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
  integrate_detail::castBundleLanes(
      [&](integrate_detail::LaneRay& r) {
        if (i >= rays.size()) return false;
        r = integrate_detail::laneRay(rays[i].o, rays[i].end, rays[i].weight, kLo, kStride);
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
  if (!integrate_detail::avx2Lanes()) {
    std::printf("this CPU has no AVX2: both runs take the portable lanes\n");
  }
  for (uint32_t seed = 1; seed <= 10; ++seed) {
    const std::vector<Ray> rays = randomRays(100 + seed, 1000, seed % 3 ? 60 : 2);
    EXPECT_EQ(castLanes(rays, true), castLanes(rays, false)) << "seed " << seed;
  }
  EXPECT_TRUE(castLanes({}, true).empty());
}


// Coarse carving (splitCarvedRay, IntegratorSettings::carve_level): the lanes against a slow
// reference that clips the ray against every coarse cell and unit voxel of its bounding box.

/// The reference for one ray: where it enters the near box (the coarse cells within one of its
/// end voxel's coarse cell; coarse cell of voxel u: floor((u + shift) / 2^level)), the length of
/// the part before that inside every coarse cell and of the rest inside every unit voxel, in
/// voxel units times the weight. Cells are indexed as in the lanes' grids (kLo, kStride).
void carveReference(const Ray& r, int level, const int64_t shift[3], std::map<int64_t, double>& coarse,
                    std::map<int64_t, double>& fine) {
  const double side = std::ldexp(1.0, level);
  double d[3], lo[3], hi[3];
  double len2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    d[a] = r.end[a] - r.o[a];
    len2 += d[a] * d[a];
    const double c = std::floor((std::floor(r.end[a]) + static_cast<double>(shift[a])) / side);
    lo[a] = (c - 1) * side - static_cast<double>(shift[a]);
    hi[a] = (c + 2) * side - static_cast<double>(shift[a]);
  }
  const double len = std::sqrt(len2);
  double t_s = 0.0;
  for (int a = 0; a < 3; ++a) {
    if (r.o[a] < lo[a]) t_s = std::max(t_s, (lo[a] - r.o[a]) / d[a]);
    if (r.o[a] >= hi[a]) t_s = std::max(t_s, (hi[a] - r.o[a]) / d[a]);
  }
  // Length of the part [t0, t1] of the ray inside the box [b0, b1).
  auto clip = [&](double t0, double t1, const double b0[3], const double b1[3]) {
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0.0) {
        if (r.o[a] < b0[a] || r.o[a] >= b1[a]) return 0.0;
        continue;
      }
      double u = (b0[a] - r.o[a]) / d[a], v = (b1[a] - r.o[a]) / d[a];
      if (u > v) std::swap(u, v);
      t0 = std::max(t0, u);
      t1 = std::min(t1, v);
    }
    return t1 > t0 ? (t1 - t0) * len * r.weight : 0.0;
  };
  auto walk = [&](double t0, double t1, double cell, const int64_t off[3], std::map<int64_t, double>& out) {
    int64_t c0[3], c1[3];
    for (int a = 0; a < 3; ++a) {
      const double p = r.o[a] + t0 * d[a], q = r.o[a] + t1 * d[a];
      c0[a] = static_cast<int64_t>(std::floor((std::min(p, q) + static_cast<double>(off[a])) / cell)) - 1;
      c1[a] = static_cast<int64_t>(std::floor((std::max(p, q) + static_cast<double>(off[a])) / cell)) + 1;
    }
    for (int64_t z = c0[2]; z <= c1[2]; ++z) {
      for (int64_t y = c0[1]; y <= c1[1]; ++y) {
        for (int64_t x = c0[0]; x <= c1[0]; ++x) {
          const int64_t c[3] = {x, y, z};
          double b0[3], b1[3];
          for (int a = 0; a < 3; ++a) {
            b0[a] = static_cast<double>(c[a]) * cell - static_cast<double>(off[a]);
            b1[a] = b0[a] + cell;
          }
          const double l = clip(t0, t1, b0, b1);
          if (l > 0.0) out[indexOf(x, y, z)] += l;
        }
      }
    }
  };
  const int64_t none[3] = {0, 0, 0};
  if (t_s > 0.0) walk(0.0, t_s, side, shift, coarse);
  walk(t_s, 1.0, 1.0, none, fine);
}

TEST(BundleLanes, CoarseCarvingEqualsTheClippingReference) {
  const int64_t shift[3] = {1, 2, 3};
  for (int level : {1, 2, 3}) {
    const std::vector<Ray> rays = randomRays(40 + level, 300, 60);
    for (const Ray& ray : rays) {
      std::map<int64_t, double> want_coarse, want_fine;
      carveReference(ray, level, shift, want_coarse, want_fine);
      for (bool simd : {true, false}) {
        integrate_detail::LaneRay coarse, fine;
        const bool split =
            integrate_detail::splitCarvedRay(ray.o, ray.end, ray.weight, level, shift, kLo, kStride, kLo, kStride, coarse, fine);
        EXPECT_EQ(split, !want_coarse.empty());
        Calls coarse_calls, fine_calls;
        int k = 0;
        integrate_detail::castBundleLanes([&](integrate_detail::LaneRay& r) { return split && k++ == 0 ? (r = coarse, true) : false; },
                                [&](int64_t c, float v) { coarse_calls.emplace_back(c, v); }, simd);
        k = 0;
        integrate_detail::castBundleLanes([&](integrate_detail::LaneRay& r) { return k++ == 0 ? (r = fine, true) : false; },
                                [&](int64_t c, float v) { fine_calls.emplace_back(c, v); }, simd);
        // The last call is the end voxel's.
        ASSERT_FALSE(fine_calls.empty());
        const int64_t end_cell = indexOf(static_cast<int64_t>(ray.end[0]), static_cast<int64_t>(ray.end[1]),
                                         static_cast<int64_t>(ray.end[2]));
        EXPECT_EQ(fine_calls.back().first, end_cell);
        // The same cells with the same lengths, up to float rounding (cells the reference
        // finds only grazed, below the tolerance, may be missing from the walk and vice versa).
        double len = 0.0;
        for (int a = 0; a < 3; ++a) len += (ray.end[a] - ray.o[a]) * (ray.end[a] - ray.o[a]);
        const double tol = 1e-5 * std::sqrt(len) * ray.weight;
        for (auto [got, want] : {std::pair{sums(coarse_calls), want_coarse}, std::pair{sums(fine_calls), want_fine}}) {
          for (const auto& [c, v] : want) EXPECT_NEAR(got.count(c) ? got[c] : 0.0, v, tol) << "level " << level;
          for (const auto& [c, v] : got) EXPECT_NEAR(want.count(c) ? want[c] : 0.0, v, tol) << "level " << level;
        }
      }
    }
  }
}
}  // namespace
}  // namespace chronomap
