// integrate(): frames cast in parallel (ray_accumulator.cpp) and merged in frame order; the
// settings checks and memory limit it shares with IncrementalIntegrator.
#include "chronomap/integrate/integrator.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <iomanip>
#include <map>
#include <mutex>
#include <type_traits>
#include <sstream>
#include <string>
#include <thread>

#include <unistd.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/happens_before.h"
#include "chronomap/core/memory.h"
#include "ray_accumulator.h"

namespace chronomap {

IntegrationStats& IntegrationStats::operator+=(const IntegrationStats& o) {
  frames += o.frames;
  points += o.points;
  points_invalid += o.points_invalid;
  points_out_of_range += o.points_out_of_range;
  points_outside_map += o.points_outside_map;
  rays += o.rays;
  voxel_updates += o.voxel_updates;
  seconds += o.seconds;
  points_depth_edges += o.points_depth_edges;
  return *this;
}

std::vector<uint8_t> depthEdgeMask(const PointCloud& cloud, double ratio) {
  const size_t w = cloud.width, h = cloud.height;
  if (!(ratio > 0.0) || h < 2 || w * h != cloud.size()) return {};
  std::vector<float> range(cloud.size());
  for (size_t i = 0; i < range.size(); ++i) {
    const float r = cloud.points[i].norm();
    range[i] = std::isfinite(r) && r > 0.0f ? r : 0.0f;  // 0: invalid, never compared
  }
  const float share = static_cast<float>(ratio);
  // Whether valid pixel (x, y) has a valid neighbour whose range differs by more than the share.
  const auto atEdge = [&](size_t x, size_t y) {
    const float limit = share * range[y * w + x];
    for (size_t ny = y > 0 ? y - 1 : 0; ny <= std::min(y + 1, h - 1); ++ny) {
      for (size_t nx = x > 0 ? x - 1 : 0; nx <= std::min(x + 1, w - 1); ++nx) {
        const float q = range[ny * w + nx];
        if (q != 0.0f && std::abs(q - range[y * w + x]) > limit) return true;
      }
    }
    return false;
  };
  std::vector<uint8_t> drop(cloud.size(), 0);
  for (size_t y = 0; y < h; ++y) {
    for (size_t x = 0; x < w; ++x) drop[y * w + x] = range[y * w + x] != 0.0f && atEdge(x, y) ? 1 : 0;
  }
  return drop;
}

std::vector<std::string> droppedPointsWarnings(const IntegrationStats& stats, const IntegratorSettings& settings) {
  std::vector<std::string> lines;
  const uint64_t valid = stats.points + stats.points_out_of_range + stats.points_outside_map;
  const auto share = [valid](uint64_t n) {
    std::ostringstream s;
    s << n << " of " << valid << " valid points (" << std::fixed << std::setprecision(1)
      << 100.0 * static_cast<double>(n) / static_cast<double>(valid) << "%)";
    return s.str();
  };
  const auto over = [valid](uint64_t n) {
    return valid > 0 && static_cast<double>(n) > kDroppedPointsWarnFraction * static_cast<double>(valid);
  };
  if (over(stats.points_out_of_range)) {
    std::ostringstream s;
    s << share(stats.points_out_of_range) << " lie beyond --max-range " << settings.max_range_m << " m; "
      << (settings.carve_beyond_range ? "the free space before them is kept, their surfaces are not"
                                      : "they were dropped, with the free space before them")
      << ": give --max-range what the sensor delivers to keep them"
      << (settings.carve_beyond_range ? "" : " (or --carve-beyond-range for their free space)");
    lines.push_back(s.str());
  }
  if (over(stats.points_outside_map)) {
    lines.push_back(share(stats.points_outside_map) +
                    " fall outside the map's extent and were dropped: use a coarser --resolution (the map spans " +
                    std::to_string(kKeysPerAxis) + " voxels per axis around the origin), or poses nearer the origin");
  }
  return lines;
}

namespace integrate_detail {

[[noreturn]] void refuseOverMemoryLimit(const char* what, size_t limit_bytes, const char* share, double resolution_m) {
  std::ostringstream msg;
  msg << what << " needs more than " << humanBytes(static_cast<double>(limit_bytes)) << share << " at resolution "
      << resolution_m << " m; use a coarser --resolution or raise --memory-limit";
  throw UsageError(msg.str());
}

IntegratorSettings perThread(const IntegratorSettings& settings, int threads) {
  IntegratorSettings s = settings;
  // A share of a limit is a limit: never 0, which means none.
  if (s.memory_limit_bytes != 0) s.memory_limit_bytes = std::max<size_t>(1, s.memory_limit_bytes / static_cast<size_t>(threads));
  return s;
}

/// Called after each merge: one comparison, so the limit costs nothing per point. The pools
/// grow 4x (session_map.cpp); what they hold is counted as at most twice their size, as much as
/// a pool that doubles reserves (its growth copies the used part; the rest of the capacity is
/// address space no page backs until written).
void checkMapMemory(const SessionMap& map, const IntegratorSettings& settings, size_t scratch_bytes) {
  const size_t held = std::min(map.reservedBytes(), 2 * map.memoryBytes());
  if (settings.memory_limit_bytes != 0 && held + scratch_bytes > settings.memory_limit_bytes) {
    refuseOverMemoryLimit(scratch_bytes ? "the session map with the frames' scratch" : "the session map",
                          settings.memory_limit_bytes, "", map.resolution_m());
  }
}

void checkSettings(const IntegratorSettings& settings) {
  if (!std::isfinite(settings.max_range_m) || settings.max_range_m <= 0.0) {
    throw UsageError("max range must be a positive number of metres");
  }
  if (settings.threads < 0) throw UsageError("thread count must be 0 (all cores) or positive");
  if (settings.carve_level != kCarveAuto && (settings.carve_level < 0 || settings.carve_level > kMaxCarveLevel)) {
    throw UsageError("carve level must be auto (" + std::to_string(kCarveAuto) + ") or 0 (off) to " +
                     std::to_string(kMaxCarveLevel));
  }
  if (settings.carve_level > 0 && !settings.fast) throw UsageError("carving free space coarser needs fast mode");
  if (!std::isfinite(settings.depth_edge_ratio) || settings.depth_edge_ratio < 0.0) {
    throw UsageError("the depth edge ratio must be 0 (off) or a positive share of a point's range");
  }
}


}  // namespace integrate_detail

using integrate_detail::checkMapMemory;
using integrate_detail::checkSettings;
using integrate_detail::perThread;

int carveLevelFor(const IntegratorSettings& settings, double resolution_m) {
  if (settings.carve_level != kCarveAuto) return settings.carve_level;
  // The tolerance keeps a resolution typed as 0.025 on the fine side.
  return settings.fast && resolution_m <= kCarveAutoCoarsestResolutionM * (1 + 1e-9) ? 2 : 0;
}

void mergeDeltas(SessionMap& map, const VoxelDeltas& deltas) {
  map.addMany(deltas.keys, deltas.deltas);
  if (!deltas.cube_keys.empty()) map.addCubes(deltas.cube_keys, deltas.cube_level, deltas.cube_length_m);
}

size_t defaultMemoryLimitBytes() { return processMemoryBytes() / 2; }

namespace {

constexpr uint32_t kDeltasMagic = 0x4c444d43;  // "CMDL" in the file's byte order

/// Appends the bytes of `values` as they lie in memory.
template <class T>
void putAll(ByteWriter& w, const std::vector<T>& values) {
  static_assert(std::is_trivially_copyable_v<T>);
  const size_t at = w.bytes.size();
  w.bytes.resize(at + values.size() * sizeof(T));
  if (!values.empty()) std::memcpy(w.bytes.data() + at, values.data(), values.size() * sizeof(T));
}

/// Reads `count` values written by putAll.
template <class T>
void getAll(ByteReader& r, uint64_t count, std::vector<T>& out) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (count > (r.bytes.size() - r.pos) / sizeof(T)) throw FormatError(r.source + ": " + r.what + " ends early (truncated)");
  out.resize(static_cast<size_t>(count));
  if (count != 0) std::memcpy(out.data(), r.bytes.data() + r.pos, out.size() * sizeof(T));
  r.pos += out.size() * sizeof(T);
}

}  // namespace

