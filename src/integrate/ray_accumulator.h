#pragma once
/// @file
/// Internal to the integrate module: the scratch stores RayAccumulator casts one frame's rays
/// into (ray_accumulator.cpp), and what integrate(), IncrementalIntegrator and the accumulator
/// share.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "chronomap/integrate/integrator.h"
#include "zero_pages.h"

namespace chronomap::integrate_detail {

/// Stops integration that needs more than the memory limit, saying what needed it.
/// `share` follows the amount (" per thread" for a frame's scratch).
[[noreturn]] void refuseOverMemoryLimit(const char* what, size_t limit_bytes, const char* share, double resolution_m);

/// @throw UsageError for settings integrate() and IncrementalIntegrator refuse.
void checkSettings(const IntegratorSettings& settings);

/// The settings each thread's accumulator gets: its share of the memory limit.
IntegratorSettings perThread(const IntegratorSettings& settings, int threads);

/// Called after each merge: @throw UsageError when the map and the frames' scratch (the
/// accumulators' buffers and the deltas in flight, `scratch_bytes`) hold more than the memory
/// limit together (integrator.cpp says how the map is counted).
void checkMapMemory(const SessionMap& map, const IntegratorSettings& settings, size_t scratch_bytes = 0);


/// A valid end point in the frame's working coordinates: voxel units, relative to the lower
/// corner of the origin's voxel, plus a bias that makes every in-range coordinate positive (so
/// truncation is floor).
struct RelPoint {
  float u[3];
  Rgb colour;
  uint32_t index;  // in the frame's cloud
};

/// Hits and colour of one end voxel (in fast mode: one bundle). One entry per cache line: the
/// bundling loop measured 1.61 ms per synthetic frame with these, 1.75 ms with 40-byte entries
/// and 1.79 ms with 32-byte ones (neighbouring points alternate between neighbouring bundles,
/// whose entries then shared lines).
struct alignas(64) EndEntry {
  uint32_t hits = 0;
  uint32_t red = 0, green = 0, blue = 0;
  /// Sums of the points as the sensor saw them (metres, sensor frame; the fourth is unused):
  /// where in the voxel they ended follows from them once per entry (emitCell), which is
  /// cheaper than transforming every point for it. Every path adds the same points in the same
  /// order, so the float sums agree bit for bit.
  alignas(16) float sensor_sum[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  int64_t cell[3] = {0, 0, 0};  // working-frame voxel

  /// One more hit of colour (r, g, b): the four counters (which lie in this order) in one vector
  /// add, where the CPU has one. The bundling loop's consecutive points often go to the same
  /// entry, so each add waits for the last one's store: one store for the four measured faster
  /// than four.
  void addHit(uint8_t r, uint8_t g, uint8_t b) {
#if defined(__SSE2__)
    static_assert(offsetof(EndEntry, red) == 4 && offsetof(EndEntry, blue) == 12, "hits, red, green, blue in order");
    const __m128i add = _mm_set_epi32(b, g, r, 1);
    __m128i* counters = reinterpret_cast<__m128i*>(&hits);
    _mm_store_si128(counters, _mm_add_epi32(_mm_load_si128(counters), add));
#else
    ++hits;
    red += r;
    green += g;
    blue += b;
#endif
  }
  void addPoint(const Eigen::Vector3f& p) {
#if defined(__SSE2__)
    // One vector add (the lanes round exactly as three scalar adds would).
    const __m128 xy = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(p.data()));
    const __m128 xyz = _mm_movelh_ps(xy, _mm_load_ss(p.data() + 2));
    _mm_store_ps(sensor_sum, _mm_add_ps(_mm_load_ps(sensor_sum), xyz));
#else
    for (int a = 0; a < 3; ++a) sensor_sum[a] += p[a];
#endif
  }
};

/// Scratch cube of side 2 * bias + 1 around the sensor, covering every in-range point: the
/// end-entry index per cell. Zero at rest; emission zeroes what it reads, so a frame costs only
/// the cells it touches. (Ray lengths go to a grid over the bundles' bounding box, which is
/// far smaller and stays in cache.)
struct CubeStore {
  int64_t side = 0;
  uint32_t* end = nullptr;  // in `block`
  size_t cells = 0;         // room in `block`
  size_t used = 0;          // the most cells a cube was made for
  ZeroPages block;
  bool clean = true;  // every cell is zero (false while a frame uses the cube)

