#pragma once
/// @file
/// A small analytic scene for tests and benchmarks: the inside of a box-shaped room with
/// axis-aligned boxes in it, rendered by exact ray casting into organized clouds.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "chronomap/core/frame.h"

namespace chronomap {

/// An axis-aligned box with one colour.
struct Box {
  Eigen::Vector3d min_m, max_m;
  Rgb colour;
};

/// A room: its walls are the inside of `bounds`; `boxes` stand inside it.
struct BoxRoom {
  Box bounds;
  std::vector<Box> boxes;
};

/// Pinhole camera in the optical frame (x right, y down, z forward).
struct PinholeCamera {
  uint32_t width = 640, height = 480;
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;
};

/// The default test room: 4.4 x 4.0 x 2.6 m with a desk, a cabinet and a box.
BoxRoom defaultRoom();

/// Pose of a camera at `position_m` looking horizontally along yaw (radians, from +x towards +y),
/// z up in the map frame.
Eigen::Isometry3d lookHorizontal(const Eigen::Vector3d& position_m, double yaw_rad);

/// Renders the room: one point per pixel at the nearest surface, with that surface's colour.
/// Depth noise with standard deviation `noise_per_m2` * z^2 (metres) is added with `seed`.
Frame renderFrame(const BoxRoom& room, const PinholeCamera& camera, const Eigen::Isometry3d& T_world_camera,
                  double noise_per_m2 = 0.0, uint64_t seed = 0);

/// Draws solid `boxes` into an organized frame (points in the optical frame of `camera`, as
/// renderFrame makes them or a depth camera recorded them) by depth, as a z-buffer does: where a
/// box's surface along a pixel's ray is nearer than the frame's point (or the pixel has none) it
/// replaces the point (with renderFrame's noise, `noise_per_m2` * z^2, drawn with `seed`), takes
/// `colour` when the frame has colours, and the pixel's entry of `inserted` (resized to the
/// frame's pixels; entries already set stay set) becomes 1. Ignores boxes the camera is inside.
/// @return the pixels replaced. @throw UsageError when the frame is not width x height of `camera`.
size_t insertBoxesByDepth(Frame& frame, const PinholeCamera& camera, const std::vector<Box>& boxes,
                          std::vector<uint8_t>& inserted, double noise_per_m2 = 0.0, uint64_t seed = 0,
                          Rgb colour = {255, 0, 255});

/// A fixed sequence for benchmarks: the camera turns a full circle in the default room while
/// moving on a 0.3 m circle, with Kinect-like noise (1.4 mm z^2). Deterministic.
std::vector<Frame> benchmarkSequence(size_t frames, const PinholeCamera& camera = {});

}  // namespace chronomap
