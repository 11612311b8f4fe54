#pragma once
/// @file
/// Rigid registration of a session map to a consensus map: the part of the localisation error
/// that is one offset for the whole session, estimated before the per-voxel re-alignment.

#include <cstddef>
#include <functional>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>

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
  /// At most this many of the session's occupied voxels take part (evenly spread in Morton order).
  size_t max_points = 20000;

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
  const std::unordered_map<uint64_t, uint32_t>& surface() const { return surface_; }

 private:
  KeyGrid grid_;
  std::unordered_map<uint64_t, uint32_t> surface_;
};

/// The rigid correction T (map frame) that moves the session's occupied voxels onto the
/// consensus' surfaces: re-integrating the session with T · pose for every frame puts it where
/// the other sessions saw the place. A mean-shift registration: every iteration pulls each
/// session voxel centre towards the hit-weighted centre of the consensus' occupied voxels
/// around it and fits the rigid motion of least squares (yaw and translation, or full). A
/// consensus that includes the session still works: its own share only slows convergence.
/// Identity when nothing matches.
/// @throw UsageError for different resolutions or bad settings.
Eigen::Isometry3d registerToConsensus(const SessionMap& session, const SessionMap& consensus,
                                      const RegisterSettings& settings = {}, RegisterReport* report = nullptr);
/// The same against a prepared target (for many sessions against one consensus).
Eigen::Isometry3d registerToConsensus(const SessionMap& session, const RegistrationTarget& target,
                                      const RegisterSettings& settings = {}, RegisterReport* report = nullptr);

/// Integrates session `index` again with every pose corrected by `correction` (map frame).
/// Called from several threads at once, for different sessions.
using Reintegrate = std::function<SessionMap(size_t index, const Eigen::Isometry3d& correction)>;

/// Registers every session to the consensus of all of them, `rounds` times (each round against
/// the consensus of the sessions as the previous round left them), integrating each session
/// again with its correction after every round. `sessions` are replaced by the re-integrated
/// ones. Sessions are registered and integrated in parallel; the result does not depend on the
/// thread count. @return the correction of each session.
/// @throw UsageError for no sessions, rounds outside [1, 10] or bad settings.
std::vector<Eigen::Isometry3d> registerSessions(std::vector<SessionMap>& sessions, const Reintegrate& reintegrate,
                                                int rounds = 3, const RegisterSettings& settings = {},
                                                std::vector<RegisterReport>* reports = nullptr);

}  // namespace chronomap
