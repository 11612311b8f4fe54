#pragma once
/// @file
/// Integration of RGB-D frames into a session map by exact ray casting (thesis §2.1).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/core/frame.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

class MemoryActivity;

/// Half the machine's physical memory: the default memory limit of integration, which leaves
/// room for a node pool growing (its old and new storage live side by side for a moment), the
/// frames in flight and the rest of the process. 0 when the system does not say.
size_t defaultMemoryLimitBytes();

/// Largest IntegratorSettings::carve_level (16 voxels per axis).
inline constexpr int kMaxCarveLevel = 4;
/// IntegratorSettings::carve_level that lets carveLevelFor() choose.
inline constexpr int kCarveAuto = -1;
/// Coarsest resolution, in metres, at which kCarveAuto carves free space coarser: coarser maps
/// gain nothing from it (measured at 0.05 m), finer ones about 1.7x of fast mode's processor
/// time (level 2 at 0.02 m; docs/integration.md).
inline constexpr double kCarveAutoCoarsestResolutionM = 0.025;

/// Settings of the integrator. Defaults follow the thesis.
struct IntegratorSettings {
  /// Points farther than this from their sensor origin are discarded entirely ...
  double max_range_m = 3.0;
  /// ... unless this is set: then free space is carved along their rays up to the range, with no
  /// hit (as OctoMap's insertPointCloud does with its maxrange). Shows space seen through, such as
  /// an open doorway in front of a far wall, that would otherwise stay unknown.
  bool carve_beyond_range = false;
  /// Fast mode: all points of a frame that end in the same voxel are cast as one ray to that
  /// voxel's centre, weighted by their count (docs/integration.md states how far it differs).
  bool fast = false;
  /// Worker threads; 0 uses every core. Results do not depend on this number.
  int threads = 0;
  /// Merge known-free subtrees after integration (see SessionMap::compressFree).
  bool compress_free = true;
  /// Fast mode accumulates a frame in one pass over a scratch cube of side 2 * max_range around
  /// the sensor when it has at most this many voxels (8 bytes each, per thread) ...
  size_t cube_max_cells = size_t{1} << 23;
  /// ... otherwise (and in exact mode) in two passes over the frame's bounding box when that has
  /// at most this many voxels, else in a hash table (long ranges, laser scans). Results are the
  /// same on every path.
  size_t dense_grid_max_cells = size_t{1} << 25;
  /// Fast mode casts its bundle rays eight at a time in AVX2 registers where the CPU has them;
  /// false takes the portable code. The maps are bitwise the same either way.
  bool simd = true;
  /// Record where in each voxel the rays ended (VoxelCounters::offset), which lets the diff's
  /// shift test see surfaces move by less than a voxel. Costs fast mode about 7% more time per
  /// frame (docs/benchmarks.md); false leaves the offsets at zero (hits at the centres).
  bool hit_positions = true;
  /// Most bytes integration may take: the session map's node pools (checked after each frame is
  /// merged) and the scratch space of one frame on each thread, this over the thread count
  /// (checked as it grows). Past it, integration stops with a UsageError saying what it needed
  /// at which resolution, instead of taking all memory. 0: no limit.
  size_t memory_limit_bytes = defaultMemoryLimitBytes();
  /// Fast mode only: carve free space coarser, far from the surfaces (docs/integration.md, "Coarse
  /// carving"). Each bundle ray is walked in cubes of 2^carve_level voxels per axis (aligned to the
  /// octree's nodes of that level) until it enters the cubes within one of its end voxel's cube,
  /// and in unit voxels from there; a cube's length is spread evenly over its voxels when merged.
  /// Hits, colours and hit positions are those of carve_level 0; the summed length is the same up
  /// to float rounding; per-voxel lengths differ. 0: off (the maps are those of before, bit for bit).
  /// kCarveAuto (the default): carveLevelFor() picks it from the map's resolution.
  int carve_level = kCarveAuto;
  /// Organized clouds (depth images): a point is dropped when the range of one of its eight
  /// neighbouring pixels differs from its own by more than this share of its range. That removes
  /// the flying pixels a depth camera makes between a foreground edge and the background behind
  /// it (and the one pixel on either side of every depth step). 0: off, the default (the maps are
  /// those of before, bit for bit). Unorganized clouds (height 1) are cast as they are.
  double depth_edge_ratio = 0.0;
};

/// The points of `cloud` that IntegratorSettings::depth_edge_ratio `ratio` drops (1: dropped),
/// one per point; empty when the cloud is not organized (height 1 or width x height != size) or
/// `ratio` is 0. Invalid points (not finite, or at the sensor) are neither dropped nor compared.
std::vector<uint8_t> depthEdgeMask(const PointCloud& cloud, double ratio);

/// The carve level integration uses at `resolution_m`: the settings' own, or for kCarveAuto 0 in
/// exact mode and in fast mode at resolutions coarser than kCarveAutoCoarsestResolutionM, and 2
/// (cubes of 4 voxels per axis) at that resolution and finer.
int carveLevelFor(const IntegratorSettings& settings, double resolution_m);

/// What an integration did, point by point.
struct IntegrationStats {
  uint64_t frames = 0;
  uint64_t points = 0;              ///< points cast as rays
  uint64_t points_invalid = 0;      ///< NaN, infinite, or at the sensor origin (zero depth)
  uint64_t points_out_of_range = 0; ///< farther than max_range_m
  uint64_t points_outside_map = 0;  ///< outside the map's extent
  uint64_t rays = 0;                ///< rays cast (fewer than points in fast mode)
  uint64_t voxel_updates = 0;       ///< per-frame unique voxels merged into the map
  double seconds = 0.0;
  uint64_t points_depth_edges = 0;  ///< dropped at depth edges (IntegratorSettings::depth_edge_ratio)

