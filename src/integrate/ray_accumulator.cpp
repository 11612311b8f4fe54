// RayAccumulator: one frame's rays cast into scratch stores (ray_accumulator.h) and emitted as
// per-voxel sums, on the path the frame's size and the settings call for.
#include "ray_accumulator.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cfloat>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_map>

#include "chronomap/core/error.h"
#include "chronomap/integrate/ray.h"
#include "bundle_rays.h"
#include "farthest.h"

namespace chronomap {

namespace {

using integrate_detail::CubeStore;
using integrate_detail::DenseStore;
using integrate_detail::EndEntry;
using integrate_detail::floorInt;
using integrate_detail::HashStore;
using integrate_detail::RelPoint;

/// Working-frame coordinates of one sensor point (R row-major, scaled to voxel units).
inline void transformPoint(const float* R, const float* of, const Eigen::Vector3f& p, float u[3]) {
  u[0] = of[0] + (R[0] * p.x() + R[1] * p.y() + R[2] * p.z());
  u[1] = of[1] + (R[3] * p.x() + R[4] * p.y() + R[5] * p.z());
  u[2] = of[2] + (R[6] * p.x() + R[7] * p.y() + R[8] * p.z());
}

/// Transforms sensor points into scratch-cube cell indices (idx; -1 for points that are
/// invalid or out of range). Written without branches so that it vectorises; where the CPU has
/// AVX2 that clone is chosen at load time. Returns the number of points kept; `out_of_range`
/// counts finite points beyond the range.
// (ThreadSanitizer builds take the portable code only: the clones' resolver runs while the
// program is loaded, before the sanitizer's runtime can handle its instrumentation.)
#if defined(__SANITIZE_THREAD__)
#define CHRONOMAP_AVX2_CLONES
#else
#define CHRONOMAP_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#endif
CHRONOMAP_AVX2_CLONES uint64_t cubeCells(
    const float* __restrict xyz, size_t n, const float* __restrict R, const float* __restrict of, float max_r2,
    int32_t sy, int32_t sz, int32_t* __restrict idx, uint64_t* out_of_range) {
  const float r00 = R[0], r01 = R[1], r02 = R[2], r10 = R[3], r11 = R[4], r12 = R[5], r20 = R[6], r21 = R[7],
              r22 = R[8];
  const float o0 = of[0], o1 = of[1], o2 = of[2];
  uint64_t kept = 0, beyond = 0;
  // Counted in 32 bits within blocks: the vector loop then adds its masks lane for lane instead
  // of widening them to 64 bits (measured: the widening took about a fifth of the loop).
  constexpr size_t kBlock = size_t{1} << 30;
  for (size_t block = 0; block < n; block += kBlock) {
    const size_t end = std::min(n, block + kBlock);
    uint32_t kept32 = 0, beyond32 = 0;
    for (size_t i = block; i < end; ++i) {
      const float px = xyz[3 * i], py = xyz[3 * i + 1], pz = xyz[3 * i + 2];
      const float r2 = px * px + py * py + pz * pz;  // the range is rotation-invariant
      const int valid = (r2 <= max_r2) & (r2 > 0.0f);  // false for NaN, infinity and zero depth
      // Same expression, same order as transformPoint(): every path must compute the same bits.
      const float a = valid ? o0 + (r00 * px + r01 * py + r02 * pz) : 0.0f;
      const float b = valid ? o1 + (r10 * px + r11 * py + r12 * pz) : 0.0f;
      const float c = valid ? o2 + (r20 * px + r21 * py + r22 * pz) : 0.0f;
      const int32_t cell = static_cast<int32_t>(a) + sy * static_cast<int32_t>(b) + sz * static_cast<int32_t>(c);
      idx[i] = valid ? cell : -1;
      kept32 += static_cast<uint32_t>(valid);
      beyond32 += static_cast<uint32_t>((r2 > max_r2) & (r2 <= FLT_MAX));
    }
    kept += kept32;
    beyond += beyond32;
  }
  *out_of_range = beyond;
  return kept;
}

/// The bounding box (lo, hi: in/out, working cells) of the valid points' cells, with the same
/// filter and the same arithmetic as cubeCells(). Returns the number of points kept;
/// `out_of_range` counts finite points beyond the range.
CHRONOMAP_AVX2_CLONES uint64_t pointBox(
    const float* __restrict xyz, size_t n, const float* __restrict R, const float* __restrict of, float max_r2,
    int32_t* __restrict lo, int32_t* __restrict hi, uint64_t* out_of_range) {
  const float r00 = R[0], r01 = R[1], r02 = R[2], r10 = R[3], r11 = R[4], r12 = R[5], r20 = R[6], r21 = R[7],
              r22 = R[8];
  const float o0 = of[0], o1 = of[1], o2 = of[2];
  int32_t lx = lo[0], ly = lo[1], lz = lo[2], hx = hi[0], hy = hi[1], hz = hi[2];
  uint64_t kept = 0, beyond = 0;
  constexpr size_t kBlock = size_t{1} << 30;  // 32-bit counts, as in cubeCells()
  for (size_t block = 0; block < n; block += kBlock) {
    const size_t end = std::min(n, block + kBlock);
    uint32_t kept32 = 0, beyond32 = 0;
    for (size_t i = block; i < end; ++i) {
      const float px = xyz[3 * i], py = xyz[3 * i + 1], pz = xyz[3 * i + 2];
      const float r2 = px * px + py * py + pz * pz;
      const int valid = (r2 <= max_r2) & (r2 > 0.0f);
      const float a = valid ? o0 + (r00 * px + r01 * py + r02 * pz) : o0;
      const float b = valid ? o1 + (r10 * px + r11 * py + r12 * pz) : o1;
      const float c = valid ? o2 + (r20 * px + r21 * py + r22 * pz) : o2;
      const int32_t x = static_cast<int32_t>(a), y = static_cast<int32_t>(b), z = static_cast<int32_t>(c);
      lx = std::min(lx, x);
      ly = std::min(ly, y);
      lz = std::min(lz, z);
      hx = std::max(hx, x);
      hy = std::max(hy, y);
      hz = std::max(hz, z);
      kept32 += static_cast<uint32_t>(valid);
      beyond32 += static_cast<uint32_t>((r2 > max_r2) & (r2 <= FLT_MAX));
    }
    kept += kept32;
    beyond += beyond32;
  }
  lo[0] = lx, lo[1] = ly, lo[2] = lz, hi[0] = hx, hi[1] = hy, hi[2] = hz;
  *out_of_range = beyond;
  return kept;
}

/// cubeCells() for a grid over a box: the index (cell - lo) . (1, sy, sz) of every point's
/// cell, -1 for points that are invalid or out of range.
CHRONOMAP_AVX2_CLONES void boxCells(const float* __restrict xyz, size_t n, const float* __restrict R,
                                    const float* __restrict of, float max_r2, const int32_t* __restrict lo, int32_t sy,
                                    int32_t sz, int32_t* __restrict idx) {
  const float r00 = R[0], r01 = R[1], r02 = R[2], r10 = R[3], r11 = R[4], r12 = R[5], r20 = R[6], r21 = R[7],
              r22 = R[8];
  const float o0 = of[0], o1 = of[1], o2 = of[2];
  const int32_t lx = lo[0], ly = lo[1], lz = lo[2];
  for (size_t i = 0; i < n; ++i) {
    const float px = xyz[3 * i], py = xyz[3 * i + 1], pz = xyz[3 * i + 2];
    const float r2 = px * px + py * py + pz * pz;
    const int valid = (r2 <= max_r2) & (r2 > 0.0f);
    const float a = valid ? o0 + (r00 * px + r01 * py + r02 * pz) : 0.0f;
    const float b = valid ? o1 + (r10 * px + r11 * py + r12 * pz) : 0.0f;
    const float c = valid ? o2 + (r20 * px + r21 * py + r22 * pz) : 0.0f;
    const int32_t cell =
        (static_cast<int32_t>(a) - lx) + sy * (static_cast<int32_t>(b) - ly) + sz * (static_cast<int32_t>(c) - lz);
    idx[i] = valid ? cell : -1;
  }
}

/// The DDA of ray.h specialised for dense stores: walks cell indices directly and adds
/// weight * segment length to each cell. Coordinates are the frame's working coordinates, the
/// same on every path so that every path computes the same lengths; cell c has index
/// (c - lo) . (1, stride_y, stride_z). Returns the index of the last cell (containing `end`).
/// Its set-up is that of integrate_detail::laneRay() plus the per-axis counts; built on laneRay() it
/// measured 8% slower in exact mode (60 against 55.5 ms per synthetic frame), so it stays here.
inline size_t castDense(const double origin[3], const double end[3], float weight, float* length,
                        const int64_t lo[3], int64_t stride_y, int64_t stride_z) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int64_t stride[3] = {1, stride_y, stride_z};
  int64_t remaining[3], step_idx[3];
  double t_max[3], t_delta[3], d[3];
  int64_t idx = 0;
  int64_t steps = 0;
  for (int a = 0; a < 3; ++a) {
    const int64_t c = floorInt(origin[a]);
    const int64_t l = floorInt(end[a]);
    d[a] = end[a] - origin[a];
    idx += (c - lo[a]) * stride[a];
    remaining[a] = l > c ? l - c : c - l;
    steps += remaining[a];
    if (remaining[a] == 0) {
      t_max[a] = kInf;
      t_delta[a] = kInf;
      step_idx[a] = 0;
    } else if (d[a] > 0) {
      t_delta[a] = 1.0 / d[a];
      t_max[a] = (static_cast<double>(c) + 1.0 - origin[a]) * t_delta[a];
      step_idx[a] = stride[a];
    } else {
      t_delta[a] = -1.0 / d[a];
      t_max[a] = (origin[a] - static_cast<double>(c)) * t_delta[a];
      step_idx[a] = -stride[a];
    }
  }
  const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  // The per-axis state lives in scalars, not arrays indexed by the chosen axis: indexing would
  // route every step through memory (store-to-load forwarding) and made a step ~3x slower.
  double tx = t_max[0], ty = t_max[1], tz = t_max[2];
  const double dx = t_delta[0], dy = t_delta[1], dz = t_delta[2];
  int64_t rx = remaining[0], ry = remaining[1], rz = remaining[2];
  const int64_t sx = step_idx[0], sy = step_idx[1], sz = step_idx[2];
  double t = 0.0;
  for (; steps > 0; --steps) {
    // Branch-free choice of the axis crossed first (the sequence of axes is irregular).
    const bool bx = tx <= ty && tx <= tz;
    const bool by = !bx && ty <= tz;
    const bool bz = !bx && !by;
    const double t_cross = bx ? tx : (by ? ty : tz);
    const double t_next = std::min(std::max(t_cross, t), 1.0);
    length[idx] += weight * static_cast<float>((t_next - t) * len);
    t = t_next;
    idx += bx ? sx : (by ? sy : sz);
    rx -= bx;
    ry -= by;
    rz -= bz;
    tx = bx ? (rx == 0 ? kInf : tx + dx) : tx;
    ty = by ? (ry == 0 ? kInf : ty + dy) : ty;
    tz = bz ? (rz == 0 ? kInf : tz + dz) : tz;
  }
  length[idx] += weight * static_cast<float>((1.0 - t) * len);
  return static_cast<size_t>(idx);
}

/// Calls emit(k) for every k in [0, n) whose cell holds ray length or an end entry, in
/// increasing order, and zeroes every cell written (whatever its bits: the stores are zero at
/// rest), four cells at a time where the CPU has SSE2 (most cells of a frame's box hold neither;
/// one at a time, the test was about a fifth of the one-pass path's own time on the 3DMatch
/// frames at 0.05 m). A cell that a ray only touched (length 0, as at a corner) is no update.
template <class Emit>
inline void emitAndClear(float* length, uint32_t* end, size_t n, Emit&& emit) {
  auto visit = [&](size_t k) {
    if (length[k] > 0.0f || end[k] != 0) emit(k);
    length[k] = 0.0f;
    end[k] = 0;
  };
  size_t k = 0;
#if defined(__SSE2__)
  const __m128i zero_i = _mm_setzero_si128();
  for (; k + 4 <= n; k += 4) {
    const __m128i l = _mm_loadu_si128(reinterpret_cast<const __m128i*>(length + k));
    const __m128i e = _mm_loadu_si128(reinterpret_cast<const __m128i*>(end + k));
    const int empty = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(_mm_or_si128(l, e), zero_i)));
    for (auto written = static_cast<unsigned>(~empty & 0xF); written != 0; written &= written - 1) {
      visit(k + static_cast<size_t>(std::countr_zero(written)));
    }
  }
