#pragma once
/// @file
/// Frames: one observation of a sensor with its pose, and sources that hand them out by index.
/// Dataset readers produce them, the integrator and registration consume them.

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "chronomap/core/point_cloud.h"

namespace chronomap {

/// One observation: a cloud in the sensor frame and the sensor's pose in the map frame.
struct Frame {
  PointCloud cloud;                                              ///< points in the sensor frame
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< sensor to map frame
  double timestamp_s = 0.0;                                      ///< seconds (0 when unknown)
  std::string source;                                            ///< file or frame name, for messages
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

}  // namespace chronomap