std::vector<uint8_t> encodeDeltas(const VoxelDeltas& d) {
  ByteWriter w;
  w.bytes.reserve(64 + d.keys.size() * (sizeof(VoxelKey) + sizeof(VoxelCounters)) +
                  d.cube_keys.size() * (sizeof(VoxelKey) + sizeof(float)));
  w.put(kDeltasMagic);
  w.put(static_cast<uint64_t>(d.keys.size()));
  w.put(static_cast<uint64_t>(d.cube_keys.size()));
  w.put(static_cast<int32_t>(d.cube_level));
  const IntegrationStats& st = d.stats;
  for (const uint64_t v : {st.frames, st.points, st.points_invalid, st.points_out_of_range, st.points_outside_map,
                           st.rays, st.voxel_updates, st.points_depth_edges}) {
    w.put(v);
  }
  w.put(st.seconds);
  putAll(w, d.keys);
  putAll(w, d.deltas);
  putAll(w, d.cube_keys);
  putAll(w, d.cube_length_m);
  return std::move(w.bytes);
}

void decodeDeltas(std::span<const uint8_t> bytes, VoxelDeltas& out, const std::string& source) {
  ByteReader r{bytes, 0, source, "a frame's deltas"};
  if (r.get<uint32_t>() != kDeltasMagic) throw FormatError(source + ": not a frame's deltas");
  const auto keys = r.get<uint64_t>(), cubes = r.get<uint64_t>();
  out.cube_level = r.get<int32_t>();
  if (cubes != 0 && (out.cube_level <= 0 || out.cube_level > kMaxCarveLevel)) {
    throw FormatError(source + ": a cube level of " + std::to_string(out.cube_level));
  }
  IntegrationStats& st = out.stats;
  for (uint64_t* v : {&st.frames, &st.points, &st.points_invalid, &st.points_out_of_range, &st.points_outside_map,
                      &st.rays, &st.voxel_updates, &st.points_depth_edges}) {
    *v = r.get<uint64_t>();
  }
  st.seconds = r.get<double>();
  getAll(r, keys, out.keys);
  getAll(r, keys, out.deltas);
  getAll(r, cubes, out.cube_keys);
  getAll(r, cubes, out.cube_length_m);
  if (r.pos != bytes.size()) {
    throw FormatError(source + ": " + std::to_string(bytes.size() - r.pos) + " byte(s) after a frame's deltas");
  }
}

