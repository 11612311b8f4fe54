#pragma once
/// @file
/// Rigid registration of a session map to a consensus map: the part of the localisation error
/// that is one offset for the whole session, estimated before the per-voxel re-alignment.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/align/pose_correction.h"
#include "chronomap/core/voxel_table.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/octree/session_map.h"

namespace chronomap {

/// Settings of registerToConsensus().
struct RegisterSettings {
  /// Neighbourhood of the mean shift: each occupied voxel of the session is pulled towards the
  /// hit-weighted centre of the consensus' occupied voxels within this many voxels.
  double radius_voxels = 2.0;
  int max_iterations = 30;
  /// Stop when an iteration moves the session less than this (metres, and radians times 1 m).
  double min_step_m = 1e-4;
  /// Rotation about the vertical axis only (a robot on a floor); false: any rotation.
  bool yaw_only = true;
  /// No vertical offset either, in the rigid fit and the drift fit: the error of a robot's 2D
  /// localisation (x, y, heading), its height and tilt fixed by the robot itself. Implies
  /// yaw_only.
  bool planar = false;
  /// At most this many of the session's occupied voxels take part (evenly spread in Morton order).
  size_t max_points = 20000;
  /// What the correction is (integrator.h): one rigid motion of the session's map frame, or the
  /// same position and heading offset of every pose. PerPose needs the session's sensor
  /// positions. PerPose is the simulator's error model, yet World corrects the simulated
  /// sessions better (docs/realign.md has the figures): a rotation about one point also takes
  /// up part of the slow drift.
  CorrectionModel model = CorrectionModel::World;
  /// PerPose: a voxel turns about the mean of the sensor positions within this distance of it
  /// (those that could have seen it; the integrator's default range), or the nearest one.
  double observer_range_m = 3.0;
  /// Drift (registerSessions, after the rigid rounds): every frame gets a correction of its own,
  /// a position offset and a heading turn about the frame's position that vary linearly between
  /// knots this many frames apart (0: no drift correction). fitDrift() has the details.
  int drift_knot_frames = 0;
  /// Drift knots along the sensor's path instead (metres travelled between knots; 0: by frames,
  /// drift_knot_frames; not both). An odometry drifts with the distance travelled, not with the
  /// frames recorded: a robot that stops, looks round and moves on keeps one error over a stop's
  /// frames and gains more over each move. Knots by path give a stop's frames one correction and
  /// a long move several knots, with the prior per metre (drift_per_m, drift_yaw_per_m_deg)
  /// instead of per frame. docs/realign.md has the figures.
  double drift_knot_m = 0.0;
  /// The smoothness prior of knots by path: the random walk of the localisation error per
  /// square root of a metre travelled (metres and degrees).
  double drift_per_m = 0.01;
  double drift_yaw_per_m_deg = 0.2;
  /// Whether the drift is corrected at all (knots by frames or by path).
  bool drift() const { return drift_knot_frames > 0 || drift_knot_m > 0.0; }
  /// Rounds of drift correction, each against the consensus the previous round left.
  int drift_rounds = 2;
  /// The neighbourhood (voxels) of the drift rounds after the first (0: radius_voxels in every
  /// round). A wide radius reaches an odometry's large drift in the first round but leaves a
  /// wobble of its own (the neighbourhood's centre is not on the surface); the later rounds, with
  /// the sessions close, refine with a narrower one (docs/changes.md has the figures).
  double fine_radius_voxels = 0.0;
  /// The smoothness prior: how far the localisation is expected to wander from one frame to the
  /// next (standard deviation of a random walk per frame, metres and degrees).
  double drift_per_frame_m = 0.002;
  double drift_yaw_per_frame_deg = 0.01;
  /// At most this many occupied voxels of each frame take part (evenly spread).
  size_t drift_samples_per_frame = 100;
  /// Frame points farther than this from their sensor are not used (the integrator's range).
  double drift_max_range_m = 3.0;
  /// The drift fit measures against the sessions' own points instead of voxel centres: each
  /// sample is a frame point, pulled along the surface normal onto the mean position of the
  /// points all sessions put in the target's voxels around it (RegistrationTarget::addPoints),
  /// so offsets below a voxel are seen. Samples where the surface is no plane are left out.
  bool drift_points = false;
  /// registerSessions(): after every round, the part of the corrections that all sessions share
  /// is taken out (the mean of the sessions' rigid corrections: a motion of the whole map with
  /// CorrectionModel::World, the mean per-pose offset with PerPose; in the drift rounds one rigid
  /// motion of the whole map fitted to every frame's correction, every frame counting once), so that
  /// registration moves the sessions against each other and the map as a whole stays where the
  /// sessions' mean put it. Registering sessions to each other cannot observe where the whole
  /// map lies: without this the sessions follow the drift most of them share, as they move
  /// together towards the consensus round after round.
  bool keep_mean = false;