  CubeStore() = default;
  CubeStore(const CubeStore&) = delete;
  CubeStore& operator=(const CubeStore&) = delete;
  /// A clean block goes back to the pool for the next integration.
  ~CubeStore() {
    if (clean) ZeroPool::giveBack(std::move(block));
  }

  /// Makes room for a cube of side `s`, every cell zero. The cells are all zero between frames
  /// (each frame zeroes what it wrote), so a block large enough is reused whatever side it last
  /// had: the side follows each frame's farthest point and changes from frame to frame. A new
  /// block has room for a cube of side `room` (the largest the range allows) when that is
  /// larger, so that it is taken once (growing with the frames' sides zeroed it again at every
  /// new largest side: about 6 % of the time on the synthetic benchmark frames at 0.05 m); it comes
  /// from the pool, zero already, when an earlier integration left one.
  void ensure(int64_t s, int64_t room) {
    side = s;
    const auto need = static_cast<size_t>(s * s * s);
    if (cells >= need) {
      if (!clean) std::fill(end, end + cells, 0u);  // a frame stopped half way (an exception)
      clean = true;
      return;
    }
    const auto r = static_cast<size_t>(std::max<int64_t>(room, 0));
    const size_t want = std::max(need, r * r * r);
    ZeroPool::replace(block, want * sizeof(uint32_t), 0, clean);
    end = static_cast<uint32_t*>(block.data());
    cells = block.bytes() / sizeof(uint32_t);
    used = std::max(used, want);
    clean = true;
  }
  /// The most bytes a cube has been given (what the memory limit counts; a block from the
  /// pool may be larger).
  size_t usedBytes() const { return used * sizeof(uint32_t); }
};

/// Dense scratch over the frame's bounding box: ray length (voxel units) and end-entry index
/// (0 = none) per cell. Cells are indexed relative to the box's lower corner `lo`. Zero at rest,
/// as the range cube is: whoever reads the box after a frame (the emissions, the carving beyond
/// the range) zeroes each cell it finds written and calls rest(), so the next frame's box needs no
/// zeroing whatever its shape, and the blocks go back to the pool (ZeroPool), zero, for the next
/// integration. Zeroing each box whole and faulting in a new box at each integration was 18 % of
/// fast mode's samples on the five 3DMatch frames at 0.02 m.
struct DenseStore {
  int64_t lo[3] = {0, 0, 0}, n[3] = {0, 0, 0};
  float* length = nullptr;   // in `length_block`, `length_cells` cells
  uint32_t* end = nullptr;   // in `end_block`, `end_cells` cells
  size_t length_cells = 0, end_cells = 0;
  size_t used_cells = 0, used_end_cells = 0;  // the largest boxes asked for
  ZeroPages length_block, end_block;
  bool clean = true;  // every cell of both blocks is zero (false while a frame uses the box)

  DenseStore() = default;
  DenseStore(const DenseStore&) = delete;
  DenseStore& operator=(const DenseStore&) = delete;
  /// Clean blocks go back to the pool for the next integration.
  ~DenseStore() {
    if (clean) {
      ZeroPool::giveBack(std::move(length_block));
      ZeroPool::giveBack(std::move(end_block));
    }
  }

