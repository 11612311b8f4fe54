#pragma once
/// @file
/// The static points of a recording: its points kept where the voxel's history says something
/// was there all the time it was seen, dropped where rays crossed the voxel in frames in which
/// nothing was there (docs/benchmarks.md, "Dynamic points"; `chronomap clean`).
///
/// Each frame is cast on its own (the integrator's ray accumulation, exact or fast mode), so a
/// voxel's history is a count of frames: those with a point in it (occupied then) and those
/// whose rays crossed it for at least `free_length_voxels` voxel lengths with no point in it
/// (observed free then), each ray counting as free only up to a margin before its point. A
/// person walking through a room leaves voxels occupied in a few frames and observed free in
/// many; a wall's voxels are occupied whenever they are seen, and observed free only where rays
/// graze it, now and then.

#include <cstddef>
#include <cstdint>

#include "chronomap/core/frame.h"
#include "chronomap/core/point_cloud.h"
#include "chronomap/integrate/integrator.h"

namespace chronomap {

/// Settings of staticPoints. The defaults were chosen on a training sequence (docs/benchmarks.md).
struct StaticPointSettings {
  /// Edge of the voxels whose histories are kept, metres.
  double resolution_m = 0.05;
  /// Points farther than this from their sensor cast no ray and are kept unjudged.
  double max_range_m = 10.0;
  /// A frame observes a voxel free when its rays cross it for at least this many voxel lengths
  /// in all and none of them ends in it.
  double free_length_voxels = 2.0;
  /// Free space is taken from each ray only up to this margin before its end point, metres:
  /// free_margin_m + free_margin_per_m2 * range^2, so that depth noise, which grows with the
  /// square of the range on depth cameras, does not carve a surface's own voxels from frames
  /// that measured it a little farther. Lidar: set the growth to 0.
  double free_margin_m = 0.05;
  double free_margin_per_m2 = 0.02;
  /// A frame sees a voxel free only when none of its points lies in a voxel within this many
  /// voxels of it (the 26-neighbourhood for 1): surfaces measured a voxel off by noise, or by a
  /// pose a few centimetres off, are not carved by the frames that saw them there.
  int occupied_dilation_voxels = 0;
  /// A voxel is dynamic when at least this many frames observed it free ...
  uint32_t min_free_frames = 2;
  /// ... and at least this fraction of the number of frames that saw it occupied (a surface
  /// grazed by rays in a few of the many frames that saw it stays).
  double min_free_ratio = 0.5;
  /// A frame's points also go where their voxel has, among its 26 neighbours holding points of
  /// the same frame, at least this fraction dynamic (grown this many steps; 0: off): the parts
  /// of a person never seen free, beside the parts that were.
  int spread_steps = 4;
  double spread_fraction = 0.7;
  /// Fast mode (one ray per end voxel, weighted by its points) instead of exact ray casting.
  bool fast = true;
  /// Worker threads; 0 uses every core. The result does not depend on it.
  int threads = 0;
};

/// What staticPoints found.
struct StaticPointResult {
  /// The points kept, in the world frame, in frame order.
  PointCloud points;
  uint64_t frames = 0;
  uint64_t points_in = 0;          ///< every point of every frame
  uint64_t points_invalid = 0;     ///< not finite or at the sensor: dropped
  uint64_t points_unjudged = 0;    ///< beyond max_range_m or outside the map: kept
  uint64_t points_dynamic = 0;     ///< in dynamic voxels: dropped
  uint64_t voxels_occupied = 0;    ///< voxels a point lay in at least once
  uint64_t voxels_dynamic = 0;     ///< of those, judged dynamic
  double seconds = 0.0;
};

/// A voxel's history over the frames of a recording.
struct VoxelFrameCounts {
  uint32_t occupied_frames = 0;  ///< frames with a ray ending in it
  uint32_t free_frames = 0;      ///< frames whose rays crossed it (enough) with none ending in it
};

/// Whether a voxel with these counts is dynamic under `settings`.
bool isDynamicVoxel(const VoxelFrameCounts& counts, const StaticPointSettings& settings);

/// One frame's dynamic voxels grown into its other voxels (Morton codes; `occupied` and
/// `dynamic` sorted, `dynamic` a subset of `occupied`): `steps` times, every occupied voxel with
/// a dynamic neighbour (26-neighbourhood) and at least `fraction` of its occupied neighbours
/// dynamic joins them. Each step looks only at the neighbours of the voxels the step before
/// added (the others' counts did not change). @return the grown set, sorted.
std::vector<uint64_t> spreadDynamic(const std::vector<uint64_t>& occupied, std::vector<uint64_t> dynamic, int steps,
                                    double fraction);

/// The static points of `source` (see the file comment). `progress` gets (done, total) units of
/// three passes over the frames (the voxels with points, their histories, the points judged):
/// 3 * frames in all.
/// @throw UsageError for bad settings; whatever source.load throws.
StaticPointResult staticPoints(const FrameSource& source, const StaticPointSettings& settings = {},
                               const ProgressFn& progress = {});

}  // namespace chronomap
