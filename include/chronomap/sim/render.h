#pragma once
/// @file
/// The simulator's camera: ray casting a scene state through a bounding-volume hierarchy into
/// Kinect-like RGB-D frames.

#include <cstdint>
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

/// Depth sensor model.
struct SensorModel {
  double noise_per_m2 = 0.0014;  ///< sigma = noise * z^2, metres
  double min_range_m = 0.5, max_range_m = 5.0;
  double depth_scale = 5000.0;   ///< units per metre in the depth PNG (TUM)
  double edge_dropout = 0.5;     ///< probability of losing a pixel at a depth edge
  double dark_dropout = 0.6;     ///< probability of losing a pixel on a dark surface
  double dark_luminance = 40.0;  ///< surfaces darker than this (0..255) are "dark"
};

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