#endif
  for (; k < n; ++k) {
    if (std::bit_cast<uint32_t>(length[k]) != 0 || end[k] != 0) visit(k);
  }
}

/// The working frame's bias (setUp()) for a reach of `reach_m`: the reach in voxels, up to the
/// map's diagonal, rounded up, plus two. The range cube's side is 2 * bias + 1.
inline int64_t biasForReach(double reach_m, double inv_res) {
  return static_cast<int64_t>(std::ceil(std::min(reach_m * inv_res, kMapDiagonalVoxels))) + 2;
}

/// True when fast mode's one pass can take a range cube of side `side` (at most `max_cells`).
inline bool cubeFits(int64_t side, size_t max_cells) {
  const auto s = static_cast<double>(side);
  return s * s * s <= static_cast<double>(max_cells);
}

/// A working cell packed 21 bits per axis, x lowest: sorting the codes is raster order.
inline uint64_t packCell(int64_t x, int64_t y, int64_t z) {
  return static_cast<uint64_t>(x) | (static_cast<uint64_t>(y) << 21) | (static_cast<uint64_t>(z) << 42);
}

/// One frame's working frame (RayAccumulator::Impl::setUp()): voxel units relative to the
/// origin's voxel, shifted by `bias` voxels so that every point within range has positive
/// coordinates (truncation is then floor) and small magnitudes keep float precision.
struct WorkingFrame {
  int64_t bias = 0;
  int64_t side = 0;           // of the range cube around the origin: 2 * bias + 1
  int64_t oc[3] = {0, 0, 0};  // key of working cell 0
  double o[3] = {0, 0, 0};    // origin in the working frame
  bool cube_inside = true;    // the whole range cube lies inside the map
  float Rm[9] = {};           // sensor metres -> voxel units, row-major
  float of[3] = {};           // the origin, as float
  float max_range = 0.0f, max_range_sq = 0.0f;
  bool colours = false;        // the cloud has colours
};

}  // namespace

