#pragma once
/// @file
/// The pinhole model of a depth camera.

namespace chronomap {

/// Pinhole intrinsics of a depth camera, in pixels.
struct CameraIntrinsics {
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;
};

}  // namespace chronomap