namespace {

/// Frames' deltas buffers kept between integrations in a process, with their capacity, so that a
/// short integration does not fault their pages in again (as the scratch grids, ZeroPool): at
/// most 8 buffers and 64 MiB in all; what does not fit is freed. Their contents do not matter
/// (accumulate() clears a buffer first).
class KeptDeltas {
 public:
  static constexpr size_t kMaxBuffers = 8;
  static constexpr size_t kMaxBytes = size_t{64} << 20;
  /// `n` buffers, the kept ones first.
  static std::vector<VoxelDeltas> take(size_t n) {
    std::vector<VoxelDeltas> out;
    out.reserve(n);
    {
      const std::lock_guard<std::mutex> lock(mutex());
      std::vector<VoxelDeltas>& k = kept();
      while (out.size() < n && !k.empty()) {
        out.push_back(std::move(k.back()));
        k.pop_back();
      }
    }
    out.resize(n);
    return out;
  }
  static void giveBack(std::vector<VoxelDeltas>& buffers) noexcept {
    const std::lock_guard<std::mutex> lock(mutex());
    std::vector<VoxelDeltas>& k = kept();
    size_t bytes = 0;
    for (const VoxelDeltas& d : k) bytes += deltaBytes(d);
    for (VoxelDeltas& d : buffers) {
      const size_t b = deltaBytes(d);
      if (b == 0 || k.size() >= kMaxBuffers || bytes + b > kMaxBytes || k.size() == k.capacity()) continue;
      bytes += b;
      k.push_back(std::move(d));
    }
    buffers.clear();
  }

