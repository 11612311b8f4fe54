#pragma once
/// @file
/// Depth images in metres (float32, as SLAM systems and Python hand them over) back-projected
/// into clouds, like depthToCloud (io/dataset.h) does for 16-bit images with a scale.

#include <cstdint>
#include <span>
#include <string>

#include "chronomap/core/camera.h"
#include "chronomap/core/image.h"
#include "chronomap/core/point_cloud.h"

namespace chronomap {

/// Back-projects a row-major depth image of `width` x `height` metres into an organized cloud
/// in the camera frame (x right, y down, z forward). Zero, negative and non-finite depths
/// become NaN points (no measurement). `rgb` may be null; otherwise it must match in size.
/// @throw DataError naming `source` when the sizes do not match.
PointCloud depthMetresToCloud(std::span<const float> depth_m, uint32_t width, uint32_t height, const ImageRgb* rgb,
                              const CameraIntrinsics& k, const std::string& source);

}  // namespace chronomap
