#pragma once
/// @file
/// Rigid poses: construction from translations and quaternions or 4x4 matrices, with checks.

#include <string>

#include <Eigen/Geometry>

namespace chronomap {

/// Tolerance on |q| - 1 above which a quaternion is rejected instead of normalised.
inline constexpr double kQuaternionNormTolerance = 1e-2;
/// Tolerance on |R^T R - I| (max abs entry) above which a rotation matrix is rejected.
inline constexpr double kRotationOrthonormalityTolerance = 1e-3;

/// Pose from a translation and a quaternion (x, y, z, w). The quaternion is normalised.
/// @throw DataError naming `context` when a value is not finite or the quaternion is zero or
/// farther than kQuaternionNormTolerance from unit length.
Eigen::Isometry3d poseFromTranslationQuaternion(const Eigen::Vector3d& t, double qx, double qy, double qz,
                                                double qw, const std::string& context);

/// Pose from a 4x4 homogeneous matrix.
/// @throw DataError naming `context` when the matrix is not rigid (non-finite entries, rotation
/// not orthonormal or a reflection, bottom row not 0 0 0 1).
Eigen::Isometry3d poseFromMatrix(const Eigen::Matrix4d& m, const std::string& context);

/// Parses "tx,ty,tz,qx,qy,qz,qw" (commas or spaces).
/// @throw UsageError when the text does not hold seven numbers, DataError for a bad quaternion.
Eigen::Isometry3d parsePose(const std::string& text);

}  // namespace chronomap