 private:
  static std::mutex& mutex() {
    static std::mutex* const m = new std::mutex;  // never destroyed (giveBack at exit)
    return *m;
  }
  static std::vector<VoxelDeltas>& kept() {
    static std::vector<VoxelDeltas>* const k = [] {
      auto* v = new std::vector<VoxelDeltas>;
      v->reserve(kMaxBuffers);
      return v;
    }();
    return *k;
  }
};

/// Buffers from KeptDeltas, given back when the integration ends (or stops).
struct DeltaBuffers {
  std::vector<VoxelDeltas> buffers;
  explicit DeltaBuffers(size_t n) : buffers(KeptDeltas::take(n)) {}
  ~DeltaBuffers() { KeptDeltas::giveBack(buffers); }
  DeltaBuffers(const DeltaBuffers&) = delete;
  DeltaBuffers& operator=(const DeltaBuffers&) = delete;
};

/// integrate() on the calling thread; adds each frame's stats to `total`.
void integrateSerial(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings,
                     const ProgressFn& progress, IntegrationStats& total) {
  const size_t n = source.size();
  RayAccumulator acc(map.grid(), perThread(settings, 1));
  DeltaBuffers kept(1);
  VoxelDeltas& deltas = kept.buffers[0];
  for (size_t i = 0; i < n; ++i) {
    acc.accumulate(source, i, deltas);
    mergeDeltas(map, deltas);
    checkMapMemory(map, settings, acc.scratchBytes() + deltaBytes(deltas));
    total += deltas.stats;
    if (progress) progress(i + 1, n);
  }
}

/// integrate() over `threads` threads; adds each frame's stats to `total`.
void integrateParallel(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings,
                       const ProgressFn& progress, int threads, IntegrationStats& total) {
  const size_t n = source.size();
  // Frames are loaded and cast in parallel; merging stays serial and in frame order, so the
  // map is the same for every thread count.
  tbb::enumerable_thread_specific<RayAccumulator> accumulators(map.grid(), perThread(settings, threads));
  // At most `tokens` frames are in flight, each in its own buffer; the stages pass buffer
  // numbers, and a merged buffer goes back to the free list.
  const size_t tokens = static_cast<size_t>(threads) * 2;
  DeltaBuffers kept(tokens);
  std::vector<VoxelDeltas>& buffers = kept.buffers;
  // Each buffer's deltas plus the scratch of the accumulator that filled it, as it was then
  // (written by the casting stage before the hand-over, summed by the merging one).
  std::vector<std::atomic<size_t>> scratch(tokens);
  std::vector<size_t> free_buffers(tokens);
  // Handed out from the back: the kept buffers (at the front) first.
  for (size_t b = 0; b < tokens; ++b) free_buffers[b] = tokens - 1 - b;
  std::mutex free_mutex;
  tbb::task_arena arena(threads);
  // Hand-overs between the stages' threads, for ThreadSanitizer (core/happens_before.h). The
  // marks are static objects: a stage must not read its captures before its mark, nor any
  // of this thread's variables after its closing mark.
  static char setup_done, source_turn, handed_over, merge_turn;
  arena.execute([&] {
    size_t next = 0;
    auto stages =
        tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order,
                                       [&](tbb::flow_control& fc) -> size_t {
                                         CHRONOMAP_HAPPENS_AFTER(&setup_done);
                                         CHRONOMAP_HAPPENS_AFTER(&source_turn);  // one call after another
                                         const size_t i = next < n ? next++ : n;
                                         const bool done = i >= n;  // n is read before the mark
                                         CHRONOMAP_HAPPENS_BEFORE(&source_turn);
                                         if (done) {
                                           fc.stop();
                                           return 0;
                                         }
                                         return i;
                                       }) &
        tbb::make_filter<size_t, size_t>(
            tbb::filter_mode::parallel,
            [&](size_t i) {
              CHRONOMAP_HAPPENS_AFTER(&setup_done);
              size_t b = 0;
              {
                std::lock_guard<std::mutex> lock(free_mutex);
                b = free_buffers.back();
                free_buffers.pop_back();
              }
              try {
                accumulators.local().accumulate(source, i, buffers[b]);
                scratch[b].store(accumulators.local().scratchBytes() + deltaBytes(buffers[b]),
                                 std::memory_order_relaxed);
              } catch (...) {
                CHRONOMAP_HAPPENS_BEFORE(&handed_over);  // to the caller, which rethrows
                throw;
              }
              CHRONOMAP_HAPPENS_BEFORE(&handed_over);  // to the merging stage
              return b;
            }) &
        tbb::make_filter<size_t, void>(tbb::filter_mode::serial_in_order, [&](size_t b) {
          CHRONOMAP_HAPPENS_AFTER(&setup_done);
          CHRONOMAP_HAPPENS_AFTER(&handed_over);
          CHRONOMAP_HAPPENS_AFTER(&merge_turn);  // one merge after another
          mergeDeltas(map, buffers[b]);
          try {
            size_t in_flight = 0;
            for (const std::atomic<size_t>& bytes : scratch) in_flight += bytes.load(std::memory_order_relaxed);
            checkMapMemory(map, settings, in_flight);
            total += buffers[b].stats;
            if (progress) progress(static_cast<size_t>(total.frames), n);  // may throw to stop
          } catch (...) {
            CHRONOMAP_HAPPENS_BEFORE(&merge_turn);  // to the caller, which rethrows
            throw;
          }
          {
            std::lock_guard<std::mutex> lock(free_mutex);
            free_buffers.push_back(b);
          }
          CHRONOMAP_HAPPENS_BEFORE(&merge_turn);
        });
    CHRONOMAP_HAPPENS_BEFORE(&setup_done);
    try {
      tbb::parallel_pipeline(tokens, stages);
    } catch (...) {
      // A stage threw (a bad frame, the memory limit, a progress callback stopping the work):
      // TBB has waited for the others, and the stages that ran marked what they touched.
      CHRONOMAP_HAPPENS_AFTER(&source_turn);
      CHRONOMAP_HAPPENS_AFTER(&handed_over);
      CHRONOMAP_HAPPENS_AFTER(&merge_turn);
      throw;
    }
    CHRONOMAP_HAPPENS_AFTER(&source_turn);
    CHRONOMAP_HAPPENS_AFTER(&merge_turn);
  });
}

