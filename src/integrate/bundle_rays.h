#pragma once
/// @file
/// Fast mode's bundle rays, cast eight at a time. Every bundle ray ends at the centre of its
/// voxel, which lets its DDA (Amanatides & Woo, as in ray.h) drop the per-axis crossing counts:
/// the crossing after an axis' last one lies half a voxel beyond the end, at a ray parameter
/// above 1, while every crossing still to come on the other axes lies below 1 - so the axis
/// with the smallest next crossing is never an exhausted one while crossings remain. What is
/// left per step is branch-free: a minimum of three, three masks, masked adds.
///
/// Eight rays run side by side in lanes (two groups of four in AVX2 registers where the CPU
/// has them: two independent chains of dependent steps, 7% faster than one group, while a
/// third group gained nothing); a lane that finishes takes the next ray. The sink sees the same
/// sequence of calls with and without AVX2, so float sums formed from it are bitwise the same
/// on every machine.

#include <cmath>
#include <algorithm>
#include <cstdint>
#include <limits>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define CHRONOMAP_HAVE_AVX2_LANES 1
#else
#define CHRONOMAP_HAVE_AVX2_LANES 0
#endif

namespace chronomap::integrate_detail {

/// The DDA state of one ray in a grid whose cell c has the linear index (c - lo) . stride.
struct LaneRay {
  double t_max[3] = {0, 0, 0};    ///< ray parameter of the next crossing per axis (inf: none)
  double t_delta[3] = {0, 0, 0};  ///< parameter between crossings per axis (inf: none)
  double length = 0;              ///< |end - origin|, in voxels
  int64_t cell = 0;               ///< index of the cell holding the origin
  int64_t step[3] = {0, 0, 0};    ///< index change per crossing (0 on axes never crossed)
  int64_t steps = 0;              ///< crossings in all
  float weight = 0;               ///< the ray's weight (points in the bundle)
  double t0 = 0.0;                ///< ray parameter where the walk starts (a part of a ray: carving)
  double t_end = 1.0;             ///< ... and where it stops; every crossing counted in `steps` lies below
};

/// floor() for finite values of moderate size, inlined (std::floor is a library call on x86-64).
inline int64_t floorInt(double v) {
  const int64_t i = static_cast<int64_t>(v);
  return i - (static_cast<double>(i) > v);
}

/// Sets up the segment origin -> end (end: a voxel centre). Computes the same crossing
/// parameters as the integrator's single-ray DDA, so the lengths per cell are the same.
inline LaneRay laneRay(const double origin[3], const double end[3], float weight, const int64_t lo[3],
                       const int64_t stride[3]) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  LaneRay r;
  r.weight = weight;
  double d[3];
  for (int a = 0; a < 3; ++a) {
    const int64_t c = floorInt(origin[a]);
    const int64_t l = floorInt(end[a]);
    d[a] = end[a] - origin[a];
    r.cell += (c - lo[a]) * stride[a];
    const int64_t remaining = l > c ? l - c : c - l;
    r.steps += remaining;
    if (remaining == 0) {
      r.t_max[a] = kInf;
      r.t_delta[a] = kInf;
      r.step[a] = 0;
    } else if (d[a] > 0) {
      r.t_delta[a] = 1.0 / d[a];
      r.t_max[a] = (static_cast<double>(c) + 1.0 - origin[a]) * r.t_delta[a];
      r.step[a] = stride[a];
    } else {
      r.t_delta[a] = -1.0 / d[a];
      r.t_max[a] = (origin[a] - static_cast<double>(c)) * r.t_delta[a];
      r.step[a] = -stride[a];
    }
  }
  r.length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  return r;
}

/// floor(a / 2^level) (an arithmetic shift, as C++20 defines >> of negative values).
inline int64_t floorShift(int64_t a, int level) { return a >> level; }

