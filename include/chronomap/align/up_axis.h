#pragma once
/// @file
/// Which way is up in a recording's world frame, and the rotation that makes it +z: chronomap's
/// maps, top views, cost maps and planner take z as up, while a camera's optical frame (x right,
/// y down, z forward) has -y up and 3DMatch's world +y. Given (`--up`) or estimated from the
/// floor (`--up auto`, docs/frames.md).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include <Eigen/Core>

#include "chronomap/core/frame.h"

namespace chronomap {

/// An axis of a world frame, with its sign.
enum class UpAxis : uint8_t { PlusX, MinusX, PlusY, MinusY, PlusZ, MinusZ };
/// Every axis, in the order above.
inline constexpr std::array<UpAxis, 6> kUpAxes = {UpAxis::PlusX, UpAxis::MinusX, UpAxis::PlusY,
                                                  UpAxis::MinusY, UpAxis::PlusZ, UpAxis::MinusZ};

/// "+x", "-x", "+y", "-y", "+z", "-z".
const char* toString(UpAxis axis);
/// Inverse of toString (also "x", "y", "z" for the plus signs).
/// @throw UsageError for another name, listing the names there are.
UpAxis parseUpAxis(const std::string& name);
/// The unit vector of `axis`.
Eigen::Vector3d upVector(UpAxis axis);
/// The rotation R of the world frame that makes `axis` +z (R * upVector(axis) = +z): a quarter
/// or half turn about x or y, entries 0 and ±1 only, so that rotated coordinates are exact.
/// +z gives the identity; -y (an optical frame) turns z (forward) into +y.
Eigen::Matrix3d uprightRotation(UpAxis axis);

/// How estimateUpAxis() looks at a recording.
struct UpEstimateSettings {
  size_t max_frames = 24;        ///< frames read, spread evenly over the recording
  size_t max_points = 200000;    ///< points read, spread evenly over those frames; one kept per bin_m cell
  double max_range_m = 8.0;      ///< points farther from their sensor are left out
  double bin_m = 0.05;           ///< height histogram bin
  int slab_bins = 2;             ///< a plane: this many bins (0.1 m, a floor seen with some noise or tilt)
  double clearance_m = 0.2;      ///< a floor lies at least this far below every sensor position
  /// The sensor frame's own up: -y for depth cameras (the optical frame every image reader and
  /// organised cloud uses). Frames of a sensor whose up is another axis (a lidar's +z) set it.
  Eigen::Vector3d sensor_up = -Eigen::Vector3d::UnitY();
  double min_score = 0.01;       ///< below it no floor was found (then the sensors' up decides)
  /// Without a floor, the axis the sensors' up (R_world_sensor sensor_up) lies along, when their
  /// mean has at least this component on it; else +z, the frame as recorded.
  double min_sensor_agreement = 0.9;
};

/// What estimateUpAxis() found.
struct UpEstimate {
  UpAxis axis = UpAxis::PlusZ;
  /// False: no axis scored min_score; axis is then the sensors' up, or +z (min_sensor_agreement).
  bool found = false;
  std::array<double, 6> scores{};  ///< of each axis of kUpAxes
  std::array<double, 6> floor_share{};  ///< share of the points in the floor plane of each axis
  size_t frames = 0, points = 0;   ///< read and used
};

/// Estimates which axis of the frames' world frame is up, from four cues, scored for each of the
/// six axes u and multiplied: a floor (the densest plane perpendicular to u lying at least
/// clearance_m below every sensor position, as a share of the points (one per bin_m cell, so that
/// surfaces count by area), less the share of points beneath it: a floor has nothing under it), sensors looking across rather than along u (one
/// minus the mean of |ray direction . u|: a camera facing a wall does not make the wall a floor,
/// and one that turns about the up looks along every horizontal axis in turn), and
/// sensors held upright (0.25 + 0.75 max(0, mean of R_world_sensor sensor_up . u): a depth camera's
/// image rows run level; a sensor_up of zero makes this cue the same for every axis), and a level
/// path (one minus the sensor positions' spread along u over their spread along all three axes:
/// people and robots move across floors, not up walls; the same for every axis when the sensor
/// moved less than bin_m). The highest score wins; without a floor (every score under min_score)
/// the sensors' up decides (docs/frames.md has the figures and the limits).
/// @throw DataError when the frames hold no valid point within max_range_m.
UpEstimate estimateUpAxis(const FrameSource& frames, const UpEstimateSettings& settings = {});

}  // namespace chronomap
