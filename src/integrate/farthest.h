#pragma once
/// @file
/// Internal to the integrate module: the farthest point of a frame, which sets the reach of the
/// working frame (RayAccumulator::Impl::setUp()).

#include <cmath>
#include <cstddef>
#include <limits>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace chronomap::integrate_detail {

/// The squared norm of one point, summed as Eigen's squaredNorm() sums a 3-vector:
/// x² + (y² + z²).
inline float squaredNorm3(const float* p) { return p[0] * p[0] + (p[1] * p[1] + p[2] * p[2]); }

/// The largest squared norm (squaredNorm3) of the `n` points `xyz` (x, y, z after each other),
/// leaving out those whose squared norm is NaN or infinite; 0 when there is none. The same value,
/// bit for bit, as a loop over the points in order: the largest of a set does not depend on the
/// order it is taken in. Once a squared norm reaches `stop` the rest is not read, and the value is
/// that squared norm (at least `stop`, at most the largest): for a caller that only needs to know
/// whether a point lies that far, such as a reach capped by the range (most frames have points
/// beyond it). Four points at a time where the CPU has SSE2: a scalar loop waits for each
/// comparison before the next (on the synthetic frames at 0.05 m, fast mode, that pass took
/// about 0.4 of 2.75 ms a frame, this one about 0.3: mostly the points' first read from memory).
inline float farthestSquaredNorm(const float* xyz, size_t n,
                                 float stop = std::numeric_limits<float>::infinity()) {
  constexpr float kLimit = std::numeric_limits<float>::max();
  float best = 0.0f;
  size_t i = 0;
#if defined(__SSE2__)
  if (n >= 8) {
    const __m128 limit = _mm_set1_ps(kLimit), stop4 = _mm_set1_ps(stop);
    __m128 best4[2] = {_mm_setzero_ps(), _mm_setzero_ps()};
    for (; i + 8 <= n; i += 8) {
      if (_mm_movemask_ps(_mm_cmpge_ps(_mm_max_ps(best4[0], best4[1]), stop4)) != 0) break;
      for (int half = 0; half < 2; ++half) {
        const float* p = xyz + 3 * (i + 4 * static_cast<size_t>(half));
        // Four points, squared coordinate by coordinate: a = x0 y0 z0 x1, b = y1 z1 x2 y2,
        // c = z2 x3 y3 z3; then the squares of x, y and z each in one vector.
        const __m128 a = _mm_loadu_ps(p), b = _mm_loadu_ps(p + 4), c = _mm_loadu_ps(p + 8);
        const __m128 sa = _mm_mul_ps(a, a), sb = _mm_mul_ps(b, b), sc = _mm_mul_ps(c, c);
        const __m128 t = _mm_shuffle_ps(sb, sc, _MM_SHUFFLE(0, 1, 0, 2));  // sb2 sb0 sc1 sc0
        const __m128 x = _mm_shuffle_ps(sa, t, _MM_SHUFFLE(2, 0, 3, 0));   // sa0 sa3 sb2 sc1
        const __m128 u = _mm_shuffle_ps(sa, sb, _MM_SHUFFLE(0, 0, 1, 1));  // sa1 sa1 sb0 sb0
        const __m128 v = _mm_shuffle_ps(sb, sc, _MM_SHUFFLE(2, 2, 3, 3));  // sb3 sb3 sc2 sc2
        const __m128 y = _mm_shuffle_ps(u, v, _MM_SHUFFLE(2, 0, 2, 0));    // sa1 sb0 sb3 sc2
        const __m128 q = _mm_shuffle_ps(sa, sb, _MM_SHUFFLE(1, 1, 2, 2));  // sa2 sa2 sb1 sb1
        const __m128 r = _mm_shuffle_ps(sc, sc, _MM_SHUFFLE(3, 3, 0, 0));  // sc0 sc0 sc3 sc3
        const __m128 z = _mm_shuffle_ps(q, r, _MM_SHUFFLE(2, 0, 2, 0));    // sa2 sb1 sc0 sc3
        const __m128 r2 = _mm_add_ps(x, _mm_add_ps(y, z));
        // NaN and infinity fail the comparison and count as 0.
        const __m128 kept = _mm_and_ps(_mm_cmple_ps(r2, limit), r2);
        best4[half] = _mm_max_ps(best4[half], kept);
      }
    }
    alignas(16) float lanes[4];
    _mm_store_ps(lanes, _mm_max_ps(best4[0], best4[1]));
    for (const float l : lanes) best = l > best ? l : best;
  }
#endif
  for (; i < n && !(best >= stop); ++i) {
    const float r2 = squaredNorm3(xyz + 3 * i);
    if (r2 > best && r2 <= kLimit) best = r2;  // NaN compares false
  }
  return best;
}

/// The least float `stop` whose square root (in double) is at least `range_m`, for
/// farthestSquaredNorm(): a point whose squared norm reaches it lies at the range or beyond.
/// Infinity when the range's square passes float's largest.
inline float rangeStop(double range_m) {
  const double range_sq = range_m * range_m;
  if (!(range_sq < double{std::numeric_limits<float>::max()})) return std::numeric_limits<float>::infinity();
  auto stop = static_cast<float>(range_sq);
  while (stop > 0.0f && std::sqrt(static_cast<double>(std::nextafter(stop, 0.0f))) >= range_m) {
    stop = std::nextafter(stop, 0.0f);
  }
  while (std::sqrt(static_cast<double>(stop)) < range_m) {
    stop = std::nextafter(stop, std::numeric_limits<float>::infinity());
  }
  return stop;
}

}  // namespace chronomap::integrate_detail