/// Coarse carving (IntegratorSettings::carve_level): splits the bundle ray origin -> end (end: a
/// voxel centre; working voxel units) where it enters the end's **near box**, the coarse cells
/// within one of the end voxel's coarse cell on every axis. Coarse cells have side S = 2^level
/// voxels; working cell u lies in coarse cell floor((u + shift) / S), so that with shift = (key
/// of working cell 0) mod S they are aligned to the map's octree nodes of that level. The part
/// before the box (ray parameter 0 to t_s) becomes `coarse`, a walk through coarse cells of the
/// grid (clo, cstride); the rest (t_s to 1) `fine`, a walk through unit voxels of the grid (lo,
/// stride). Both keep the whole ray's length and parameter, so their lengths sum to the ray's.
/// Returns false when the origin lies inside the near box: then `fine` is laneRay() itself.
inline bool splitCarvedRay(const double origin[3], const double end[3], float weight, int level,
                           const int64_t shift[3], const int64_t lo[3], const int64_t stride[3], const int64_t clo[3],
                           const int64_t cstride[3], LaneRay& coarse, LaneRay& fine) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int64_t side = int64_t{1} << level;
  int64_t first[3], last[3], box_lo[3], box_hi[3];  // box: [box_lo, box_hi) in working voxels
  double d[3];
  double t_s = 0.0;
  int entry = -1;  // the axis on which the ray enters the near box
  for (int a = 0; a < 3; ++a) {
    first[a] = floorInt(origin[a]);
    last[a] = floorInt(end[a]);
    d[a] = end[a] - origin[a];
    const int64_t c = floorShift(last[a] + shift[a], level);
    box_lo[a] = (c - 1) * side - shift[a];
    box_hi[a] = (c + 2) * side - shift[a];
    double t_a = 0.0;
    if (origin[a] < static_cast<double>(box_lo[a])) {
      t_a = (static_cast<double>(box_lo[a]) - origin[a]) / d[a];
    } else if (origin[a] >= static_cast<double>(box_hi[a])) {
      t_a = (static_cast<double>(box_hi[a]) - origin[a]) / d[a];
    }
    if (t_a > t_s) {
      t_s = t_a;
      entry = a;
    }
  }
  if (entry < 0) {
    fine = laneRay(origin, end, weight, lo, stride);
    return false;
  }
  const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  coarse = LaneRay{};
  fine = LaneRay{};
  coarse.weight = fine.weight = weight;
  coarse.length = fine.length = length;
  coarse.t_end = fine.t0 = t_s;
  for (int a = 0; a < 3; ++a) {
    // The unit voxel where the fine walk starts: inside the box on the entry axis, else where the
    // entry point lies, kept between the origin's and the end's voxel and inside the box.
    int64_t f = 0;
    if (a == entry) {
      f = d[a] > 0 ? box_lo[a] : box_hi[a] - 1;
    } else {
      f = floorInt(origin[a] + t_s * d[a]);
      f = std::max(f, std::max(std::min(first[a], last[a]), box_lo[a]));
      f = std::min(f, std::min(std::max(first[a], last[a]), box_hi[a] - 1));
    }
    // The coarse walk goes from the origin's coarse cell to the one just before the box.
    const int64_t c0 = floorShift(first[a] + shift[a], level);
    const int64_t c1 = a == entry ? floorShift((d[a] > 0 ? box_lo[a] - 1 : box_hi[a]) + shift[a], level)
                                  : floorShift(f + shift[a], level);
    const int64_t fine_n = f < last[a] ? last[a] - f : f - last[a];
    const int64_t coarse_n = c0 < c1 ? c1 - c0 : c0 - c1;
    fine.cell += (f - lo[a]) * stride[a];
    coarse.cell += (c0 - clo[a]) * cstride[a];
    fine.steps += fine_n;
    coarse.steps += coarse_n;
    const double inv = d[a] != 0.0 ? 1.0 / std::abs(d[a]) : kInf;
    if (fine_n == 0) {
      fine.t_max[a] = fine.t_delta[a] = kInf;
    } else {
      fine.t_delta[a] = inv;
      fine.t_max[a] = (d[a] > 0 ? static_cast<double>(f) + 1.0 - origin[a] : origin[a] - static_cast<double>(f)) * inv;
      fine.step[a] = d[a] > 0 ? stride[a] : -stride[a];
    }
    if (coarse_n == 0) {
      coarse.t_max[a] = coarse.t_delta[a] = kInf;
    } else {
      const double next = static_cast<double>((d[a] > 0 ? c0 + 1 : c0) * side - shift[a]);  // next boundary
      coarse.t_delta[a] = static_cast<double>(side) * inv;
      coarse.t_max[a] = (d[a] > 0 ? next - origin[a] : origin[a] - next) * inv;
      coarse.step[a] = d[a] > 0 ? cstride[a] : -cstride[a];
    }
  }
  return true;
}

/// Lanes of ray state, laid out for vector loads. A lane without a ray is all zeros with
/// steps = -1 (it never finishes and its calls are skipped).
constexpr int kLanes = 8;
struct Lanes {
  alignas(32) double tx[kLanes], ty[kLanes], tz[kLanes], t[kLanes], dx[kLanes], dy[kLanes], dz[kLanes], len[kLanes],
      te[kLanes];
  alignas(32) int64_t cell[kLanes], sx[kLanes], sy[kLanes], sz[kLanes], steps[kLanes];
  alignas(32) float w[kLanes];

