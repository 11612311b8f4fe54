#pragma once
/// @file
/// Point clouds: what readers produce and the integrator consumes.

#include <cstdint>
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
  std::vector<Rgb> colours;
  std::vector<uint32_t> labels;
  uint32_t width = 0;   ///< columns of an organized cloud, or the point count
  uint32_t height = 1;  ///< rows of an organized cloud, or 1

  size_t size() const { return points.size(); }
  bool hasColours() const { return !colours.empty(); }
  bool hasLabels() const { return !labels.empty(); }
};

}  // namespace chronomap