struct RayAccumulator::Impl {
  Impl(const KeyGrid& g, const IntegratorSettings& s) : grid(g), settings(s) {
    settings.carve_level = carveLevelFor(s, g.resolution_m());
    hash.max_bytes = s.memory_limit_bytes;
    hash.resolution_m = g.resolution_m();
    // The side of the range cube of a frame that reaches the whole range, when fast mode's one
    // pass can take such a cube: the cube's buffer is made that large at once.
    const int64_t side = 2 * biasForReach(s.max_range_m, 1.0 / g.resolution_m()) + 1;
    cube_room = cubeFits(side, s.cube_max_cells) ? side : 0;
  }
  KeyGrid grid;
  IntegratorSettings settings;
  std::vector<RelPoint> points;
  std::vector<int32_t> cell_index;  // one-pass path: per point
  // The frame being accumulated: its cloud, its sensor origin in the working frame, the rotation
  // from sensor metres to working voxel units (row-major).
  const PointCloud* cloud = nullptr;
  Frame edge_frame;  // the frame without its depth-edge points (IntegratorSettings::depth_edge_ratio)
  void accumulateFrame(const Frame& frame, VoxelDeltas& out);
  double origin[3] = {0.0, 0.0, 0.0};
  double rotation[9] = {};
  std::vector<EndEntry> ends;  // ends[0] unused so that index 0 means "none"
  std::vector<std::array<double, 3>> beyond_ends;  // carveBeyondRange(): the pulled-back ends
  DenseStore dense;
  HashStore hash;
  CubeStore cube;
  int64_t cube_room = 0;  // CubeStore::ensure()'s room
  // A point whose squared norm (a float) is at least this lies at the range or beyond, which is
  // then the frame's reach: setUp() need not read the rest of the points.
  const float range_stop = integrate_detail::rangeStop(settings.max_range_m);
  // Coarse carving (settings.carve_level > 0): key of working cell 0, the frame's deltas (the
  // cubes go straight there), the coarse cells' lengths in voxel units.
  int64_t key_origin[3] = {0, 0, 0};
  VoxelDeltas* frame_out = nullptr;
  std::vector<float> coarse_length;
  std::vector<integrate_detail::LaneRay> fine_rays;

