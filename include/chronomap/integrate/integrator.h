#pragma once
/// @file
/// Integration of RGB-D frames into a session map by exact ray casting (thesis §2.1).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include "chronomap/core/point_cloud.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Settings of the integrator. Defaults follow the thesis.
struct IntegratorSettings {
  /// Points farther than this from their sensor origin are discarded entirely.
  double max_range_m = 3.0;
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
};

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

  uint64_t pointsSkipped() const { return points_invalid + points_out_of_range + points_outside_map; }
  IntegrationStats& operator+=(const IntegrationStats& o);
};

/// A sequence of frames that can be loaded by index from several threads at once.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Number of frames.
  virtual size_t size() const = 0;
  /// Loads frame i. Must be safe to call concurrently.
  /// @throw DataError, FormatError or IoError naming the file at fault.
  virtual Frame load(size_t i) const = 0;
  /// Frame i when it is already in memory (then it is used without a copy), else null.
  virtual const Frame* resident(size_t /*i*/) const { return nullptr; }
  /// The pose of frame i (T_world_sensor) without its points. Sources that hold their poses
  /// answer without reading the frame.
  virtual Eigen::Isometry3d poseOf(size_t i) const { return load(i).T_world_sensor; }
};

/// Frames already in memory.
class FrameVector : public FrameSource {
 public:
  explicit FrameVector(std::vector<Frame> frames) : frames_(std::move(frames)) {}
  size_t size() const override { return frames_.size(); }
  Frame load(size_t i) const override { return frames_.at(i); }
  const Frame* resident(size_t i) const override { return &frames_.at(i); }
  Eigen::Isometry3d poseOf(size_t i) const override { return frames_.at(i).T_world_sensor; }
  const std::vector<Frame>& frames() const { return frames_; }

 private:
  std::vector<Frame> frames_;
};

/// How a session's pose correction moves its poses.
enum class CorrectionModel : uint8_t {
  /// One rigid motion C of the map frame: T_world_sensor becomes C * T_world_sensor (the
  /// session's frame of reference was off as a whole, as between two SLAM maps).
  World,
  /// Every pose turned by C's rotation about its own position, then moved by C's translation:
  /// the sensor's position and heading estimates were off by the same amounts all session (a
  /// robot localising against a prior map). Far from where the session started this differs
  /// from World: a heading error of 0.3° turns the world about the sensor, not about a fixed
  /// point 20 m away.
  PerPose,
};

/// A correction of every pose of a session: one motion of the given model, then, when
/// `per_frame` is not empty, a motion for each frame by index (the slow drift of a localisation
/// within the session), each in the PerPose sense: turned about the frame's own position, then
/// moved.
struct PoseCorrection {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  CorrectionModel model = CorrectionModel::World;
  std::vector<Eigen::Isometry3d> per_frame;

  PoseCorrection() = default;
  PoseCorrection(const Eigen::Isometry3d& motion_, CorrectionModel model_,
                 std::vector<Eigen::Isometry3d> per_frame_ = {})
      : motion(motion_), model(model_), per_frame(std::move(per_frame_)) {}

  /// The corrected pose of a frame, ignoring `per_frame`.
  Eigen::Isometry3d apply(const Eigen::Isometry3d& T_world_sensor) const {
    return model == CorrectionModel::World ? motion * T_world_sensor : perPose(motion, T_world_sensor);
  }
  /// The corrected pose of frame `i`. @throw UsageError when `per_frame` is set for a
  /// different number of frames (i beyond it).
  Eigen::Isometry3d apply(const Eigen::Isometry3d& T_world_sensor, size_t i) const;
  /// The correction `next` applied after this one (same model; `next.per_frame` empty or as
  /// long as this one's). @throw UsageError otherwise.
  PoseCorrection then(const PoseCorrection& next) const;
  bool isIdentity() const;
  /// `T` turned by `c`'s rotation about its own position, then moved by `c`'s translation.
  static Eigen::Isometry3d perPose(const Eigen::Isometry3d& c, const Eigen::Isometry3d& T) {
    Eigen::Isometry3d out = T;
    out.linear() = c.linear() * T.linear();
    out.translation() = T.translation() + c.translation();
    return out;
  }
};

/// Another source's frames with every pose corrected (a session registered to others).
class CorrectedFrames : public FrameSource {
 public:
  CorrectedFrames(const FrameSource& inner, const PoseCorrection& correction) : inner_(inner), correction_(correction) {}
  /// A World correction: T_world_sensor becomes correction * T_world_sensor.
  CorrectedFrames(const FrameSource& inner, const Eigen::Isometry3d& correction)
      : inner_(inner), correction_{correction, CorrectionModel::World, {}} {}
  size_t size() const override { return inner_.size(); }
  Frame load(size_t i) const override {
    Frame f = inner_.load(i);
    f.T_world_sensor = correction_.apply(f.T_world_sensor, i);
    return f;
  }
  Eigen::Isometry3d poseOf(size_t i) const override { return correction_.apply(inner_.poseOf(i), i); }

 private:
  const FrameSource& inner_;
  PoseCorrection correction_;
};

/// The voxels one frame touches and what it adds to each, in a fixed order.
struct VoxelDeltas {
  std::vector<VoxelKey> keys;
  std::vector<VoxelCounters> deltas;
  IntegrationStats stats;
};

/// Scratch space that turns one frame into VoxelDeltas. One per thread; reusable.
class RayAccumulator {
 public:
  RayAccumulator(const KeyGrid& grid, const IntegratorSettings& settings);
  ~RayAccumulator();
  RayAccumulator(RayAccumulator&&) noexcept;
  RayAccumulator& operator=(RayAccumulator&&) noexcept;

  /// Casts the rays of `frame` and writes the per-voxel sums to `out` (cleared first).
  /// @throw DataError when the sensor pose is not finite or lies outside the map.
  void accumulate(const Frame& frame, VoxelDeltas& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Called after each frame is merged: (frames done, frames in all).
using ProgressFn = std::function<void(size_t, size_t)>;

/// Integrates every frame of `source` into `map`, in frame order.
/// @throw UsageError for bad settings; whatever source.load throws for bad frames.
IntegrationStats integrate(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings = {},
                           const ProgressFn& progress = {});

}  // namespace chronomap