  uint64_t pointsSkipped() const {
    return points_invalid + points_out_of_range + points_outside_map + points_depth_edges;
  }
  IntegrationStats& operator+=(const IntegrationStats& o);
};

/// Share of the valid points (finite, not at the sensor) that a limit may drop before
/// droppedPointsWarnings() says so: above it the limit, not the sensor, shapes the map.
inline constexpr double kDroppedPointsWarnFraction = 0.10;

/// One line per limit that dropped more than kDroppedPointsWarnFraction of the valid points of
/// `stats`: the range (IntegratorSettings::max_range_m; with carve_beyond_range the points' free
/// space is kept, their hits are not) and the map's extent. Empty when no limit did.
std::vector<std::string> droppedPointsWarnings(const IntegrationStats& stats, const IntegratorSettings& settings);

/// The voxels one frame touches and what it adds to each, in a fixed order.
struct VoxelDeltas {
  std::vector<VoxelKey> keys;
  std::vector<VoxelCounters> deltas;
  /// Coarse carving (IntegratorSettings::carve_level > 0): the lower corners of cubes of
  /// 2^cube_level voxels per axis and the free-space length (metres) each got as a whole, in
  /// raster order; merged after `keys`, spread evenly over the cube (SessionMap::addCubes).
  std::vector<VoxelKey> cube_keys;
  std::vector<float> cube_length_m;
  int cube_level = 0;
  IntegrationStats stats;
};

/// The bytes `deltas` holds (capacities), for the memory limit.
size_t deltaBytes(const VoxelDeltas& deltas);

/// Adds one frame's deltas to `map`: the voxels, then the cubes.
void mergeDeltas(SessionMap& map, const VoxelDeltas& deltas);

/// Scratch space that turns one frame into VoxelDeltas. One per thread; reusable.
class RayAccumulator {
 public:
  RayAccumulator(const KeyGrid& grid, const IntegratorSettings& settings);
  ~RayAccumulator();
  RayAccumulator(RayAccumulator&&) noexcept;
  RayAccumulator& operator=(RayAccumulator&&) noexcept;

  /// Casts the rays of `frame` and writes the per-voxel sums to `out` (cleared first).
  /// @throw DataError when the sensor pose is not finite or lies outside the map; UsageError when
  /// the frame's scratch space would pass settings.memory_limit_bytes.
  void accumulate(const Frame& frame, VoxelDeltas& out);
  /// accumulate() of frame `i` of `source`: the frame it holds in memory (not copied), else the one
  /// it loads. @throw also what source.load throws.
  void accumulate(const FrameSource& source, size_t i, VoxelDeltas& out);
  /// The bytes its scratch holds now (every buffer's capacity), for the memory limit.
  size_t scratchBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// One frame's deltas as bytes, every counter bit for bit, for another process of the same build
/// (`mpirun -np N chronomap build`: pipeline/distributed.h).
std::vector<uint8_t> encodeDeltas(const VoxelDeltas& deltas);
/// encodeDeltas() read back into `out`. @throw FormatError for bytes it did not write (a wrong
/// length or count), naming `source`.
void decodeDeltas(std::span<const uint8_t> bytes, VoxelDeltas& out, const std::string& source);

/// Frames of one integration that other processes cast (`mpirun -np N chronomap build`). integrate()
/// still merges every frame in frame order, whoever cast it, so the map is the same bytes.
/// integrate() asks for frames in frame order: it hands frames out ahead of the one it merges,
/// and casts frames itself while it waits for them (so that no process idles). Frames 0 to k may
/// have been handed out before integrate() began (the next recording's first frames, handed out
/// while the last one was being added).
class FrameSharing {
 public:
  virtual ~FrameSharing() = default;
  /// Hands frames `first`, `first + 1`, ... (below `end`) to other processes, as many as they have
  /// room for now. @return how many (0: none now).
  virtual size_t handOut(size_t first, size_t end) = 0;
  /// True when frame `i` was handed out and not collected yet.
  virtual bool handedOut(size_t i) const = 0;
  /// The deltas of frame `i`, which was handed out, into `out`. Called for the handed-out frames in
  /// frame order. @return false when they have not arrived yet and `wait` is false.
  /// @throw what casting the frame threw there (the same error this process would have given).
  virtual bool collect(size_t i, VoxelDeltas& out, bool wait) = 0;
  /// Every frame was merged (integrate() still compresses the map): the other processes may be
  /// given what comes next.
  virtual void framesDone() {}
};

/// While it lives, running out of memory is reported as integrate() reports it for `frames` frames
/// at `resolution_m` ("out of memory while integrating ..." with advice); for a process that casts
/// another's frames (FrameSharing).
std::unique_ptr<MemoryActivity> integrationMemoryActivity(size_t frames, double resolution_m);

/// Called after each frame is merged: (frames done, frames in all). It may throw to stop the
/// integration; the exception leaves integrate().
using ProgressFn = std::function<void(size_t, size_t)>;

/// Integrates every frame of `source` into `map`, in frame order. With `sharing`, other processes
/// cast frames too and this one casts on one thread (settings.threads is not used); the map is the
/// same bytes either way.
/// @throw UsageError for bad settings or when the map or a frame needs more memory than
/// settings.memory_limit_bytes; whatever source.load throws for bad frames, or `progress`.
/// Frames handed out and not collected when it throws are left to `sharing`.
IntegrationStats integrate(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings = {},
                           const ProgressFn& progress = {}, FrameSharing* sharing = nullptr);

}  // namespace chronomap