  uint32_t newEnd(const int64_t cell[3]) {
    EndEntry e;
    for (int a = 0; a < 3; ++a) e.cell[a] = cell[a];
    ends.push_back(e);
    return static_cast<uint32_t>(ends.size() - 1);
  }
  void addEnd(EndEntry& e, const RelPoint& p) const {
    e.addHit(p.colour.r, p.colour.g, p.colour.b);
    if (settings.hit_positions) e.addPoint(cloud->points[p.index]);
  }
  /// Bundles one chunk of points, those from `begin` on, whose cells are in `cells` (-1:
  /// none), into end entries; `end` maps a cell to its entry (0: none yet), and new_end(cell)
  /// makes the entry of a cell seen first. Four variants, with and without colours and
  /// positions, so that the loop tests neither per point.
  template <class NewEnd>
  void bundleChunk(const int32_t* cells, size_t begin, size_t count, uint32_t* end, NewEnd&& new_end) {
    auto run = [&](auto with_colours, auto with_positions) {
      EndEntry* entries = ends.data();
      const Rgb* colour = with_colours ? cloud->colours.data() + begin : nullptr;
      // Held here: read through `cloud` on every point, it was loaded again after each store.
      const Eigen::Vector3f* point = cloud->points.data() + begin;
      for (size_t j = 0; j < count; ++j) {
        const int32_t c = cells[j];
        if (c < 0) continue;
        uint32_t& e = end[static_cast<size_t>(c)];
        if (e == 0) {
          e = new_end(c);
          entries = ends.data();
        }
        EndEntry& entry = entries[e];
        if constexpr (decltype(with_colours)::value) {
          entry.addHit(colour[j].r, colour[j].g, colour[j].b);
        } else {
          ++entry.hits;
        }
        if constexpr (decltype(with_positions)::value) entry.addPoint(point[j]);
      }
    };
    const bool colours = cloud->hasColours();
    if (colours && settings.hit_positions) {
      run(std::true_type{}, std::true_type{});
    } else if (colours) {
      run(std::true_type{}, std::false_type{});
    } else if (settings.hit_positions) {
      run(std::false_type{}, std::true_type{});
    } else {
      run(std::false_type{}, std::false_type{});
    }
  }
  /// Where a bundle's ray ends: the centre of its voxel.
  static void bundleTarget(const EndEntry& e, double target[3]) {
    for (int a = 0; a < 3; ++a) target[a] = static_cast<double>(e.cell[a]) + 0.5;
  }
  /// The working-frame voxel of a point (coordinates are positive, so truncation is floor).
  static void cellOf(const RelPoint& p, int64_t cell[3]) {
    for (int a = 0; a < 3; ++a) cell[a] = static_cast<int64_t>(p.u[a]);
  }
  /// Casts one weighted ray per bundle, eight at a time (bundle_rays.h), in a grid with cell
  /// index (c - lo) . stride, calling add(index, length) per cell. Every fast-mode path goes
  /// through here, so all of them form the same float sums.
  template <class Add>
  void castBundleRays(const double o[3], const int64_t lo[3], const int64_t stride[3], Add&& add) {
    if (settings.carve_level > 0) {
      castCarved(o, lo, stride, add);
      return;
    }
    size_t e = 1;
    auto next = [&](integrate_detail::LaneRay& r) {
      if (e >= ends.size()) return false;
      double target[3];
      bundleTarget(ends[e], target);
      r = integrate_detail::laneRay(o, target, static_cast<float>(ends[e].hits), lo, stride);
      ++e;
      return true;
    };
    integrate_detail::castBundleLanes(next, add, settings.simd);
  }
  /// castBundleRays() with coarse carving (IntegratorSettings::carve_level, bundle_rays.h
  /// splitCarvedRay()): first the coarse parts of every bundle ray, in bundle order, into a grid
  /// of coarse cells (dense over their box, or a hash table for boxes over dense_grid_max_cells:
  /// the same sums either way), emitted as cubes in raster order; then the fine parts as
  /// castBundleRays() casts whole rays. The grid the fine parts go to does not change the coarse
  /// sums, so every scratch path gives the same map.
  template <class Add>
  void castCarved(const double o[3], const int64_t lo[3], const int64_t stride[3], Add& add) {
    const int level = settings.carve_level;
    const int64_t side = int64_t{1} << level;
    int64_t shift[3], clo[3], chi[3];
    for (int a = 0; a < 3; ++a) {
      shift[a] = key_origin[a] & (side - 1);
      clo[a] = chi[a] = integrate_detail::floorShift(floorInt(o[a]) + shift[a], level);
    }
    for (size_t e = 1; e < ends.size(); ++e) {
      for (int a = 0; a < 3; ++a) {
        const int64_t c = integrate_detail::floorShift(ends[e].cell[a] + shift[a], level);
        clo[a] = std::min(clo[a], c - 2);
        chi[a] = std::max(chi[a], c + 2);
      }
    }
    const int64_t cn[3] = {chi[0] - clo[0] + 1, chi[1] - clo[1] + 1, chi[2] - clo[2] + 1};
    const double coarse_cells = static_cast<double>(cn[0]) * static_cast<double>(cn[1]) * static_cast<double>(cn[2]);
    const bool dense_coarse = coarse_cells <= static_cast<double>(settings.dense_grid_max_cells);
    // The hash table's cells are packed (c - clo) with 21 bits per axis.
    constexpr int kShift = 21;
    constexpr int64_t kMask = (int64_t{1} << kShift) - 1;
    const int64_t cstride[3] = {1, dense_coarse ? cn[0] : int64_t{1} << kShift,
                                dense_coarse ? cn[0] * cn[1] : int64_t{1} << (2 * kShift)};
    std::unordered_map<int64_t, float> coarse_hash;
    if (dense_coarse) coarse_length.assign(static_cast<size_t>(coarse_cells), 0.0f);
    // The fine parts are kept from the first pass for the second.
    const size_t n_ends = ends.size();
    fine_rays.resize(n_ends);
    size_t e = 1;
    auto next_coarse = [&](integrate_detail::LaneRay& r) {
      while (e < n_ends) {
        double target[3];
        bundleTarget(ends[e], target);
        const float w = static_cast<float>(ends[e].hits);
        const bool split =
            integrate_detail::splitCarvedRay(o, target, w, level, shift, lo, stride, clo, cstride, r, fine_rays[e]);
        ++e;
        if (split) return true;
      }
      return false;
    };
    if (dense_coarse) {
      float* length = coarse_length.data();
      integrate_detail::castBundleLanes(next_coarse, [length](int64_t c, float v) { length[c] += v; }, settings.simd);
    } else {
      // Counted against the thread's share of the memory limit like the fine hash table: a node
      // and its bucket, then the sorted copy and the cube it becomes.
      constexpr size_t kBytesPerCell = 48 + sizeof(std::pair<int64_t, float>) + sizeof(VoxelKey) + sizeof(float);
      const size_t max_cells = hash.max_bytes == 0 ? SIZE_MAX : hash.max_bytes / kBytesPerCell;
      integrate_detail::castBundleLanes(
          next_coarse,
          [&](int64_t c, float v) {
            coarse_hash[c] += v;
            if (coarse_hash.size() > max_cells) {
              integrate_detail::refuseOverMemoryLimit("carving one frame's free space", hash.max_bytes, " per thread", hash.resolution_m);
            }
          },
          settings.simd);
    }
    e = 1;
    auto next_fine = [&](integrate_detail::LaneRay& r) {
      if (e >= n_ends) return false;
      r = fine_rays[e++];
      return true;
    };
    integrate_detail::castBundleLanes(next_fine, add, settings.simd);
    // The cubes, in raster order of their cells (z, then y, then x).
    VoxelDeltas& out = *frame_out;
    out.cube_level = level;
    const float res = static_cast<float>(grid.resolution_m());
    auto emit = [&](int64_t x, int64_t y, int64_t z, float len) {
      const int64_t k[3] = {(x + clo[0]) * side - shift[0] + key_origin[0],
                            (y + clo[1]) * side - shift[1] + key_origin[1],
                            (z + clo[2]) * side - shift[2] + key_origin[2]};
      out.cube_keys.push_back(
          VoxelKey{static_cast<uint16_t>(k[0]), static_cast<uint16_t>(k[1]), static_cast<uint16_t>(k[2])});
      out.cube_length_m.push_back(len * res);
    };
    if (dense_coarse) {
      size_t idx = 0;
      for (int64_t z = 0; z < cn[2]; ++z) {
        for (int64_t y = 0; y < cn[1]; ++y) {
          for (int64_t x = 0; x < cn[0]; ++x, ++idx) {
            if (coarse_length[idx] > 0.0f) emit(x, y, z, coarse_length[idx]);
          }
        }
      }
    } else {
      std::vector<std::pair<int64_t, float>> cells(coarse_hash.begin(), coarse_hash.end());
      // Packed z, y, x from the top bits down: sorting the codes is raster order.
      std::sort(cells.begin(), cells.end());
      for (const auto& [c, len] : cells) {
        if (len > 0.0f) emit(c & kMask, (c >> kShift) & kMask, c >> (2 * kShift), len);
      }
    }
  }

  /// Casts the bundles into the bounding-box store's lengths.
  void castBundles(const double o[3]) {
    DenseStore& d = dense;
    const int64_t stride[3] = {1, d.n[0], d.n[0] * d.n[1]};
    float* length = d.length;
    castBundleRays(o, d.lo, stride, [length](int64_t c, float v) { length[c] += v; });
  }

  /// Casts every point (exact) or bundle (fast) into the bounding-box store; `o` is the sensor
  /// origin in working coordinates, like the points.
  void castDenseAll(const double o[3]) {
    DenseStore& d = dense;
    const int64_t sy = d.n[0], sz = d.n[0] * d.n[1];
    float* length = d.length;
    if (!settings.fast) {
      for (const RelPoint& p : points) {
        const double end[3] = {p.u[0], p.u[1], p.u[2]};
        const size_t last = castDense(o, end, 1.0f, length, d.lo, sy, sz);
        uint32_t& e = d.end[last];
        if (e == 0) {
          int64_t cell[3];
          cellOf(p, cell);
          e = newEnd(cell);
        }
        addEnd(ends[e], p);
      }
      return;
    }
    for (const RelPoint& p : points) {
      int64_t cell[3];
      cellOf(p, cell);
      uint32_t& e = d.end[d.cell(cell[0], cell[1], cell[2])];
      if (e == 0) e = newEnd(cell);
      addEnd(ends[e], p);
    }
    castBundles(o);
  }

