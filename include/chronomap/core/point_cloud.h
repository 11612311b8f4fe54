#pragma once
/// @file
/// Point clouds and frames: what readers produce and the integrator consumes.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "chronomap/core/counters.h"

namespace chronomap {

/// Points in one frame of reference. Organized clouds (from depth images) keep invalid samples
/// as NaN so that pixel indices stay meaningful; `colors` and `labels` are empty or as long as
/// `points`.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<Rgb> colors;
  std::vector<uint32_t> labels;
  uint32_t width = 0;   ///< columns of an organized cloud, or the point count
  uint32_t height = 1;  ///< rows of an organized cloud, or 1

  size_t size() const { return points.size(); }
  bool hasColors() const { return !colors.empty(); }
  bool hasLabels() const { return !labels.empty(); }
};

/// One observation: a cloud in the sensor frame and the sensor's pose in the map frame.
struct Frame {
  PointCloud cloud;                                              ///< points in the sensor frame
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< sensor to map frame
  double timestamp_s = 0.0;                                      ///< seconds (0 when unknown)
  std::string source;                                            ///< file or frame name, for messages
};

}  // namespace chronomap
