#pragma once
/// @file
/// The simulator's camera: ray casting a scene state through a bounding-volume hierarchy into
/// Kinect-like RGB-D frames.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/image.h"
#include "chronomap/sim/scene.h"

namespace chronomap {

/// Pinhole camera in the optical frame (x right, y down, z forward).
struct Camera {
  uint32_t width = 640, height = 480;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};
/// The Kinect-like camera: 57 degrees horizontal field of view, 640 x 480 times `scale`.
Camera kinectCamera(double scale = 1.0);

/// Which depth camera the simulator imitates: `ideal` (the clean z^2 Gaussian the simulator has
/// always had), `kinect` (a Kinect v1-like structured-light camera) or `realsense` (a RealSense
/// D435-like active stereo camera). See docs/simulator.md.
enum class SensorKind : uint8_t { Ideal, Kinect, RealSense };
/// "ideal", "kinect", "realsense".
const char* toString(SensorKind kind);
/// The kind toString() names. @throw UsageError for an unknown name, naming the three.
SensorKind parseSensorKind(const std::string& name);

/// The effects of a real active depth camera (SensorModel::kind other than Ideal), applied per
/// pixel in this order: lateral noise (where the pixel samples), range, grazing incidence, depth
/// edges (lost or flying), dark and shiny surfaces (lost or biased), axial noise, disparity
/// quantisation. Angles theta are the incidence: between the ray and the surface's normal.
struct DepthCameraModel {
  /// Axial noise, the total spread of the depth (quantisation included):
  /// sigma_z(z, theta) = axial_a_m + axial_b_per_m * (z - axial_z0_m)^2
  ///                     + axial_incidence_m / sqrt(z) * theta^2 / (pi/2 - theta)^2.
  double axial_a_m = 0.0012, axial_b_per_m = 0.0019, axial_z0_m = 0.4, axial_incidence_m = 0.0001;
  /// Lateral noise: the pixel samples the scene sigma_L = lateral_px + lateral_incidence_px *
  /// theta / (pi/2 - theta) pixels away (per axis, rounded to a pixel, at most lateral_max_px).
  double lateral_px = 0.8, lateral_incidence_px = 0.035, lateral_max_px = 2.0;
  /// Disparity quantisation: depth = baseline * focal / disparity with the disparity a multiple
  /// of disparity_step_px; 0 turns it off.
  double baseline_m = 0.075, focal_px = 580.0, disparity_step_px = 0.125;
  double max_incidence_deg = 78.0;  ///< no depth at more grazing incidence
  double edge_dropout = 0.3;        ///< at a depth edge: probability of losing the pixel
  double flying_pixel = 0.4;        ///< at a depth edge: probability of a depth between the two surfaces
  double dark_dropout = 0.5;        ///< on a dark surface (SensorModel::dark_luminance): probability of loss
  double dark_bias_m = 0.03;        ///< on a dark surface: added to the depth
  double shiny_dropout = 0.4;       ///< on a shiny face (Part::shiny_faces): probability of loss
  double shiny_bias_m = 0.04;       ///< on a shiny face: added to the depth
};

/// Odometry of the robot carrying the camera (SensorModel::kind other than Ideal): the estimated
/// poses start at the true first pose with the session's localisation offset and then add each
/// measured planar motion, whose errors accumulate with the path: per frame, a distance d and a
/// turn a measured with a random error of sigma translation_m_per_sqrt_m * sqrt(d) along and
/// across the motion, sigma yaw_deg_per_sqrt_m * sqrt(d) + yaw_deg_per_sqrt_rad * sqrt(|a|) in
/// the heading, and per session a scale error (sigma scale_sigma) of every distance and a
/// heading bias (sigma yaw_bias_deg_per_m) per metre travelled.
struct OdometryModel {
  double translation_m_per_sqrt_m = 0.01;
  double yaw_deg_per_sqrt_m = 0.2;
  double yaw_deg_per_sqrt_rad = 0.1;
  double scale_sigma = 0.005;
  double yaw_bias_deg_per_m = 0.05;
};

/// Depth sensor model. The first fields are the ideal model's; `camera` and `odometry` apply
/// when `kind` is not Ideal (sensorModel() fills them and the range).
struct SensorModel {
  double noise_per_m2 = 0.0014;  ///< ideal: sigma = noise * z^2, metres
  double min_range_m = 0.5, max_range_m = 5.0;
  double depth_scale = 5000.0;   ///< units per metre in the depth PNG (TUM)
  double edge_dropout = 0.5;     ///< ideal: probability of losing a pixel at a depth edge
  double dark_dropout = 0.6;     ///< ideal: probability of losing a pixel on a dark surface
  double dark_luminance = 40.0;  ///< surfaces darker than this (0..255) are "dark"
  SensorKind kind = SensorKind::Ideal;
  DepthCameraModel camera;
  OdometryModel odometry;
};
/// The model of a kind of sensor: Ideal gives SensorModel{} (the simulator's default), Kinect
/// the published Kinect noise and a 0.5-4.5 m range, RealSense D435-like constants and 0.3-6 m.
SensorModel sensorModel(SensorKind kind);
/// The axial noise sigma_z(z, theta) of `camera` (metres), theta the incidence in radians.
double axialSigma(const DepthCameraModel& camera, double z_m, double theta_rad);
/// The depth step of the disparity quantisation at depth z (metres; 0 when off):
/// z^2 * disparity_step_px / (baseline_m * focal_px).
double depthStep(const DepthCameraModel& camera, double z_m);

/// One rendered frame: what the sensor recorded, and the noise-free depth (metres, 0 = no hit).
struct RenderedFrame {
  ImageRgb rgb;
  ImageU16 depth;
  std::vector<float> true_depth_m;
};

/// Lighting that depends on the hour and the place (SimulationSettings::lighting "daylight"):
/// a surface's colour is its albedo (face colour and texture) times
/// illumination(hour, p) = ceiling(hour) + window(p) * daylight(hour), per channel.
/// ceiling: the lamps, on from 07:00 to 19:00 (half-hour ramps), a dim night light otherwise;
/// daylight: the sun through the windows, from 06:30 to 19:00, warm when low (morning, sunset),
/// none at night; window(p): exp(-d / 2 m), d the horizontal distance to the nearest outer wall
/// of the building, so rooms on the facade get more daylight than the corridor.
struct Daylight {
  Eigen::AlignedBox3d building;  ///< the building's bounds (outer walls)
  static Eigen::Vector3d ceiling(double hour);
  static Eigen::Vector3d daylight(double hour);
  double window(const Eigen::Vector3d& p) const;
  Eigen::Vector3d at(double hour, const Eigen::Vector3d& p) const {
    return ceiling(hour) + window(p) * daylight(hour);
  }
};

/// Ray caster over a scene state: a bounding-volume hierarchy over the present parts.
///
/// cast() returns the nearest part along the ray; at exactly equal distances the part that
/// comes first in parts() wins. parts() is in the order in which the first renderer (a
/// median-split hierarchy walked in a fixed order) met them, so that every image stays
/// byte-identical to what that renderer drew.
class Renderer {
 public:
  explicit Renderer(const SceneState& state);
  /// Distance along a unit ray to the nearest part, its face colour; false when nothing is hit.
  bool cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double& t, Rgb& colour) const;
  /// Renders one frame. `hour` (0..24) sets the lighting colour (lightingAt(), the same
  /// everywhere, or `daylight`'s when given); `seed` the noise. The lighting changes the colour
  /// image only: depth, its noise and its dropouts do not depend on it.
  RenderedFrame render(const Camera& camera, const Eigen::Isometry3d& T_world_camera, const SensorModel& sensor,
                       double hour, uint64_t seed, const Daylight* daylight = nullptr) const;
  /// The present parts in tie-breaking order (see above).
  const std::vector<Part>& parts() const { return parts_; }

 private:
  struct Node {
    double lo[3], hi[3];
    uint32_t first = 0, count = 0;  // boxes_[first, first + count) (leaf) or, when count == 0, children first, first + 1
  };
  struct Box {
    double lo[3], hi[3];
    uint32_t part = 0;  // index into parts_
  };
  std::vector<Part> parts_;
  std::vector<Box> boxes_;
  std::vector<Node> nodes_;
  void build(std::vector<Box>& boxes, uint32_t index, uint32_t begin, uint32_t end, int depth);
};

/// The lighting colour multiplier at an hour of the day (warm mornings, cool evenings).
Eigen::Vector3d lightingAt(double hour);


}  // namespace chronomap
