// The patrol: where the robot stops and looks in a session, and its localisation error.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "internal.h"

namespace chronomap {

namespace sim_detail {

namespace {

struct Shot {
  Eigen::Vector2d position;
  double yaw;
};

// Stops and pan angles of one patrol through the rooms whose doors are open (each visited
// with probability 0.85, all of them in the first session).
std::vector<Shot> patrol(const SceneState& state, Rng& rng, bool first_session) {
  std::vector<Shot> shots;
  const double deg = std::numbers::pi / 180.0;
  auto pan = [&](const Eigen::Vector2d& p, int steps, double start) {
    for (int k = 0; k < steps; ++k) shots.push_back({p, start + 2.0 * std::numbers::pi * k / steps});
  };
  if (state.rooms.size() == 1) {  // tiny: four stops inside the room
    const auto& a = state.rooms[0].area;
    for (const Eigen::Vector2d& f : {Eigen::Vector2d(0.3, 0.35), Eigen::Vector2d(0.7, 0.35), Eigen::Vector2d(0.7, 0.65),
                                     Eigen::Vector2d(0.3, 0.65)}) {
      pan(a.min() + f.cwiseProduct(a.sizes()), 8, rng.uniform(0, 45 * deg));
    }
    return shots;
  }
  const Room& corridor = state.rooms[0];
  const double y = corridor.area.center().y();
  std::vector<const Room*> rooms;
  for (size_t r = 1; r < state.rooms.size(); ++r) rooms.push_back(&state.rooms[r]);
  std::sort(rooms.begin(), rooms.end(), [](const Room* a, const Room* b) { return a->door_m.x() < b->door_m.x(); });
  size_t next_room = 0;
  // The stops as they have always been computed: an integer counter would move them by rounding
  // and change every simulated dataset.
  // NOLINTNEXTLINE(clang-analyzer-security.FloatLoopCounter)
  for (double x = corridor.area.min().x() + 0.6; x < corridor.area.max().x() - 0.4; x += 1.0) {
    for (double a : {-60.0, 0.0, 60.0}) shots.push_back({{x, y}, a * deg});
    // Rooms whose door lies before the next stop: visit when the door is open and the patrol
    // includes it this time.
    while (next_room < rooms.size() && rooms[next_room]->door_m.x() < x + 1.0) {
      const Room& r = *rooms[next_room++];
      bool open = true;
      for (const Object& o : state.objects) {
        if (o.id == r.door_object) open = !o.present;
      }
      if (!open || (!first_session && !rng.chance(0.85))) continue;
      shots.push_back({{r.door_m.x(), y}, std::atan2(r.inside_m.y() - y, 0.0)});
      pan(r.inside_m, 8, rng.uniform(0, 45 * deg));
    }
  }
  return shots;
}

Eigen::Isometry3d cameraPose(const Eigen::Vector2d& p, double yaw) {
  const double pitch = kCameraPitchDeg * std::numbers::pi / 180.0;
  const Eigen::Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
  const Eigen::Vector3d right(std::sin(yaw), -std::cos(yaw), 0.0);
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = down;
  T.linear().col(2) = forward;
  T.translation() = Eigen::Vector3d(p.x(), p.y(), kOffset.z() + kCameraHeight);
  return T;
}

// The estimated poses of a sensor model's odometry (OdometryModel): from the first true pose
// with the session's localisation offset, each frame's planar motion (in the frame of the one
// before) measured with errors that accumulate along the path.
std::vector<Eigen::Isometry3d> odometryPoses(const std::vector<Shot>& shots, const OdometryModel& m, const Patrol& start,
                                             Rng& rng) {
  const double deg = std::numbers::pi / 180.0;
  const double scale = 1.0 + m.scale_sigma * rng.normal();
  const double yaw_bias_per_m = m.yaw_bias_deg_per_m * deg * rng.normal();
  std::vector<Eigen::Isometry3d> poses;
  if (shots.empty()) return poses;
  Eigen::Vector2d p = shots[0].position + Eigen::Vector2d(start.offset_x_m, start.offset_y_m);
  double yaw = shots[0].yaw + start.offset_yaw_rad;
  poses.push_back(cameraPose(p, yaw));
  for (size_t k = 1; k < shots.size(); ++k) {
    const Eigen::Rotation2Dd before(shots[k - 1].yaw);
    const Eigen::Vector2d motion = before.inverse() * (shots[k].position - shots[k - 1].position);
    const double turn = std::remainder(shots[k].yaw - shots[k - 1].yaw, 2.0 * std::numbers::pi);
    const double d = motion.norm();
    const double n1 = rng.normal(), n2 = rng.normal(), n3 = rng.normal();
    const Eigen::Vector2d measured =
        scale * motion + m.translation_m_per_sqrt_m * std::sqrt(d) * Eigen::Vector2d(n1, n2);
    const double measured_turn =
        turn + (m.yaw_deg_per_sqrt_m * deg * std::sqrt(d) + m.yaw_deg_per_sqrt_rad * deg * std::sqrt(std::abs(turn))) * n3 +
        yaw_bias_per_m * d;
    p += Eigen::Rotation2Dd(yaw) * measured;
    yaw += measured_turn;
    poses.push_back(cameraPose(p, yaw));
  }
  return poses;
}

}  // namespace

Patrol patrolSession(const SceneState& state, const SimulationSettings& settings, int session) {
  Rng path_rng(mix(settings.seed, 5000 + static_cast<uint64_t>(session)));
  const std::vector<Shot> shots = patrol(state, path_rng, session == 0);
  Patrol out;
  out.offset_x_m = settings.localisation_offset_m * path_rng.normal();
  out.offset_y_m = settings.localisation_offset_m * path_rng.normal();
  out.offset_yaw_rad = settings.localisation_yaw_deg * std::numbers::pi / 180.0 * path_rng.normal();
  double dx = out.offset_x_m, dy = out.offset_y_m, dyaw = out.offset_yaw_rad;
  for (const Shot& shot : shots) {
    const Eigen::Isometry3d T = cameraPose(shot.position, shot.yaw);
    dx += settings.drift_per_frame_m * path_rng.normal();
    dy += settings.drift_per_frame_m * path_rng.normal();
    dyaw += 0.01 * std::numbers::pi / 180.0 * path_rng.normal();
    Eigen::Isometry3d E = T;
    E.linear() = Eigen::AngleAxisd(dyaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * T.linear();
    E.translation() += Eigen::Vector3d(dx, dy, 0.0);
    out.true_poses.push_back(T);
    out.estimated.push_back(E);
  }
  const SensorModel sensor = sensorModel(parseSensorKind(settings.sensor));
  if (sensor.kind != SensorKind::Ideal) {
    // Its own stream, so that the patrol and the offset stay those of the ideal sensor.
    Rng odometry_rng(mix(settings.seed, 9000 + static_cast<uint64_t>(session)));
    out.estimated = odometryPoses(shots, sensor.odometry, out, odometry_rng);
  }
  return out;
}

}  // namespace sim_detail

}  // namespace chronomap