  /// The same for the hash store, with absolute key-space coordinates (`oc` = key of the
  /// working frame's cell 0).
  void castHashAll(const double o[3], const int64_t oc[3]) {
    auto castOne = [&](const double end[3], float weight) {
      traverseRay(o, end, [&](int64_t x, int64_t y, int64_t z, double len, bool) {
        hash.slot(x + oc[0], y + oc[1], z + oc[2]).length += weight * static_cast<float>(len);
      });
    };
    if (!settings.fast) {
      for (const RelPoint& p : points) {
        const double end[3] = {p.u[0], p.u[1], p.u[2]};
        castOne(end, 1.0f);
        int64_t cell[3];
        cellOf(p, cell);
        HashStore::Slot& s = hash.slot(cell[0] + oc[0], cell[1] + oc[1], cell[2] + oc[2]);
        if (s.end == 0) s.end = newEnd(cell);
        addEnd(ends[s.end], p);
      }
      return;
    }
    for (const RelPoint& p : points) {
      int64_t cell[3];
      cellOf(p, cell);
      HashStore::Slot& s = hash.slot(cell[0] + oc[0], cell[1] + oc[1], cell[2] + oc[2]);
      if (s.end == 0) s.end = newEnd(cell);
      addEnd(ends[s.end], p);
    }
    // Cells as packed absolute keys: x + y * 2^21 + z * 2^42 (keys have 16 bits).
    constexpr int kShift = 21;
    constexpr int64_t kMask = (int64_t{1} << kShift) - 1;
    const int64_t lo[3] = {-oc[0], -oc[1], -oc[2]};
    const int64_t stride[3] = {1, int64_t{1} << kShift, int64_t{1} << (2 * kShift)};
    castBundleRays(o, lo, stride, [this](int64_t c, float v) {
      hash.slot(c & kMask, (c >> kShift) & kMask, c >> (2 * kShift)).length += v;
    });
  }

  /// Free space along the rays of points beyond the range, up to the range
  /// (IntegratorSettings::carve_beyond_range): each such point is pulled back along its ray to
  /// `max_range` and cast without a hit, one ray per point (exact) or one weighted ray per end
  /// voxel to its centre (fast). Cast apart from the frame's other rays and then added to its
  /// deltas, so that every scratch path gives the same sums.
  void carveBeyondRange(const WorkingFrame& w, VoxelDeltas& out) {
    collectBeyondEnds(w);
    if (beyond_ends.empty()) return;
    std::vector<float> weights(beyond_ends.size(), 1.0f);
    if (settings.fast) bundleBeyondEnds(weights);
    out.stats.rays += beyond_ends.size();
    addBeyondLengths(beyondLengths(weights), w.oc, out);
  }

  /// beyond_ends: the points beyond the range pulled back to it, in the working frame, those
  /// inside the map.
  void collectBeyondEnds(const WorkingFrame& w) {
    const PointCloud& c = *cloud;
    const int64_t* oc = w.oc;
    std::vector<std::array<double, 3>>& ends_u = beyond_ends;
    ends_u.clear();
    for (const Eigen::Vector3f& p : c.points) {
      const float r2 = p.squaredNorm();
      if (!(r2 > w.max_range_sq && r2 <= FLT_MAX)) continue;
      const Eigen::Vector3f q = p * (w.max_range / std::sqrt(r2));
      float u[3];
      transformPoint(w.Rm, w.of, q, u);
      bool inside = true;
      if (!w.cube_inside) {
        for (int a = 0; a < 3; ++a) {
          inside = inside && u[a] >= static_cast<float>(-oc[a]) && u[a] < static_cast<float>(kKeysPerAxis - oc[a]);
        }
      }
      if (inside) ends_u.push_back({u[0], u[1], u[2]});
    }
  }

  /// Fast mode: one ray per end voxel, to its centre, weighted by its points; in key order.
  void bundleBeyondEnds(std::vector<float>& weights) {
    std::vector<std::array<double, 3>>& ends_u = beyond_ends;
    std::vector<uint64_t> cells(ends_u.size());
    for (size_t i = 0; i < ends_u.size(); ++i) {
      const auto& u = ends_u[i];
      cells[i] = static_cast<uint64_t>(u[0]) | (static_cast<uint64_t>(u[1]) << 21) |
                 (static_cast<uint64_t>(u[2]) << 42);
    }
    std::sort(cells.begin(), cells.end());
    ends_u.clear();
    weights.clear();
    for (size_t i = 0; i < cells.size();) {
      size_t j = i;
      while (j < cells.size() && cells[j] == cells[i]) ++j;
      const uint64_t m = (uint64_t{1} << 21) - 1;
      ends_u.push_back({static_cast<double>(cells[i] & m) + 0.5, static_cast<double>((cells[i] >> 21) & m) + 0.5,
                        static_cast<double>(cells[i] >> 42) + 0.5});
      weights.push_back(static_cast<float>(j - i));
      i = j;
    }
  }

