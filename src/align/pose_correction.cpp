#include "chronomap/align/pose_correction.h"

#include <algorithm>
#include <string>

#include "chronomap/core/error.h"

namespace chronomap {

const char* toString(CorrectionModel model) { return model == CorrectionModel::World ? "world" : "per-pose"; }

CorrectionModel parseCorrectionModel(const std::string& name) {
  if (name == "world") return CorrectionModel::World;
  if (name == "per-pose") return CorrectionModel::PerPose;
  throw UsageError("a registration model must be world or per-pose, not '" + name + "'");
}

Eigen::Isometry3d PoseCorrection::apply(const Eigen::Isometry3d& T_world_sensor, size_t i) const {
  const Eigen::Isometry3d out = apply(T_world_sensor);
  if (per_frame.empty()) return out;
  if (i >= per_frame.size()) {
    throw UsageError("a pose correction for " + std::to_string(per_frame.size()) + " frames applied to frame " +
                     std::to_string(i));
  }
  return perPose(per_frame[i], out);
}

PoseCorrection PoseCorrection::then(const PoseCorrection& next) const {
  if (next.model != model) throw UsageError("pose corrections of different models cannot be combined");
  if (!per_frame.empty() || !next.per_frame.empty()) {
    // Per-frame parts come last: only a correction without a motion of its own can follow them.
    if (!next.motion.matrix().isIdentity(0.0) && !per_frame.empty()) {
      throw UsageError("a pose correction cannot follow per-frame corrections with a motion of its own");
    }
    if (!per_frame.empty() && !next.per_frame.empty() && per_frame.size() != next.per_frame.size()) {
      throw UsageError("per-frame pose corrections for different numbers of frames cannot be combined");
    }
  }
  PoseCorrection out{Eigen::Isometry3d::Identity(), model, {}};
  if (model == CorrectionModel::World) {
    out.motion = next.motion * motion;
  } else {
    // Per pose: rotations about the (moving) sensor position compose, translations add.
    out.motion = perPose(next.motion, motion);
  }
  out.per_frame = per_frame.empty() ? next.per_frame : per_frame;
  if (!per_frame.empty() && !next.per_frame.empty()) {
    for (size_t i = 0; i < per_frame.size(); ++i) out.per_frame[i] = perPose(next.per_frame[i], per_frame[i]);
  }
  return out;
}

bool PoseCorrection::isIdentity() const {
  if (!motion.matrix().isIdentity(0.0)) return false;
  return std::all_of(per_frame.begin(), per_frame.end(),
                     [](const Eigen::Isometry3d& c) { return c.matrix().isIdentity(0.0); });
}

}  // namespace chronomap