  /// The box [a, b], every cell zero; `with_end`: the end indices are used too (else `end` is
  /// left as it is, zero, and must not be written).
  void reset(const int64_t a[3], const int64_t b[3], bool with_end = true) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = a[k];
      n[k] = b[k] - a[k] + 1;
    }
    if (!clean) {  // a frame stopped half way (an exception): its cells were not read
      std::fill(length, length + length_cells, 0.0f);
      std::fill(end, end + end_cells, 0u);
      clean = true;
    }
    const size_t cells = static_cast<size_t>(n[0] * n[1] * n[2]);
    // A kept block large enough, else a new one with a quarter more room than asked, for the
    // next frames' boxes (a block's pages cost only when written); a failed take leaves the
    // store as it was (ZeroPool::replace).
    const size_t room = cells + cells / 4;
    if (cells > length_cells) {
      ZeroPool::replace(length_block, cells * sizeof(float), room * sizeof(float), true);
      length = static_cast<float*>(length_block.data());
      length_cells = length_block.bytes() / sizeof(float);
    }
    if (with_end && cells > end_cells) {
      ZeroPool::replace(end_block, cells * sizeof(uint32_t), room * sizeof(uint32_t), true);
      end = static_cast<uint32_t*>(end_block.data());
      end_cells = end_block.bytes() / sizeof(uint32_t);
    }
    used_cells = std::max(used_cells, cells);
    if (with_end) used_end_cells = std::max(used_end_cells, cells);
    clean = false;
  }
  /// Every cell the frame wrote has been zeroed again.
  void rest() { clean = true; }
  size_t cell(int64_t x, int64_t y, int64_t z) const {
    return static_cast<size_t>((x - lo[0]) + n[0] * ((y - lo[1]) + n[1] * (z - lo[2])));
  }
  /// The most bytes a frame's box has used (what the memory limit counts; the blocks may hold
  /// more, untouched, or what an earlier integration left in the pool).
  size_t usedBytes() const { return used_cells * sizeof(float) + used_end_cells * sizeof(uint32_t); }
};

/// Open-addressing hash scratch for frames whose bounding box is too large for a dense grid.
struct HashStore {
  struct Slot {
    uint64_t code = 0;  // Morton code + 1; 0 = empty
    float length = 0.0f;
    uint32_t end = 0;
  };
  std::vector<Slot> slots;
  size_t used = 0;
  size_t max_bytes = 0;  // 0: no limit
  double resolution_m = 0.0;

  /// A table of `n` slots and the deltas of the voxels it can hold (half of them) once emitted.
  static size_t bytesFor(size_t n) { return n * sizeof(Slot) + n / 2 * (sizeof(VoxelKey) + sizeof(VoxelCounters)); }

  void reset() {
    slots.assign(1 << 16, Slot{});
    used = 0;
  }
  static size_t hashOf(uint64_t code) { return static_cast<size_t>((code * 0x9E3779B97F4A7C15ULL) >> 20); }
  Slot& slot(int64_t x, int64_t y, int64_t z) {
    if (2 * (used + 1) > slots.size()) grow();
    const uint64_t code =
        mortonEncode(VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)}) + 1;
    const size_t mask = slots.size() - 1;
    size_t i = hashOf(code) & mask;
    while (slots[i].code != 0 && slots[i].code != code) i = (i + 1) & mask;
    if (slots[i].code == 0) {
      slots[i].code = code;
      ++used;
    }
    return slots[i];
  }
  void grow() {
    if (max_bytes != 0 && bytesFor(slots.size() * 2) > max_bytes) {
      refuseOverMemoryLimit("casting one frame's rays", max_bytes, " per thread", resolution_m);
    }
    std::vector<Slot> old = std::move(slots);
    slots.assign(old.size() * 2, Slot{});
    const size_t mask = slots.size() - 1;
    for (const Slot& s : old) {
      if (s.code == 0) continue;
      size_t i = hashOf(s.code) & mask;
      while (slots[i].code != 0) i = (i + 1) & mask;
      slots[i] = s;
    }
  }
};

}  // namespace chronomap::integrate_detail