  /// The lengths (voxel units) of the rays to beyond_ends per working cell (packCell()), in
  /// order: over the bounding box of the origin and the ends when it is small enough, else in a
  /// hash map; either way summed ray by ray in the same order.
  std::vector<std::pair<uint64_t, float>> beyondLengths(const std::vector<float>& weights) {
    const std::vector<std::array<double, 3>>& ends_u = beyond_ends;
    int64_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = floorInt(origin[a]);
    for (const auto& u : ends_u) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], floorInt(u[a]));
        hi[a] = std::max(hi[a], floorInt(u[a]));
      }
    }
    std::vector<std::pair<uint64_t, float>> cells;  // packed working cell, length in voxels
    const double box = static_cast<double>(hi[0] - lo[0] + 1) * static_cast<double>(hi[1] - lo[1] + 1) *
                       static_cast<double>(hi[2] - lo[2] + 1);
    if (box <= static_cast<double>(settings.dense_grid_max_cells)) {
      // The frame's own rays are emitted by now: their store is free to reuse.
      DenseStore& d = dense;
      d.reset(lo, hi, /*with_end=*/false);
      float* length = d.length;
      for (size_t i = 0; i < ends_u.size(); ++i) {
        castDense(origin, ends_u[i].data(), weights[i], length, d.lo, d.n[0], d.n[0] * d.n[1]);
      }
      size_t idx = 0;
      for (int64_t z = lo[2]; z <= hi[2]; ++z) {
        for (int64_t y = lo[1]; y <= hi[1]; ++y) {
          for (int64_t x = lo[0]; x <= hi[0]; ++x, ++idx) {
            if (length[idx] > 0.0f) cells.emplace_back(packCell(x, y, z), length[idx]);
            length[idx] = 0.0f;  // the store is zero at rest
          }
        }
      }
      d.rest();
    } else {
      std::unordered_map<uint64_t, float> length;
      for (size_t i = 0; i < ends_u.size(); ++i) {
        const float w = weights[i];
        traverseRay(origin, ends_u[i].data(), [&](int64_t x, int64_t y, int64_t z, double len, bool) {
          length[packCell(x, y, z)] += w * static_cast<float>(len);
        });
      }
      cells.assign(length.begin(), length.end());
      std::sort(cells.begin(), cells.end());
    }
    return cells;
  }

  /// Adds carved lengths to the frame's deltas: to a voxel they already hold, or as a voxel only
  /// crossed; `oc` is the key of working cell 0.
  void addBeyondLengths(const std::vector<std::pair<uint64_t, float>>& cells, const int64_t oc[3],
                        VoxelDeltas& out) const {
    std::unordered_map<uint64_t, size_t> index;
    index.reserve(out.keys.size());
    for (size_t i = 0; i < out.keys.size(); ++i) {
      const VoxelKey& k = out.keys[i];
      index.emplace(packCell(k.x - oc[0], k.y - oc[1], k.z - oc[2]), i);
    }
    const float res = static_cast<float>(grid.resolution_m());
    constexpr uint64_t kMask = (uint64_t{1} << 21) - 1;
    for (const auto& [cell, len] : cells) {
      if (len <= 0.0f) continue;
      const auto it = index.find(cell);
      if (it != index.end()) {
        out.deltas[it->second].length_m += len * res;
        continue;
      }
      const int64_t x = static_cast<int64_t>(cell & kMask), y = static_cast<int64_t>((cell >> 21) & kMask),
                    z = static_cast<int64_t>(cell >> 42);
      out.keys.push_back(VoxelKey{static_cast<uint16_t>(x + oc[0]), static_cast<uint16_t>(y + oc[1]),
                                  static_cast<uint16_t>(z + oc[2])});
      out.deltas.emplace_back().length_m = len * res;
    }
  }

  /// Emits every cell of the bounding-box store that a ray crossed or ended in, in raster order
  /// (consecutive keys share most of their path in the tree); `oc` is the key of working cell 0.
  /// Zeroes the store as it goes.
  void emitDense(const int64_t oc[3], VoxelDeltas& out) {
    DenseStore& d = dense;
    out.keys.reserve(ends.size() * 8);
    out.deltas.reserve(ends.size() * 8);
    const auto nx = static_cast<size_t>(d.n[0]);
    float* l_row = d.length;
    uint32_t* e_row = d.end;
    for (int64_t z = 0; z < d.n[2]; ++z) {
      for (int64_t y = 0; y < d.n[1]; ++y, l_row += nx, e_row += nx) {
        emitAndClear(l_row, e_row, nx, [&](size_t k) {
          emitCell(oc[0] + d.lo[0] + static_cast<int64_t>(k), oc[1] + d.lo[1] + y, oc[2] + d.lo[2] + z, l_row[k],
                   e_row[k], out);
        });
      }
    }
    d.rest();
  }

  void emitCell(int64_t x, int64_t y, int64_t z, float length, uint32_t end, VoxelDeltas& out) const {
    out.keys.push_back(VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)});
    // Written in place, field by field: a copy of a counter built on the stack measured a
    // store-forwarding stall per cell.
    VoxelCounters& c = out.deltas.emplace_back();
    c.length_m = length * static_cast<float>(grid.resolution_m());
    if (end != 0) {
      const EndEntry& entry = ends[end];
      c.hits = entry.hits;
      c.red = entry.red;
      c.green = entry.green;
      c.blue = entry.blue;
      // The points' offsets from the voxel centre, summed: R . sum + n (o - centre), in voxels.
      if (settings.hit_positions) {
        const double n = entry.hits;
        for (int a = 0; a < 3; ++a) {
          double sum = n * (origin[a] - static_cast<double>(entry.cell[a]) - 0.5);
          for (int b = 0; b < 3; ++b) sum += rotation[3 * a + b] * static_cast<double>(entry.sensor_sum[b]);
          c.offset[a] = static_cast<float>(sum);
        }
      }
    }
  }

  /// Checks the frame's pose and sets up its working frame; points the accumulator at the frame.
  WorkingFrame setUp(const Frame& frame);
  /// Fast mode in one pass: filter, transform and bundle straight into the range cube.
  void accumulateCube(const WorkingFrame& w, VoxelDeltas& out);
  /// accumulateCube()'s bundling; `lo`, `hi` (in/out) grow to the bounding box of the bundles.
  /// Returns the points beyond the range.
  uint64_t bundleCube(const WorkingFrame& w, int32_t lo[3], int32_t hi[3], IntegrationStats& st);
  /// Fast mode in two vectorised passes over a grid over the points' bounding box; false
  /// (nothing done) when no point is kept or the box is too large.
  bool accumulateBox(const WorkingFrame& w, VoxelDeltas& out);
  /// Every other frame: a filtered point list, cast into a store over its bounding box.
  void accumulatePoints(const WorkingFrame& w, VoxelDeltas& out);
  /// accumulatePoints()'s filter into `points`; `lo`, `hi` (in/out) grow to their bounding box.
  void listPoints(const WorkingFrame& w, int32_t lo[3], int32_t hi[3], IntegrationStats& st);
  /// Casts the point list into the hash store and emits its cells in key order.
  void castAndEmitHash(const WorkingFrame& w, VoxelDeltas& out);
  /// The end of every path: free space beyond the range when asked for, and the update count.
  void finishFrame(const WorkingFrame& w, bool carve, VoxelDeltas& out) {
    if (carve) carveBeyondRange(w, out);
    out.stats.voxel_updates = out.keys.size() + out.cube_keys.size();
  }
};

RayAccumulator::RayAccumulator(const KeyGrid& grid, const IntegratorSettings& settings)
    : impl_(std::make_unique<Impl>(grid, settings)) {}
RayAccumulator::~RayAccumulator() = default;
RayAccumulator::RayAccumulator(RayAccumulator&&) noexcept = default;
RayAccumulator& RayAccumulator::operator=(RayAccumulator&&) noexcept = default;

namespace {
template <class T>
size_t capacityBytes(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}
}  // namespace

size_t deltaBytes(const VoxelDeltas& d) {
  return capacityBytes(d.keys) + capacityBytes(d.deltas) + capacityBytes(d.cube_keys) + capacityBytes(d.cube_length_m);
}

size_t RayAccumulator::scratchBytes() const {
  const Impl& m = *impl_;
  return capacityBytes(m.points) + capacityBytes(m.cell_index) + capacityBytes(m.ends) + capacityBytes(m.beyond_ends) +
         m.dense.usedBytes() + capacityBytes(m.hash.slots) +
         m.cube.usedBytes() + capacityBytes(m.coarse_length) + capacityBytes(m.fine_rays) +
         capacityBytes(m.edge_frame.cloud.points) + capacityBytes(m.edge_frame.cloud.colours) +
         capacityBytes(m.edge_frame.cloud.labels);
}

void RayAccumulator::accumulate(const FrameSource& source, size_t i, VoxelDeltas& out) {
  if (const Frame* resident = source.resident(i)) {
    accumulate(*resident, out);
  } else {
    accumulate(source.load(i), out);
  }
}

void RayAccumulator::accumulate(const Frame& frame, VoxelDeltas& out) {
  Impl& s = *impl_;
  const std::vector<uint8_t> edges = depthEdgeMask(frame.cloud, s.settings.depth_edge_ratio);
  const auto dropped = static_cast<uint64_t>(std::count(edges.begin(), edges.end(), uint8_t{1}));
  if (dropped == 0) {
    s.accumulateFrame(frame, out);
    return;
  }
  // The frame without its depth-edge points (NaN: cast as invalid points, then counted apart).
  // Copy-assigned into the scratch frame, whose buffers keep their capacity from frame to frame.
  s.edge_frame = frame;
  for (size_t i = 0; i < edges.size(); ++i) {
    if (edges[i]) s.edge_frame.cloud.points[i].setConstant(std::numeric_limits<float>::quiet_NaN());
  }
  s.accumulateFrame(s.edge_frame, out);
  out.stats.points_invalid -= dropped;
  out.stats.points_depth_edges = dropped;
}

