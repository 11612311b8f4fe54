#pragma once
/// @file
/// Corrections of a session's poses, as registration finds them, and a frame source that
/// applies one.

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/frame.h"

namespace chronomap {

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

/// "world" or "per-pose".
const char* toString(CorrectionModel model);
/// Inverse of toString. @throw UsageError for another name.
CorrectionModel parseCorrectionModel(const std::string& name);

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

}  // namespace chronomap