  /// @throw UsageError for values out of range.
  void validate() const;
};

/// What registerToConsensus() found.
struct RegisterReport {
  int iterations = 0;
  size_t points = 0;   ///< occupied voxels of the session used
  size_t matched = 0;  ///< of those, with consensus surface in reach at the end
  double mean_shift_before_m = 0.0;  ///< mean distance to the pull targets, first iteration
  double mean_shift_after_m = 0.0;   ///< the same after the last
};

/// The occupied surface of a consensus map, prepared once for many registrations against it.
class RegistrationTarget {
 public:
  explicit RegistrationTarget(const SessionMap& consensus);
  double resolution_m() const { return grid_.resolution_m(); }
  const KeyGrid& grid() const { return grid_; }
  /// Hits of the occupied unit voxels, by Morton code.
  const VoxelTable<uint32_t>& surface() const { return surface_; }
  /// Adds the points of `frames` (within `max_range_m` of their sensor) that fall into the
  /// surface's voxels to those voxels' point sums (for RegisterSettings::drift_points).
  /// @throw whatever frames.load throws.
  void addPoints(const FrameSource& frames, double max_range_m);
  /// A world point and the Morton code of its voxel in grid().
  struct KeyedPoint {
    uint64_t code;
    Eigen::Vector3d point;
  };
  /// addPoints() in two steps, the first safe from several threads at once: the points of one
  /// frame that addPoints() would add, in order, with their voxels (`out` is replaced); then
  /// adding them. Adding every frame's points in the order addPoints() reads them gives the same
  /// sums, bit for bit. @throw UsageError for a pose that is not finite.
  void keyPoints(const Frame& frame, double max_range_m, std::vector<KeyedPoint>& out) const;
  void addKeyedPoints(std::span<const KeyedPoint> points);
  /// Adds the hits of `map`'s occupied unit voxels that lie in the surface to the point sums,
  /// each voxel's hits at their mean position (the voxel centre plus the mean hit offset, or the
  /// centre where the map kept no offsets): the points of sessions whose frames are not at hand,
  /// such as a stored consensus (registerSessions' prior).
  /// @throw UsageError when `map`'s resolution is not the target's.
  void addMapPoints(const SessionMap& map);
  /// Sum of the added points (x, y, z) and their number (w), by Morton code.
  const VoxelTable<Eigen::Vector4d>& points() const { return points_; }