void RayAccumulator::Impl::accumulateFrame(const Frame& frame, VoxelDeltas& out) {
  Impl& s = *this;
  out.keys.clear();
  out.deltas.clear();
  out.cube_keys.clear();
  out.cube_length_m.clear();
  out.cube_level = 0;
  out.stats = IntegrationStats{};
  s.frame_out = &out;
  out.stats.frames = 1;
  const WorkingFrame w = s.setUp(frame);
  // Fast mode bundles in one pass over the cube. (Exact mode stays with two passes: its rays
  // touch every cell of the bounding box, and the smaller box grid measured faster.)
  if (s.settings.fast && w.cube_inside && cubeFits(w.side, s.settings.cube_max_cells)) {
    s.accumulateCube(w, out);
    return;
  }
  if (s.settings.fast && w.cube_inside && s.accumulateBox(w, out)) return;
  s.accumulatePoints(w, out);
}

WorkingFrame RayAccumulator::Impl::setUp(const Frame& frame) {
  const Eigen::Isometry3d& T = frame.T_world_sensor;
  if (!T.matrix().allFinite()) throw DataError(frame.source + ": sensor pose is not finite");
  const Eigen::Vector3d origin_m = T.translation();
  if (!grid.keyOf(origin_m)) {
    std::ostringstream msg;
    msg << frame.source << ": sensor position (" << origin_m.transpose() << ") m lies outside the map (|x| < "
        << grid.halfExtent_m() << " m at this resolution)";
    throw DataError(msg.str());
  }
  WorkingFrame w;
  // The bias reaches as far as the frame's farthest point, or the range when a point lies beyond
  // it: the working coordinates (floats) then depend on the points only, so every range that
  // reaches them all gives the same map, bit for bit (a bias from --max-range 1e6 rounded the
  // same points differently: 24,986 occupied voxels against 25,017 at 6 m). A reach beyond the
  // map's diagonal reaches no further voxel than the diagonal itself, so the bias stops there
  // and stays in integer range.
  const double inv_res = 1.0 / grid.resolution_m();
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are read as a flat float array");
  const float farthest_sq = integrate_detail::farthestSquaredNorm(
      frame.cloud.points.empty() ? nullptr : frame.cloud.points[0].data(), frame.cloud.points.size(), range_stop);
  const double reach_m = std::min(settings.max_range_m, std::sqrt(static_cast<double>(farthest_sq)));
  w.bias = biasForReach(reach_m, inv_res);
  const Eigen::Vector3d origin_u = grid.toKeySpace(origin_m);
  for (int a = 0; a < 3; ++a) {
    const int64_t cell = floorInt(origin_u[a]);
    w.oc[a] = cell - w.bias;
    w.o[a] = origin_u[a] - static_cast<double>(cell) + static_cast<double>(w.bias);
    key_origin[a] = w.oc[a];
  }
  // When the whole range cube lies inside the map, no point needs a bounds test.
  for (int a = 0; a < 3; ++a) {
    w.cube_inside = w.cube_inside && w.oc[a] >= 0 && w.oc[a] + 2 * w.bias + 1 < kKeysPerAxis;
  }
  const Eigen::Matrix3f R = (T.linear() * inv_res).cast<float>();  // sensor metres -> voxel units
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) w.Rm[3 * r + c] = R(r, c);
  }
  for (int a = 0; a < 3; ++a) w.of[a] = static_cast<float>(w.o[a]);
  // Squared in double, then saturated: a range past float's reach keeps every finite point.
  w.max_range = static_cast<float>(std::min(settings.max_range_m, double{std::numeric_limits<float>::max()}));
  w.max_range_sq = static_cast<float>(
      std::min(settings.max_range_m * settings.max_range_m, double{std::numeric_limits<float>::max()}));

  cloud = &frame.cloud;
  const Eigen::Matrix3d rotation_u = T.linear() * inv_res;
  for (int r = 0; r < 3; ++r) {
    origin[r] = w.o[r];
    for (int c = 0; c < 3; ++c) rotation[3 * r + c] = rotation_u(r, c);
  }
  w.colours = cloud->hasColours();
  ends.assign(1, EndEntry{});
  w.side = 2 * w.bias + 1;
  return w;
}

void RayAccumulator::Impl::accumulateCube(const WorkingFrame& w, VoxelDeltas& out) {
  IntegrationStats& st = out.stats;
  int32_t lo[3], hi[3];  // bounding box of the origin and all bundles
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = static_cast<int32_t>(w.o[a]);
  const uint64_t out_of_range = bundleCube(w, lo, hi, st);
  // Cast the bundle rays into a grid over the bounding box only.
  DenseStore& d = dense;
  const int64_t lo64[3] = {lo[0], lo[1], lo[2]}, hi64[3] = {hi[0], hi[1], hi[2]};
  d.reset(lo64, hi64, /*with_end=*/false);
  castBundles(w.o);
  float* length = d.length;
  // Emit in raster order (consecutive keys share most of their path in the tree), zeroing the
  // cube's and the box's cells read so that both are clean for the next frame.
  out.keys.reserve(ends.size() * 8);
  out.deltas.reserve(ends.size() * 8);
  uint32_t* end = cube.end;
  const int64_t sy = w.side, sz = w.side * w.side;
  const int64_t* oc = w.oc;
  const auto nx = static_cast<size_t>(hi[0] - lo[0] + 1);
  float* l_row = length;
  for (int64_t z = lo[2]; z <= hi[2]; ++z) {
    for (int64_t y = lo[1]; y <= hi[1]; ++y, l_row += nx) {
      uint32_t* e_row = end + static_cast<size_t>(sy * y + sz * z + lo[0]);
      emitAndClear(l_row, e_row, nx, [&](size_t k) {
        emitCell(oc[0] + lo[0] + static_cast<int64_t>(k), oc[1] + y, oc[2] + z, l_row[k], e_row[k], out);
      });
    }
  }
  cube.clean = true;
  d.rest();
  finishFrame(w, settings.carve_beyond_range && out_of_range > 0, out);
}

uint64_t RayAccumulator::Impl::bundleCube(const WorkingFrame& w, int32_t lo[3], int32_t hi[3],
                                          IntegrationStats& st) {
  const PointCloud& c_cloud = *cloud;
  const size_t n = c_cloud.points.size();
  cube.ensure(w.side, cube_room);
  cube.clean = false;  // until the emission has cleared what this frame writes
  const int64_t sy = w.side, sz = w.side * w.side;
  uint32_t* end = cube.end;
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are read as a flat float array");
  // Chunks small enough that the cell indices stay in cache between the two loops.
  constexpr size_t kChunk = 8192;
  cell_index.resize(std::min(n, kChunk));
  int32_t* cells = cell_index.data();
  uint64_t kept = 0, out_of_range = 0;
  for (size_t begin = 0; begin < n; begin += kChunk) {
    const size_t count = std::min(kChunk, n - begin);
    uint64_t beyond = 0;
    kept += cubeCells(c_cloud.points[begin].data(), count, w.Rm, w.of, w.max_range_sq, static_cast<int32_t>(sy),
                      static_cast<int32_t>(sz), cells, &beyond);
    out_of_range += beyond;
    bundleChunk(cells, begin, count, end, [&](int32_t c) {
      const int32_t c32[3] = {static_cast<int32_t>(c % sy), static_cast<int32_t>((c / sy) % sy),
                              static_cast<int32_t>(c / sz)};
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], c32[a]);
        hi[a] = std::max(hi[a], c32[a]);
      }
      const int64_t c64[3] = {c32[0], c32[1], c32[2]};
      return newEnd(c64);
    });
  }
  st.points = kept;
  st.points_out_of_range = out_of_range;
  st.points_invalid = n - kept - out_of_range;
  st.rays = ends.size() - 1;
  return out_of_range;
}

