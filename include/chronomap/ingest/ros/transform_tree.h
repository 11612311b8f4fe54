#pragma once
/// @file
/// Poses of a robot recording: stamped transforms between named frames (as ROS's /tf and
/// /tf_static hold them) and stamped poses of one frame (an odometry or pose topic), looked up
/// at a frame's time with the recording's tolerance.

#include <Eigen/Geometry>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace chronomap {

/// A pose at a time.
struct TimedPose {
  double t = 0.0;  ///< seconds
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

/// The pose at `t` from poses sorted by time: the sample itself when one has exactly that time;
/// interpolated (translation linearly, rotation by slerp) between the samples before and after
/// `t`, both at most `tolerance_s` away; the nearest sample alone when `t` lies before the first
/// or after the last one by at most `tolerance_s`. Nothing when the nearest sample is farther
/// than `tolerance_s`, or when `t` lies in a gap wider than that on both sides.
std::optional<Eigen::Isometry3d> poseAt(const std::vector<TimedPose>& sorted, double t, double tolerance_s);

/// Transforms between frames: each child frame has one parent; a static transform holds at
/// every time, a dynamic one is looked up with poseAt.
class TransformTree {
 public:
  /// Records T_parent_child at time t (static: at every time; a later static one replaces it).
  /// @throw DataError naming `context` when `child` already has another parent (a tf tree gives
  /// each frame one), or is its own parent.
  void add(const std::string& parent, const std::string& child, double t, const Eigen::Isometry3d& T_parent_child,
           bool is_static, const std::string& context = "transform");
  /// Sorts the samples; call once after the last add().
  /// @throw DataError naming `context` and the frames of a loop (a -> b -> a), which would
  /// leave every frame on it without a pose.
  void finish(const std::string& context = "transform tree");
  /// T_target_source at time t: the transform of points of `source` into `target`, through their
  /// common ancestor. Nothing when the frames are not connected or a transform on the way has no
  /// sample within the tolerance.
  std::optional<Eigen::Isometry3d> lookup(const std::string& target, const std::string& source, double t,
                                          double tolerance_s) const;
  /// Every frame named by a transform.
  std::set<std::string> frames() const;
  /// Frames without a parent (the candidates for a fixed frame).
  std::set<std::string> roots() const;
  bool empty() const { return parents_.empty(); }

 private:
  struct Edge {
    std::string parent;
    std::vector<TimedPose> samples;  ///< sorted after finish()
    std::optional<Eigen::Isometry3d> fixed;
  };
  /// `frame` and its ancestors up to the root, nearest first.
  std::vector<std::string> ancestors(const std::string& frame) const;
  /// T_ancestor_frame at t along `path` (as ancestors() returns it) up to index `to`.
  std::optional<Eigen::Isometry3d> along(const std::vector<std::string>& path, size_t to, double t,
                                         double tolerance_s) const;
  std::map<std::string, Edge> parents_;  ///< by child frame
};

}  // namespace chronomap
