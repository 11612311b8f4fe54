#include "chronomap/align/up_axis.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/sim/box_room.h"

namespace chronomap {
namespace {

TEST(UpAxis, NamesReadBackAndEveryRotationMakesItsAxisUp) {
  for (UpAxis a : kUpAxes) {
    EXPECT_EQ(parseUpAxis(toString(a)), a);
    const Eigen::Matrix3d r = uprightRotation(a);
    EXPECT_TRUE((r * upVector(a)).isApprox(Eigen::Vector3d::UnitZ())) << toString(a);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12) << toString(a);  // a turn, never a mirror
  }
  EXPECT_EQ(parseUpAxis("y"), UpAxis::PlusY);
  // An optical frame turned upright looks along +y with x to the right.
  EXPECT_TRUE((uprightRotation(UpAxis::MinusY) * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitY()));
  for (const char* bad : {"up", "+w", "", "--y", "Y"}) EXPECT_THROW(parseUpAxis(bad), UsageError) << bad;
}

/// Frames of the default box room from a camera at 1.2 m looking horizontally (z up), at a few
/// places and headings, with every pose then expressed in `T_new_world`'s frame.
FrameVector roomFrames(size_t count, const Eigen::Isometry3d& T_new_world) {
  const BoxRoom room = defaultRoom();
  PinholeCamera camera;
  camera.width = 96;
  camera.height = 72;
  camera.fx = camera.fy = 80.0;
  camera.cx = 47.5;
  camera.cy = 35.5;
  std::vector<Frame> frames;
  for (size_t i = 0; i < count; ++i) {
    const double yaw = 0.3 + 1.9 * static_cast<double>(i);
    const Eigen::Vector3d at(-1.0 + 0.6 * static_cast<double>(i), -0.5 + 0.4 * static_cast<double>(i % 2), 1.2);
    Frame f = renderFrame(room, camera, lookHorizontal(at, yaw));
    f.T_world_sensor = T_new_world * f.T_world_sensor;
    frames.push_back(std::move(f));
  }
  return FrameVector(std::move(frames));
}

Eigen::Isometry3d turn(const Eigen::Matrix3d& r) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  return t;
}

TEST(UpAxis, EstimateFindsTheFloorInEveryFrameConvention) {
  // A z-up session (the simulator's, a robot's map frame): +z.
  const UpEstimate z_up = estimateUpAxis(roomFrames(4, Eigen::Isometry3d::Identity()));
  EXPECT_TRUE(z_up.found);
  EXPECT_EQ(z_up.axis, UpAxis::PlusZ);
  for (size_t k = 0; k < 4; ++k) EXPECT_GT(z_up.scores[4], 1.5 * z_up.scores[k]) << k;  // by a margin
  // One frame in the camera's own optical frame (a single PCD, identity pose): -y.
  const FrameVector one = roomFrames(1, Eigen::Isometry3d::Identity());
  const Eigen::Isometry3d T_camera_world = one.frames()[0].T_world_sensor.inverse();
  EXPECT_EQ(estimateUpAxis(roomFrames(1, T_camera_world)).axis, UpAxis::MinusY);
  // A trajectory in its first camera's optical frame (many SLAM outputs): -y as well.
  EXPECT_EQ(estimateUpAxis(roomFrames(4, T_camera_world)).axis, UpAxis::MinusY);
  // A y-up world (3DMatch, 7-Scenes) and the other axes: each found.
  for (UpAxis a : kUpAxes) {
    const UpEstimate e = estimateUpAxis(roomFrames(3, turn(uprightRotation(a).transpose())));
    EXPECT_EQ(e.axis, a) << toString(a);
    EXPECT_TRUE(e.found) << toString(a);
  }
}

TEST(UpAxis, WithoutAFloorTheSensorsUpDecidesAndNoPointIsAnError) {
  // A camera close to a wall sees no floor below it: its own up (-y of the optical frame) decides.
  std::vector<Frame> wall(1);
  for (int v = -20; v <= 20; ++v) {
    for (int u = -20; u <= 20; ++u) wall[0].cloud.points.emplace_back(0.01f * u, 0.01f * v, 0.8f);
  }
  const UpEstimate e = estimateUpAxis(FrameVector(wall));
  EXPECT_FALSE(e.found);
  EXPECT_EQ(e.axis, UpAxis::MinusY);
  std::vector<Frame> empty(1);
  empty[0].cloud.points.assign(4, Eigen::Vector3f::Constant(std::nanf("")));
  EXPECT_THROW(estimateUpAxis(FrameVector(empty)), DataError);
}

}  // namespace
}  // namespace chronomap