// For a cube too large for one pass (fine resolutions, 0.02 m at 3 m): one pass for the bounding
// box of the points' cells, one for their cells in a grid over that box, bundled as in the cube.
// The same cells, entries and order as the point list, which it replaces here (it measured 2.3
// of 27 ms per synthetic frame at 0.02 m); the list stays for frames near the map's edge and for
// exact mode.
bool RayAccumulator::Impl::accumulateBox(const WorkingFrame& w, VoxelDeltas& out) {
  IntegrationStats& st = out.stats;
  const PointCloud& c_cloud = *cloud;
  const size_t n = c_cloud.points.size();
  if (n == 0) return false;  // keeps no point: the point list takes the frame, as below
  int32_t lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = static_cast<int32_t>(w.o[a]);
  uint64_t out_of_range = 0;
  const uint64_t kept =
      pointBox(c_cloud.points[0].data(), n, w.Rm, w.of, w.max_range_sq, lo, hi, &out_of_range);
  const double cells = static_cast<double>(hi[0] - lo[0] + 1) * static_cast<double>(hi[1] - lo[1] + 1) *
                       static_cast<double>(hi[2] - lo[2] + 1);
  if (!(kept > 0 && cells <= static_cast<double>(settings.dense_grid_max_cells))) return false;
  st.points = kept;
  st.points_out_of_range = out_of_range;
  st.points_invalid = n - kept - out_of_range;
  DenseStore& d = dense;
  const int64_t lo64[3] = {lo[0], lo[1], lo[2]}, hi64[3] = {hi[0], hi[1], hi[2]};
  d.reset(lo64, hi64);
  const int64_t sy = d.n[0], sz = d.n[0] * d.n[1];
  constexpr size_t kChunk = 8192;
  cell_index.resize(std::min(n, kChunk));
  int32_t* cell_idx = cell_index.data();
  for (size_t begin = 0; begin < n; begin += kChunk) {
    const size_t count = std::min(kChunk, n - begin);
    boxCells(c_cloud.points[begin].data(), count, w.Rm, w.of, w.max_range_sq, lo, static_cast<int32_t>(sy),
             static_cast<int32_t>(sz), cell_idx);
    bundleChunk(cell_idx, begin, count, d.end, [&](int32_t c) {
      const int64_t cell[3] = {lo[0] + c % sy, lo[1] + (c / sy) % d.n[1], lo[2] + c / sz};
      return newEnd(cell);
    });
  }
  st.rays = ends.size() - 1;
  castBundles(w.o);
  emitDense(w.oc, out);
  finishFrame(w, settings.carve_beyond_range && out_of_range > 0, out);
  return true;
}

void RayAccumulator::Impl::listPoints(const WorkingFrame& w, int32_t lo[3], int32_t hi[3], IntegrationStats& st) {
  const PointCloud& c_cloud = *cloud;
  const int64_t* oc = w.oc;
  points.clear();
  const size_t n = c_cloud.points.size();
  points.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = c_cloud.points[i];
    const float r2 = p.squaredNorm();
    if (!(r2 <= w.max_range_sq && r2 > 0.0f)) {
      if (r2 > w.max_range_sq && std::isfinite(r2)) {
        ++st.points_out_of_range;
      } else {
        ++st.points_invalid;
      }
      continue;
    }
    RelPoint rp;
    transformPoint(w.Rm, w.of, p, rp.u);
    rp.colour = w.colours ? c_cloud.colours[i] : Rgb{};
    rp.index = static_cast<uint32_t>(i);
    if (!w.cube_inside) {
      // Tested before any integer conversion: a far point's coordinate may exceed int32.
      bool inside = true;
      for (int a = 0; a < 3; ++a) {
        inside = inside && rp.u[a] >= static_cast<float>(-oc[a]) && rp.u[a] < static_cast<float>(kKeysPerAxis - oc[a]);
      }
      if (!inside) {
        ++st.points_outside_map;
        continue;
      }
    }
    const int32_t c[3] = {static_cast<int32_t>(rp.u[0]), static_cast<int32_t>(rp.u[1]), static_cast<int32_t>(rp.u[2])};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], c[a]);
      hi[a] = std::max(hi[a], c[a]);
    }
    points.push_back(rp);
  }
}

// Two passes for large cubes (long ranges, fine resolutions): filter into a point list with its
// bounding box, then accumulate over that box only.
void RayAccumulator::Impl::accumulatePoints(const WorkingFrame& w, VoxelDeltas& out) {
  IntegrationStats& st = out.stats;
  int32_t lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = static_cast<int32_t>(w.o[a]);
  listPoints(w, lo, hi, st);
  st.points = points.size();
  st.rays = st.points;
  const bool carve = settings.carve_beyond_range && st.points_out_of_range > 0;
  if (st.points == 0) {
    finishFrame(w, carve, out);
    return;
  }
  const double cells = static_cast<double>(hi[0] - lo[0] + 1) * static_cast<double>(hi[1] - lo[1] + 1) *
                       static_cast<double>(hi[2] - lo[2] + 1);
  if (cells <= static_cast<double>(settings.dense_grid_max_cells)) {
    DenseStore& d = dense;
    const int64_t lo64[3] = {lo[0], lo[1], lo[2]}, hi64[3] = {hi[0], hi[1], hi[2]};
    d.reset(lo64, hi64);
    castDenseAll(w.o);
    emitDense(w.oc, out);
  } else {
    castAndEmitHash(w, out);
  }
  if (settings.fast) st.rays = ends.size() - 1;
  finishFrame(w, carve, out);
}

void RayAccumulator::Impl::castAndEmitHash(const WorkingFrame& w, VoxelDeltas& out) {
  HashStore& h = hash;
  h.reset();
  castHashAll(w.o, w.oc);
  std::vector<const HashStore::Slot*> filled;
  filled.reserve(h.used);
  for (const auto& slot : h.slots) {
    // As emitDense(): a cell that a ray only touched (length 0, as at a corner) is no update.
    if (slot.code != 0 && (slot.length > 0.0f || slot.end != 0)) filled.push_back(&slot);
  }
  std::sort(filled.begin(), filled.end(), [](auto* a, auto* b) { return a->code < b->code; });
  for (const auto* slot : filled) {
    const VoxelKey k = mortonDecode(slot->code - 1);
    emitCell(k.x, k.y, k.z, slot->length, slot->end, out);
  }
}

}  // namespace chronomap