/// Frames this process casts before their turn while it waits for others' (integrateShared): at
/// most this many are held.
constexpr size_t kMostCastAhead = 8;

/// integrate() with frames cast by other processes too: frames are merged in frame order whoever
/// cast them, so the map is integrateSerial's. Frames are handed out ahead of the one merged; while
/// a handed-out frame has not arrived, this process casts the next free frame itself and holds its
/// deltas (or what casting it threw) until its turn, so that an error is the first in frame order,
/// as one process gives it.
void integrateShared(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings,
                     const ProgressFn& progress, FrameSharing& sharing, IntegrationStats& total) {
  const size_t n = source.size();
  RayAccumulator acc(map.grid(), perThread(settings, 1));
  struct Ahead {
    VoxelDeltas deltas;
    std::exception_ptr error;
  };
  std::map<size_t, Ahead> ahead;
  size_t ahead_bytes = 0;
  VoxelDeltas deltas;
  size_t next = 0;  // every frame from the merged ones to here is handed out or cast ahead
  for (size_t i = 0; i < n; ++i) {
    next = std::max(next, i);
    while (next < n && sharing.handedOut(next)) ++next;  // handed out before integrate() began
    next += sharing.handOut(next, n);
    if (sharing.handedOut(i)) {
      while (!sharing.collect(i, deltas, /*wait=*/false)) {
        if (next >= n || ahead.size() >= kMostCastAhead) {
          sharing.collect(i, deltas, /*wait=*/true);
          break;
        }
        Ahead& a = ahead[next];
        try {
          acc.accumulate(source, next, a.deltas);
          ahead_bytes += deltaBytes(a.deltas);
        } catch (...) {
          a.error = std::current_exception();
        }
        ++next;
        next += sharing.handOut(next, n);
      }
    } else if (const auto it = ahead.find(i); it != ahead.end()) {
      if (it->second.error) std::rethrow_exception(it->second.error);
      std::swap(deltas, it->second.deltas);
      ahead_bytes -= deltaBytes(deltas);
      ahead.erase(it);
    } else {
      acc.accumulate(source, i, deltas);
    }
    mergeDeltas(map, deltas);
    checkMapMemory(map, settings, acc.scratchBytes() + deltaBytes(deltas) + ahead_bytes);
    total += deltas.stats;
    if (progress) progress(i + 1, n);
  }
  sharing.framesDone();
}

}  // namespace

std::unique_ptr<MemoryActivity> integrationMemoryActivity(size_t frames, double resolution_m) {
  std::ostringstream what;
  what << "integrating " << frames << " frame(s) at resolution " << resolution_m << " m";
  return std::make_unique<MemoryActivity>(what.str(),
                                          "use a coarser --resolution, fewer --threads, or a --memory-limit below "
                                          "the memory this process may use (" +
                                              humanBytes(static_cast<double>(processMemoryBytes())) + ")");
}

IntegrationStats integrate(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings,
                           const ProgressFn& progress, FrameSharing* sharing) {
  checkSettings(settings);
  const auto start = std::chrono::steady_clock::now();
  IntegrationStats total;
  const size_t n = source.size();
  const auto activity = integrationMemoryActivity(n, map.resolution_m());
  int threads = settings.threads > 0 ? settings.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::max(1, threads);
  if (sharing) {
    integrateShared(source, map, settings, progress, *sharing, total);
  } else if (threads == 1 || n <= 1) {
    integrateSerial(source, map, settings, progress, total);
  } else {
    integrateParallel(source, map, settings, progress, threads, total);
  }
  if (settings.compress_free) map.compressFree();
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace chronomap
