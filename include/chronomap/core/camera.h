#pragma once
/// @file
/// The pinhole model of a depth camera, and the checks every reader and back-projection applies
/// to it.

#include <cstdint>
#include <string>

namespace chronomap {

/// Pinhole intrinsics of a depth camera, in pixels.
struct CameraIntrinsics {
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;
};

/// True when the focal lengths are positive and finite and the principal point finite: a zero,
/// negative (it mirrors the map) or NaN value is no camera.
bool intrinsicsValid(const CameraIntrinsics& k);

/// @throw DataError "CONTEXT: ..." naming the bad values unless intrinsicsValid(k).
void checkIntrinsics(const CameraIntrinsics& k, const std::string& context);

/// checkIntrinsics, and the principal point must lie on a `width` x `height` image: intrinsics
/// of another image size (a CameraInfo of 640 x 480 beside depth images of 64 x 48) put it
/// far outside, and would build a map of a few voxels without a word.
/// @throw DataError naming `context`, the principal point and the image size.
void checkIntrinsicsFit(const CameraIntrinsics& k, uint32_t width, uint32_t height, const std::string& context);

}  // namespace chronomap