  /// Puts the next ray with crossings into lane k; rays without crossings (origin and end in
  /// one cell) get their single call on the way. Returns false when the source is empty.
  template <class Next, class Add>
  bool refill(int k, Next& next, Add& add) {
    LaneRay r;
    while (next(r)) {
      if (r.steps == 0) {
        add(r.cell, r.weight * static_cast<float>((r.t_end - r.t0) * r.length));
        continue;
      }
      tx[k] = r.t_max[0];
      ty[k] = r.t_max[1];
      tz[k] = r.t_max[2];
      dx[k] = r.t_delta[0];
      dy[k] = r.t_delta[1];
      dz[k] = r.t_delta[2];
      t[k] = r.t0;
      te[k] = r.t_end;
      len[k] = r.length;
      cell[k] = r.cell;
      sx[k] = r.step[0];
      sy[k] = r.step[1];
      sz[k] = r.step[2];
      steps[k] = r.steps;
      w[k] = r.weight;
      return true;
    }
    tx[k] = ty[k] = tz[k] = t[k] = dx[k] = dy[k] = dz[k] = len[k] = te[k] = 0.0;
    cell[k] = sx[k] = sy[k] = sz[k] = 0;
    steps[k] = -1;
    w[k] = 0.0f;
    return false;
  }

  /// Fills every lane; returns the mask of lanes holding a ray.
  template <class Next, class Add>
  unsigned fill(Next& next, Add& add) {
    unsigned live = 0;
    for (int k = 0; k < kLanes; ++k) live |= static_cast<unsigned>(refill(k, next, add)) << k;
    return live;
  }

  /// Ends the rays of the lanes in `done` (their last segment, to the end) and refills those
  /// lanes, in lane order. Returns the new mask of live lanes.
  template <class Next, class Add>
  unsigned finish(unsigned done, unsigned live, Next& next, Add& add) {
    for (int k = 0; k < kLanes; ++k) {
      if (!(done >> k & 1u)) continue;
      add(cell[k], w[k] * static_cast<float>((te[k] - t[k]) * len[k]));
      if (!refill(k, next, add)) live &= ~(1u << k);
    }
    return live;
  }
};

/// The lanes in plain C++, step by step as the vector lanes do it: every lane's arithmetic
/// (idle lanes are all zeros and stay put), then the calls of the live lanes in lane order,
/// then the lanes that finished. Selects are written as masks so that no branch depends on
/// the irregular sequence of axes.
template <class Next, class Add>
void castLanesPortable(Next& next, Add& add) {
  Lanes s;
  unsigned live = s.fill(next, add);
  while (live != 0) {
    unsigned done = 0;
    while (done == 0) {
      int64_t cells[kLanes];
      float values[kLanes];
      for (int k = 0; k < kLanes; ++k) {
        const double tc = std::min(std::min(s.tx[k], s.ty[k]), s.tz[k]);
        const int64_t mx = -static_cast<int64_t>(s.tx[k] == tc);
        const int64_t my = ~mx & -static_cast<int64_t>(s.ty[k] == tc);
        const int64_t mz = ~(mx | my);
        const double tn = std::min(std::max(tc, s.t[k]), s.te[k]);
        cells[k] = s.cell[k];
        values[k] = s.w[k] * static_cast<float>((tn - s.t[k]) * s.len[k]);
        s.t[k] = tn;
        s.cell[k] += (s.sx[k] & mx) | (s.sy[k] & my) | (s.sz[k] & mz);
        s.tx[k] += mx ? s.dx[k] : 0.0;
        s.ty[k] += my ? s.dy[k] : 0.0;
        s.tz[k] += mz ? s.dz[k] : 0.0;
        done |= static_cast<unsigned>(--s.steps[k] == 0) << k;
      }
      for (int k = 0; k < kLanes; ++k) {
        if (live >> k & 1u) add(cells[k], values[k]);
      }
      done &= live;
    }
    live = s.finish(done, live, next, add);
  }
}

#if CHRONOMAP_HAVE_AVX2_LANES
/// The same lanes in AVX2 registers. Each operation is the portable one's, lane by lane
/// (minimum, equality masks, masked adds, float conversion), so the calls are the same.
__attribute__((target("avx2"))) inline __m256i ld(const int64_t* p) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
}
__attribute__((target("avx2"))) inline void st(int64_t* p, __m256i v) {
  _mm256_store_si256(reinterpret_cast<__m256i*>(p), v);
}

