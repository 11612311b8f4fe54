#include "chronomap/integrate/static_points.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>
#include <vector>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "chronomap/core/error.h"
#include "chronomap/core/key.h"

namespace chronomap {

namespace {

void checkSettings(const StaticPointSettings& s) {
  if (!(s.max_range_m > 0.0) || !std::isfinite(s.max_range_m)) {
    throw UsageError("static points: max range must be a positive number of metres");
  }
  if (!(s.free_length_voxels >= 0.0) || !(s.min_free_ratio >= 0.0) || !(s.free_margin_m >= 0.0) ||
      !(s.free_margin_per_m2 >= 0.0)) {
    throw UsageError("static points: the free length, the free ratio and the free margins must not be negative");
  }
  if (s.min_free_frames == 0) throw UsageError("static points: at least one frame must observe a voxel free");
  if (s.spread_steps < 0 || !(s.spread_fraction >= 0.0 && s.spread_fraction <= 1.0)) {
    throw UsageError("static points: the spread steps must not be negative and the spread fraction must lie in [0, 1]");
  }
  if (s.occupied_dilation_voxels < 0 || s.occupied_dilation_voxels > 3) {
    throw UsageError("static points: the occupied dilation must lie in [0, 3] voxels");
  }
}

IntegratorSettings integratorSettings(const StaticPointSettings& s) {
  IntegratorSettings o;
  o.max_range_m = s.max_range_m;
  o.fast = s.fast;
  o.threads = 1;  // one frame per thread here
  o.carve_level = 0;
  o.hit_positions = false;
  o.compress_free = false;
  return o;
}

/// Frames cast in batches of one per thread; their counts merged in frame order (sums, so the
/// order does not change them, but it keeps memory to one batch of deltas).
template <typename PerFrame, typename Merge>
void inBatches(const FrameSource& source, size_t threads, size_t progress_offset, size_t progress_total,
               const ProgressFn& progress, PerFrame per_frame, Merge merge) {
  using Out = decltype(per_frame(size_t{0}));
  const size_t n = source.size();
  const size_t batch = std::max<size_t>(1, threads * 2);
  std::vector<Out> outs;
  for (size_t first = 0; first < n; first += batch) {
    const size_t count = std::min(batch, n - first);
    outs.assign(count, Out{});
    tbb::parallel_for(size_t{0}, count, [&](size_t k) { outs[k] = per_frame(first + k); });
    for (size_t k = 0; k < count; ++k) merge(first + k, outs[k]);
    if (progress) progress(progress_offset + first + count, progress_total);
  }
}

/// fn(frame i of `source`): the frame it holds, else the one it loads.
template <typename Fn>
auto onFrame(const FrameSource& source, size_t i, Fn fn) {
  if (const Frame* resident = source.resident(i)) return fn(*resident);
  return fn(source.load(i));
}

/// The voxels a frame's points lie in (within the range), as sorted unique Morton codes.
std::vector<uint64_t> occupiedCodes(const Frame& frame, const KeyGrid& grid, const StaticPointSettings& s) {
  std::vector<uint64_t> codes;
  codes.reserve(frame.cloud.points.size());
  const double max_range_sq = s.max_range_m * s.max_range_m;
  for (const Eigen::Vector3f& p : frame.cloud.points) {
    const double range_sq = p.cast<double>().squaredNorm();
    if (!p.allFinite() || range_sq == 0.0 || range_sq > max_range_sq) continue;
    if (const auto key = grid.keyOf(frame.T_world_sensor * p.cast<double>())) codes.push_back(mortonEncode(*key));
  }
  std::sort(codes.begin(), codes.end());
  codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
  return codes;
}

/// The voxels within `radius` voxels (per axis) of `codes`, sorted and unique.
std::vector<uint64_t> dilated(const std::vector<uint64_t>& codes, int radius) {
  if (radius == 0) return codes;
  std::vector<uint64_t> out;
  out.reserve(codes.size() * static_cast<size_t>((2 * radius + 1) * (2 * radius + 1) * (2 * radius + 1)));
  for (uint64_t code : codes) {
    forEachKeyInCube(mortonDecode(code), radius, [&](const VoxelKey& k) { out.push_back(mortonEncode(k)); });
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool contains(const std::vector<uint64_t>& sorted, uint64_t code) {
  return std::binary_search(sorted.begin(), sorted.end(), code);
}

/// Where `code` is in `surface` (sorted), or surface.size().
size_t indexOf(const std::vector<uint64_t>& surface, uint64_t code) {
  const auto it = std::lower_bound(surface.begin(), surface.end(), code);
  return it != surface.end() && *it == code ? static_cast<size_t>(it - surface.begin()) : surface.size();
}

/// One frame's evidence, as indices into the surface voxels: those its points lie in, and those
/// its rays (cut short by the margin; their hits ignored: the cut end points are no surface)
/// cross for the free length while none of its points lies within the dilation.
struct FrameEvidence {
  std::vector<uint32_t> occupied, free;
};

FrameEvidence frameEvidence(const Frame& frame, const KeyGrid& grid, const StaticPointSettings& s,
                            const std::vector<uint64_t>& surface, RayAccumulator& accumulator) {
  const std::vector<uint64_t> occupied = occupiedCodes(frame, grid, s);
  const std::vector<uint64_t> near = dilated(occupied, s.occupied_dilation_voxels);
  FrameEvidence out;
  for (uint64_t code : occupied) out.occupied.push_back(static_cast<uint32_t>(indexOf(surface, code)));
  Frame cut;
  cut.T_world_sensor = frame.T_world_sensor;
  cut.cloud.points.reserve(frame.cloud.points.size());
  const double max_range_sq = s.max_range_m * s.max_range_m;
  for (const Eigen::Vector3f& p : frame.cloud.points) {
    const double range_sq = p.cast<double>().squaredNorm();
    if (!p.allFinite() || range_sq == 0.0 || range_sq > max_range_sq) continue;
    const double range = std::sqrt(range_sq);
    const double kept = range - s.free_margin_m - s.free_margin_per_m2 * range_sq;
    if (kept > 0.0) cut.cloud.points.push_back(p * static_cast<float>(kept / range));
  }
  cut.cloud.width = static_cast<uint32_t>(cut.cloud.points.size());
  VoxelDeltas deltas;
  accumulator.accumulate(cut, deltas);
  const float free_length_m = static_cast<float>(s.free_length_voxels * grid.resolution_m());
  for (size_t k = 0; k < deltas.keys.size(); ++k) {
    if (deltas.deltas[k].length_m < free_length_m) continue;
    const uint64_t code = mortonEncode(deltas.keys[k]);
    const size_t index = indexOf(surface, code);
    if (index < surface.size() && !contains(near, code)) out.free.push_back(static_cast<uint32_t>(index));
  }
  return out;
}

/// Pass 1: every voxel a point of any frame lies in (the only ones whose history matters).
std::vector<uint64_t> surfaceVoxels(const FrameSource& source, const KeyGrid& grid, const StaticPointSettings& s,
                                    size_t threads, const ProgressFn& progress) {
  std::vector<uint64_t> surface;
  inBatches(
      source, threads, 0, 3 * source.size(), progress,
      [&](size_t i) { return onFrame(source, i, [&](const Frame& f) { return occupiedCodes(f, grid, s); }); },
      [&](size_t, const std::vector<uint64_t>& codes) { surface.insert(surface.end(), codes.begin(), codes.end()); });
  std::sort(surface.begin(), surface.end());
  surface.erase(std::unique(surface.begin(), surface.end()), surface.end());
  return surface;
}

/// Pass 2: each frame's points and rays, counted per surface voxel as an occupied or a free frame.
std::vector<VoxelFrameCounts> countFrames(const FrameSource& source, const KeyGrid& grid, const StaticPointSettings& s,
                                          const std::vector<uint64_t>& surface, size_t threads,
                                          const ProgressFn& progress) {
  const IntegratorSettings settings = integratorSettings(s);
  tbb::enumerable_thread_specific<RayAccumulator> accumulators([&] { return RayAccumulator(grid, settings); });
  std::vector<VoxelFrameCounts> counts(surface.size());
  inBatches(
      source, threads, source.size(), 3 * source.size(), progress,
      [&](size_t i) {
        return onFrame(source, i,
                       [&](const Frame& f) { return frameEvidence(f, grid, s, surface, accumulators.local()); });
      },
      [&](size_t, const FrameEvidence& e) {
        for (uint32_t index : e.occupied) ++counts[index].occupied_frames;
        for (uint32_t index : e.free) ++counts[index].free_frames;
      });
  return counts;
}

/// One frame's points judged: kept (world frame) and the counts.
struct Judged {
  PointCloud kept;
  uint64_t in = 0, invalid = 0, unjudged = 0, dynamic = 0;
};

/// Calls `fn` with the Morton code of each of the 26 neighbours of `code` inside the key space.
template <typename Fn>
void forNeighbours(uint64_t code, Fn fn) {
  forEachKeyInCube(mortonDecode(code), 1, [&](const VoxelKey& k) {
    const uint64_t n = mortonEncode(k);
    if (n != code) fn(n);
  });
}

/// The voxels of one frame (its sorted occupied codes) whose points go: those judged dynamic,
/// grown by spreadDynamic (a person's parts never seen free, beside parts that were).
std::vector<uint64_t> dynamicInFrame(const std::vector<uint64_t>& occupied, const std::vector<uint64_t>& surface,
                                     const std::vector<VoxelFrameCounts>& counts, const StaticPointSettings& s) {
  std::vector<uint64_t> dynamic;
  for (uint64_t code : occupied) {
    const size_t index = indexOf(surface, code);
    if (index < surface.size() && isDynamicVoxel(counts[index], s)) dynamic.push_back(code);
  }
  return spreadDynamic(occupied, std::move(dynamic), s.spread_steps, s.spread_fraction);
}

Judged judgeFrame(const Frame& frame, const KeyGrid& grid, const std::vector<uint64_t>& surface,
                  const std::vector<VoxelFrameCounts>& counts, const StaticPointSettings& s) {
  Judged out;
  const std::vector<uint64_t> dynamic = dynamicInFrame(occupiedCodes(frame, grid, s), surface, counts, s);
  const Eigen::Vector3d origin = frame.T_world_sensor.translation();
  const double max_range_sq = s.max_range_m * s.max_range_m;
  for (size_t i = 0; i < frame.cloud.points.size(); ++i) {
    ++out.in;
    const Eigen::Vector3d p = frame.cloud.points[i].cast<double>();
    if (!p.allFinite() || p.squaredNorm() == 0.0) {
      ++out.invalid;
      continue;
    }
    const Eigen::Vector3d w = frame.T_world_sensor * p;
    const std::optional<VoxelKey> key = grid.keyOf(w);
    if (!key || (w - origin).squaredNorm() > max_range_sq) {
      ++out.unjudged;
    } else if (contains(dynamic, mortonEncode(*key))) {
      ++out.dynamic;
      continue;
    }
    out.kept.points.push_back(w.cast<float>());
  }
  return out;
}

}  // namespace

bool isDynamicVoxel(const VoxelFrameCounts& c, const StaticPointSettings& s) {
  return c.free_frames >= s.min_free_frames &&
         static_cast<double>(c.free_frames) >= s.min_free_ratio * static_cast<double>(c.occupied_frames);
}

std::vector<uint64_t> spreadDynamic(const std::vector<uint64_t>& occupied, std::vector<uint64_t> dynamic, int steps,
                                    double fraction) {
  std::vector<uint64_t> added = dynamic, candidates, grown;
  for (int step = 0; step < steps && !added.empty(); ++step) {
    candidates.clear();
    for (uint64_t code : added) {
      forNeighbours(code, [&](uint64_t n) {
        if (contains(occupied, n) && !contains(dynamic, n)) candidates.push_back(n);
      });
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    grown.clear();
    for (uint64_t code : candidates) {
      int in_frame = 0, moving = 0;
      forNeighbours(code, [&](uint64_t n) {
        if (!contains(occupied, n)) return;
        ++in_frame;
        moving += contains(dynamic, n) ? 1 : 0;
      });
      if (moving > 0 && moving >= fraction * in_frame) grown.push_back(code);
    }
    dynamic.insert(dynamic.end(), grown.begin(), grown.end());
    std::sort(dynamic.begin(), dynamic.end());
    added = grown;
  }
  return dynamic;
}

StaticPointResult staticPoints(const FrameSource& source, const StaticPointSettings& s, const ProgressFn& progress) {
  checkSettings(s);
  const auto start = std::chrono::steady_clock::now();
  const KeyGrid grid(s.resolution_m);
  const size_t threads =
      s.threads > 0 ? static_cast<size_t>(s.threads) : std::max<size_t>(1, std::thread::hardware_concurrency());
  tbb::task_arena arena(static_cast<int>(threads));
  StaticPointResult r;
  r.frames = source.size();
  arena.execute([&] {
    const std::vector<uint64_t> surface = surfaceVoxels(source, grid, s, threads, progress);
    const std::vector<VoxelFrameCounts> counts = countFrames(source, grid, s, surface, threads, progress);
    r.voxels_occupied = surface.size();
    for (const VoxelFrameCounts& c : counts) r.voxels_dynamic += isDynamicVoxel(c, s) ? 1 : 0;
    inBatches(
        source, threads, 2 * source.size(), 3 * source.size(), progress,
        [&](size_t i) {
          return onFrame(source, i, [&](const Frame& f) { return judgeFrame(f, grid, surface, counts, s); });
        },
        [&](size_t, const Judged& j) {
          r.points.points.insert(r.points.points.end(), j.kept.points.begin(), j.kept.points.end());
          r.points_in += j.in;
          r.points_invalid += j.invalid;
          r.points_unjudged += j.unjudged;
          r.points_dynamic += j.dynamic;
        });
  });
  r.points.width = static_cast<uint32_t>(r.points.points.size());
  r.points.height = 1;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

}  // namespace chronomap