 private:
  KeyGrid grid_;
  VoxelTable<uint32_t> surface_;
  VoxelTable<Eigen::Vector4d> points_;
};

/// The correction that moves the session's occupied voxels onto the consensus' surfaces:
/// re-integrating the session with every pose corrected by it (PoseCorrection{T, settings.model})
/// puts it where the other sessions saw the place. For the World model T is a rigid motion of
/// the map frame; for PerPose, T's rotation turns every pose about its own position and T's
/// translation moves it, and `sensor_positions` (the session's, as integrated) are required. A mean-shift registration: every iteration pulls each
/// session voxel centre towards the hit-weighted centre of the consensus' occupied voxels
/// around it and fits the rigid motion of least squares (yaw and translation, or full). A
/// consensus that includes the session still works: its own share only slows convergence.
/// Identity when nothing matches.
/// @throw UsageError for different resolutions or bad settings.
Eigen::Isometry3d registerToConsensus(const SessionMap& session, const SessionMap& consensus,
                                      const RegisterSettings& settings = {}, RegisterReport* report = nullptr,
                                      std::span<const Eigen::Vector3d> sensor_positions = {});
/// The same against a prepared target (for many sessions against one consensus).
Eigen::Isometry3d registerToConsensus(const SessionMap& session, const RegistrationTarget& target,
                                      const RegisterSettings& settings = {}, RegisterReport* report = nullptr,
                                      std::span<const Eigen::Vector3d> sensor_positions = {});

/// The slow drift of a session's localisation: one correction per frame of `frames` (as
/// integrated into `session`), to apply after the poses' present correction in the PerPose sense
/// (turned about the frame's position, then moved). The voxels each frame's points end in (at
/// most drift_samples_per_frame, within drift_max_range_m of its sensor) are pulled towards the
/// target's surface as in registerToConsensus(), relative to the pull of the frame's own voxels,
/// along the frame surface's normal where that is a plane; `session` gives the voxel grid
/// (its resolution must be the target's). The unknowns are a position
/// offset and a yaw at knots every drift_knot_frames frames (or every drift_knot_m metres of the
/// sensor's path as the frames give it), linear in between, fitted by least squares along each
/// pull with a random-walk prior on the differences of neighbouring knots (drift_per_frame_m and
/// drift_yaw_per_frame_deg, or drift_per_m and drift_yaw_per_m_deg; a pull's noise taken as half
/// a voxel), so stretches of a session that see little are carried by their neighbours.
/// @throw UsageError for bad settings (no drift knots included) or resolutions that differ;
/// whatever frames.load throws.
std::vector<Eigen::Isometry3d> fitDrift(const FrameSource& frames, const SessionMap& session,
                                        const RegistrationTarget& target, const RegisterSettings& settings,
                                        RegisterReport* report = nullptr);

/// The recording of session `index` as first read (poses uncorrected), for the drift correction.
using SessionFrames = std::function<std::unique_ptr<FrameSource>(size_t index)>;

/// Integrates session `index` again with every pose corrected by `correction`. `last`: the
/// session's last re-integration, the map registerSessions() leaves; of the maps before it only
/// the occupancy and the hits are used (the next round's consensus and fit), so they may be
/// integrated without colour. Called from several threads at once, for different sessions.
using Reintegrate = std::function<SessionMap(size_t index, const PoseCorrection& correction, bool last)>;

/// Registers every session to the consensus of all of them, `rounds` times (each round against
/// the consensus of the sessions as the previous round left them), integrating each session
/// again with its correction after every round. `sessions` are replaced by the re-integrated
/// ones. Sessions are registered and integrated in parallel; the result does not depend on the
/// thread count. `sensor_positions`: each session's sensor positions as first integrated
/// (required by the PerPose model, ignored by World). With settings.drift(),
/// drift_rounds more rounds follow, each fitting every session's drift (fitDrift()) on the
/// frames `frames` gives, corrected as integrated last, and integrating it again.
/// `prior`, when given, is the consensus of sessions registered before (a tiled map's stored
/// sessions, the streaming build): it joins every round's consensus as it is, never moved, and
/// its hits join the drift fit's points (RegistrationTarget::addMapPoints). It anchors where the
/// map lies, so keep_mean is not applied with it.
/// @return the correction of each session (with per-frame parts after a drift correction).
/// @throw UsageError for no sessions, rounds outside [1, 10], bad settings, missing positions or
/// frames, a prior of another resolution.
std::vector<PoseCorrection> registerSessions(std::vector<SessionMap>& sessions, const Reintegrate& reintegrate,
                                             int rounds = 3, const RegisterSettings& settings = {},
                                             std::vector<RegisterReport>* reports = nullptr,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions = {},
                                             const SessionFrames& frames = {}, const SessionMap* prior = nullptr);

}  // namespace chronomap