template <class Next, class Add>
__attribute__((target("avx2"))) void castLanesAvx2(Next& next, Add& add) {
  Lanes s;
  unsigned live = s.fill(next, add);
  const __m256i zero = _mm256_setzero_si256(), minus_one = _mm256_set1_epi64x(-1);
  // Groups of four lanes: g = 0 holds lanes 0-3, g = 1 lanes 4-7.
  while (live != 0) {
    __m256d tx[kLanes / 4], ty[kLanes / 4], tz[kLanes / 4], t[kLanes / 4], te[kLanes / 4];
    __m256i cell[kLanes / 4], steps[kLanes / 4];
    for (int g = 0; g < kLanes / 4; ++g) {
      tx[g] = _mm256_load_pd(s.tx + 4 * g);
      ty[g] = _mm256_load_pd(s.ty + 4 * g);
      tz[g] = _mm256_load_pd(s.tz + 4 * g);
      t[g] = _mm256_load_pd(s.t + 4 * g);
      te[g] = _mm256_load_pd(s.te + 4 * g);
      cell[g] = ld(s.cell + 4 * g);
      steps[g] = ld(s.steps + 4 * g);
    }
    unsigned done = 0;
    alignas(32) int64_t cells[kLanes];
    alignas(32) float values[kLanes];
    while (done == 0) {
      for (int g = 0; g < kLanes / 4; ++g) {
        // min(a, b) is a < b ? a : b, as std::min(b, a); with no NaN the values match.
        const __m256d tc = _mm256_min_pd(_mm256_min_pd(tx[g], ty[g]), tz[g]);
        const __m256d mx = _mm256_cmp_pd(tx[g], tc, _CMP_EQ_OQ);
        const __m256d my = _mm256_andnot_pd(mx, _mm256_cmp_pd(ty[g], tc, _CMP_EQ_OQ));
        const __m256d mz = _mm256_andnot_pd(_mm256_or_pd(mx, my), _mm256_castsi256_pd(minus_one));
        const __m256d tn = _mm256_min_pd(_mm256_max_pd(tc, t[g]), te[g]);
        const __m256d seg = _mm256_mul_pd(_mm256_sub_pd(tn, t[g]), _mm256_load_pd(s.len + 4 * g));
        _mm_store_ps(values + 4 * g, _mm_mul_ps(_mm_load_ps(s.w + 4 * g), _mm256_cvtpd_ps(seg)));
        st(cells + 4 * g, cell[g]);
        t[g] = tn;
        const __m256i step =
            _mm256_or_si256(_mm256_or_si256(_mm256_and_si256(ld(s.sx + 4 * g), _mm256_castpd_si256(mx)),
                                            _mm256_and_si256(ld(s.sy + 4 * g), _mm256_castpd_si256(my))),
                            _mm256_and_si256(ld(s.sz + 4 * g), _mm256_castpd_si256(mz)));
        cell[g] = _mm256_add_epi64(cell[g], step);
        tx[g] = _mm256_add_pd(tx[g], _mm256_and_pd(_mm256_load_pd(s.dx + 4 * g), mx));
        ty[g] = _mm256_add_pd(ty[g], _mm256_and_pd(_mm256_load_pd(s.dy + 4 * g), my));
        tz[g] = _mm256_add_pd(tz[g], _mm256_and_pd(_mm256_load_pd(s.dz + 4 * g), mz));
        steps[g] = _mm256_add_epi64(steps[g], minus_one);
        done |= static_cast<unsigned>(_mm256_movemask_pd(_mm256_castsi256_pd(_mm256_cmpeq_epi64(steps[g], zero))))
                << (4 * g);
      }
      for (int k = 0; k < kLanes; ++k) {
        if (live >> k & 1u) add(cells[k], values[k]);
      }
      done &= live;
    }
    for (int g = 0; g < kLanes / 4; ++g) {
      _mm256_store_pd(s.tx + 4 * g, tx[g]);
      _mm256_store_pd(s.ty + 4 * g, ty[g]);
      _mm256_store_pd(s.tz + 4 * g, tz[g]);
      _mm256_store_pd(s.t + 4 * g, t[g]);
      st(s.cell + 4 * g, cell[g]);
      st(s.steps + 4 * g, steps[g]);
    }
    live = s.finish(done, live, next, add);
  }
}
#endif

/// True when this CPU runs the AVX2 lanes.
inline bool avx2Lanes() {
#if CHRONOMAP_HAVE_AVX2_LANES
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

/// Casts the rays that `next(LaneRay&)` yields (false: none left), calling add(cell, weight *
/// segment length) once per cell of every ray. `simd = false` takes the portable lanes (the
/// calls are the same either way).
template <class Next, class Add>
void castBundleLanes(Next&& next, Add&& add, bool simd = true) {
#if CHRONOMAP_HAVE_AVX2_LANES
  if (simd && avx2Lanes()) {
    castLanesAvx2(next, add);
    return;
  }
#endif
  (void)simd;
  castLanesPortable(next, add);
}

}  // namespace chronomap::integrate_detail
