#include "chronomap/sim/box_room.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>

#include "chronomap/core/error.h"

namespace chronomap {

BoxRoom defaultRoom() {
  BoxRoom room;
  room.bounds = {{-2.2, -2.0, 0.0}, {2.2, 2.0, 2.6}, {200, 200, 190}};
  room.boxes = {
      {{1.2, -1.9, 0.0}, {2.1, -0.7, 0.75}, {140, 90, 50}},   // desk
      {{-2.1, 1.3, 0.0}, {-1.5, 1.95, 1.9}, {60, 90, 160}},   // cabinet
      {{-0.6, 1.0, 0.0}, {-0.1, 1.4, 0.45}, {180, 60, 50}},   // box
      {{0.8, 1.4, 0.0}, {1.3, 1.95, 1.1}, {70, 150, 80}},     // shelf
  };
  return room;
}

Eigen::Isometry3d lookHorizontal(const Eigen::Vector3d& position_m, double yaw_rad) {
  Eigen::Matrix3d optical_to_forward_x;
  // Columns: images of the optical x (right), y (down), z (forward) axes when looking along +x.
  optical_to_forward_x << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() * optical_to_forward_x;
  T.translation() = position_m;
  return T;
}

namespace {

/// Entry distance of a ray into a solid box (outside hit), or infinity.
double hitOutside(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < b.min_m[a] || o[a] > b.max_m[a]) return std::numeric_limits<double>::infinity();
      continue;
    }
    double ta = (b.min_m[a] - o[a]) / d[a], tb = (b.max_m[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return (t0 <= t1 && t0 > 0.0) ? t0 : std::numeric_limits<double>::infinity();
}

/// Exit distance of a ray from inside a box (the walls).
double hitInside(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double t = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) t = std::min(t, (b.max_m[a] - o[a]) / d[a]);
    if (d[a] < 0) t = std::min(t, (b.min_m[a] - o[a]) / d[a]);
  }
  return t;
}

}  // namespace

Frame renderFrame(const BoxRoom& room, const PinholeCamera& cam, const Eigen::Isometry3d& T, double noise_per_m2,
                  uint64_t seed) {
  Frame frame;
  frame.T_world_sensor = T;
  frame.source = "synthetic";
  PointCloud& cloud = frame.cloud;
  cloud.width = cam.width;
  cloud.height = cam.height;
  cloud.points.resize(size_t{cam.width} * cam.height);
  cloud.colours.resize(cloud.points.size());
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d o = T.translation();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      const size_t i = size_t{v} * cam.width + u;
      const Eigen::Vector3d ray_c((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);  // z = 1
      const Eigen::Vector3d d = R * ray_c;
      double t = hitInside(room.bounds, o, d);
      Rgb colour = room.bounds.colour;
      for (const Box& b : room.boxes) {
        const double tb = hitOutside(b, o, d);
        if (tb < t) {
          t = tb;
          colour = b.colour;
        }
      }
      if (!std::isfinite(t)) {
        cloud.points[i] = Eigen::Vector3f(nan, nan, nan);
        continue;
      }
      double z = t;  // ray_c has z = 1, so the parameter is the depth
      if (noise_per_m2 > 0.0) z += gauss(rng) * noise_per_m2 * z * z;
      cloud.points[i] = (ray_c * z).cast<float>();
      // Shade walls a little by height so that colour varies across the scene.
      const double h = (o + d * t).z();
      const double shade = 0.85 + 0.15 * std::clamp(h / 2.6, 0.0, 1.0);
      cloud.colours[i] = Rgb{static_cast<uint8_t>(colour.r * shade), static_cast<uint8_t>(colour.g * shade),
                            static_cast<uint8_t>(colour.b * shade)};
    }
  }
  return frame;
}

size_t insertBoxesByDepth(Frame& frame, const PinholeCamera& cam, const std::vector<Box>& boxes,
                          std::vector<uint8_t>& inserted, double noise_per_m2, uint64_t seed, Rgb colour) {
  PointCloud& cloud = frame.cloud;
  if (cloud.width != cam.width || cloud.height != cam.height || cloud.points.size() != size_t{cam.width} * cam.height) {
    throw UsageError("inserting boxes by depth: the frame is " + std::to_string(cloud.width) + " x " +
                     std::to_string(cloud.height) + ", the camera " + std::to_string(cam.width) + " x " +
                     std::to_string(cam.height));
  }
  inserted.resize(cloud.points.size(), 0);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Matrix3d R = frame.T_world_sensor.linear();
  const Eigen::Vector3d o = frame.T_world_sensor.translation();
  size_t replaced = 0;
  for (uint32_t v = 0; v < cam.height; ++v) {
    for (uint32_t u = 0; u < cam.width; ++u) {
      const size_t i = size_t{v} * cam.width + u;
      const Eigen::Vector3d ray_c((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);  // z = 1: t is depth
      const Eigen::Vector3d d = R * ray_c;
      double t = std::numeric_limits<double>::infinity();
      for (const Box& b : boxes) t = std::min(t, hitOutside(b, o, d));
      const Eigen::Vector3f& p = cloud.points[i];
      const bool has_depth = p.allFinite() && p.z() > 0.0f;
      if (!std::isfinite(t) || (has_depth && !(t < static_cast<double>(p.z())))) continue;
      double z = t;
      if (noise_per_m2 > 0.0) z += gauss(rng) * noise_per_m2 * z * z;
      cloud.points[i] = (ray_c * z).cast<float>();
      if (cloud.hasColours()) cloud.colours[i] = colour;
      inserted[i] = 1;
      ++replaced;
    }
  }
  return replaced;
}

std::vector<Frame> benchmarkSequence(size_t frames, const PinholeCamera& camera) {
  const BoxRoom room = defaultRoom();
  std::vector<Frame> out;
  out.reserve(frames);
  for (size_t i = 0; i < frames; ++i) {
    const double a = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(frames);
    const Eigen::Vector3d pos(0.3 * std::cos(a), 0.3 * std::sin(a), 1.2);
    Frame f = renderFrame(room, camera, lookHorizontal(pos, a), 0.0014, 1000 + i);
    f.source = "synthetic frame " + std::to_string(i);
    f.timestamp_s = static_cast<double>(i) / 30.0;
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace chronomap
