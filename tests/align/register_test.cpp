// Registration to the consensus: one rigid motion, per-pose corrections, drift along a session
// (fitDrift), the registration target's points, and registerSessions with re-integration.

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <numbers>
#include <span>
#include <vector>

#include "chronomap/align/consensus.h"
#include "chronomap/align/register.h"
#include "chronomap/core/error.h"
#include "builders.h"

using namespace chronomap;
using test::at;
using test::occupiedVoxel;

// ---------------------------------------------------------------------------------------------
// Registration to the consensus

namespace {

// A closed room (floor z = 0, four walls 1 m high, 2 x 2 m inside) sampled every 1 cm and moved
// by `t`: occupied voxels where the points fall.
SessionMap room(const Eigen::Isometry3d& t) {
  SessionMap m(0.05);
  const KeyGrid& g = m.grid();
  auto hit = [&](double x, double y, double z) {
    if (const auto k = g.keyOf(t * Eigen::Vector3d(x, y, z))) m.add(*k, occupiedVoxel({100, 100, 100}, 1));
  };
  for (double a = 0.005; a < 2.0; a += 0.01) {
    for (double b = 0.005; b < 2.0; b += 0.01) hit(a, b, 0.0126);
    for (double z = 0.005; z < 1.0; z += 0.01) {
      hit(0.0126, a, z);
      hit(2.0126, a, z);
      hit(a, 0.0126, z);
      hit(a, 2.0126, z);
    }
  }
  return m;
}

}  // namespace

TEST(RegisterToConsensus, FindsAShiftOfOneVoxel) {
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0.05, -0.05, 0.0);
  const SessionMap truth = room(Eigen::Isometry3d::Identity());
  const SessionMap shifted = room(shift);
  for (bool yaw_only : {true, false}) {
    RegisterSettings settings;
    settings.yaw_only = yaw_only;
    RegisterReport report;
    const Eigen::Isometry3d t = registerToConsensus(shifted, truth, settings, &report);
    EXPECT_NEAR(t.translation().x(), -0.05, 0.006) << yaw_only;
    EXPECT_NEAR(t.translation().y(), 0.05, 0.006);
    EXPECT_NEAR(t.translation().z(), 0.0, 0.006);
    EXPECT_LT(Eigen::AngleAxisd(t.linear()).angle(), 0.01);
    EXPECT_GT(report.points, 1000u);
    EXPECT_GT(report.mean_shift_before_m, 0.03);
    EXPECT_LT(report.mean_shift_after_m, 0.01);
  }
  // Planar: x, y and heading only. A shift with a vertical part: the horizontal part is found,
  // the vertical one left exactly as it is.
  Eigen::Isometry3d up = shift;
  up.translation().z() = 0.05;
  RegisterSettings planar;
  planar.planar = true;
  const Eigen::Isometry3d tp = registerToConsensus(room(up), truth, planar);
  EXPECT_NEAR(tp.translation().x(), -0.05, 0.006);
  EXPECT_NEAR(tp.translation().y(), 0.05, 0.006);
  EXPECT_NEAR(tp.translation().z(), 0.0, 1e-9);
  EXPECT_LT(Eigen::AngleAxisd(tp.linear()).angle(), 0.01);
  EXPECT_NEAR(registerToConsensus(room(up), truth).translation().z(), -0.05, 0.006);  // not planar: found
  // The same map needs no correction; nothing in reach gives the identity.
  EXPECT_LT(registerToConsensus(truth, truth).translation().norm(), 1e-9);
  SessionMap far_away(0.05);
  far_away.add(at(500, 500, 500), occupiedVoxel({1, 1, 1}));
  EXPECT_TRUE(registerToConsensus(far_away, truth).isApprox(Eigen::Isometry3d::Identity()));
}

TEST(RegisterToConsensus, RejectsBadSettings) {
  RegisterSettings s;
  s.radius_voxels = 0.5;
  EXPECT_THROW(s.validate(), UsageError);
  s = {};
  s.max_iterations = 0;
  EXPECT_THROW(s.validate(), UsageError);
  s = {};
  s.min_step_m = std::nan("");
  EXPECT_THROW(s.validate(), UsageError);
  for (const double fine : {0.5, 9.0, -1.0, std::nan("")}) {
    s = {};
    s.fine_radius_voxels = fine;
    EXPECT_THROW(s.validate(), UsageError) << fine;
  }
  s = {};
  s.fine_radius_voxels = 2.0;
  EXPECT_NO_THROW(s.validate());
  EXPECT_THROW(registerToConsensus(SessionMap(0.05), SessionMap(0.1)), UsageError);
}

namespace {

// Four sessions' poses: three agree, the fourth lies 5 cm off in x.
std::vector<Eigen::Isometry3d> threeAndAnOddOne() {
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0.05, 0.0, 0.0);
  return {Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), shift};
}

}  // namespace

TEST(RegisterSessions, BringsTheOddSessionToTheOthersAndReintegratesIt) {
  const std::vector<Eigen::Isometry3d> poses = threeAndAnOddOne();
  const Eigen::Isometry3d& shift = poses[3];
  std::vector<SessionMap> sessions;
  for (const auto& p : poses) sessions.push_back(room(p));
  std::atomic<size_t> calls = 0, last_calls = 0;  // sessions are integrated again in parallel
  std::vector<RegisterReport> reports;
  const auto corrections = registerSessions(
      sessions,
      [&](size_t k, const PoseCorrection& c, bool last) {
        ++calls;
        last_calls += last;
        EXPECT_EQ(c.model, CorrectionModel::World);
        return room(c.motion * poses[k]);
      },
      3, {}, &reports);
  EXPECT_EQ(calls, 3 * poses.size());
  EXPECT_EQ(last_calls, poses.size());  // the last round's, once per session
  ASSERT_EQ(corrections.size(), poses.size());
  // Any correction that puts the shifted walls back into the others' voxels is exact at this
  // resolution: x in (-0.0626, -0.0126) m.
  EXPECT_GT(corrections[3].motion.translation().x(), -0.0626);
  EXPECT_LT(corrections[3].motion.translation().x(), -0.0126);
  EXPECT_EQ(sessions[3], sessions[0]);
  for (size_t k = 0; k < 3; ++k) EXPECT_LT(corrections[k].motion.translation().norm(), 0.02);
  EXPECT_EQ(sessions[3], room(corrections[3].motion * shift));  // the re-integrated map replaced it
  EXPECT_GT(reports[3].mean_shift_before_m, reports[3].mean_shift_after_m);
  std::vector<SessionMap> none;
  EXPECT_THROW(registerSessions(none, {}, 1), UsageError);
  EXPECT_THROW(registerSessions(sessions, {}, 0), UsageError);
  RegisterSettings per_pose;
  per_pose.model = CorrectionModel::PerPose;
  EXPECT_THROW(registerSessions(sessions, {}, 1, per_pose), UsageError);  // no sensor positions
}

namespace {

// A hall 20 x 4 m (walls 1 m high, pillars of 0.3 m every 4 m along both long walls) seen from
// sensors every 0.5 m along its middle, each seeing the surfaces within 3 m. With a per-pose
// error every sensor sees its surroundings turned by `yaw` about itself and moved by `offset`,
// as a robot that localises with a heading and position offset does.
struct Hall {
  std::vector<Eigen::Vector3d> surface;  // samples every 2 cm
  std::vector<Eigen::Vector3d> sensors;  // true positions
  Hall() {
    auto box = [&](double x0, double y0, double x1, double y1) {
      for (double z = 0.01; z < 1.0; z += 0.02) {
        for (double x = x0; x <= x1; x += 0.02) {
          surface.emplace_back(x, y0, z);
          surface.emplace_back(x, y1, z);
        }
        for (double y = y0; y <= y1; y += 0.02) {
          surface.emplace_back(x0, y, z);
          surface.emplace_back(x1, y, z);
        }
      }
    };
    box(0.0, 0.0, 20.0, 4.0);
    for (double x = 2.0; x < 20.0; x += 4.0) {
      box(x, 0.0, x + 0.3, 0.3);
      box(x + 1.0, 3.7, x + 1.3, 4.0);
    }
    for (double x = 0.01; x < 20.0; x += 0.02) {
      for (double y = 0.01; y < 4.0; y += 0.02) surface.emplace_back(x, y, 0.0);
    }
    for (double x = 1.0; x <= 19.0; x += 0.5) sensors.emplace_back(x, 2.0, 0.5);
  }
  SessionMap seen(double yaw, const Eigen::Vector3d& offset) const {
    SessionMap m(0.05);
    const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (const Eigen::Vector3d& c : sensors) {
      for (const Eigen::Vector3d& p : surface) {
        if ((p - c).squaredNorm() > 9.0) continue;
        if (const auto k = m.grid().keyOf(c + offset + r * (p - c))) m.add(*k, occupiedVoxel({100, 100, 100}, 1));
      }
    }
    return m;
  }
  std::vector<Eigen::Vector3d> estimatedSensors(const Eigen::Vector3d& offset) const {
    std::vector<Eigen::Vector3d> out = sensors;
    for (auto& c : out) c += offset;
    return out;
  }
};

}  // namespace

TEST(RegisterToConsensus, PerPoseFindsAHeadingOffsetThatNoRigidMotionUndoes) {
  const Hall hall;
  const double yaw = 0.5 * std::numbers::pi / 180.0;  // 0.5 degrees: 8.7 cm at 10 m from a pivot
  const Eigen::Vector3d offset(0.04, -0.03, 0.0);
  const SessionMap truth = hall.seen(0.0, Eigen::Vector3d::Zero());
  const SessionMap session = hall.seen(yaw, offset);
  const std::vector<Eigen::Vector3d> believed = hall.estimatedSensors(offset);
  RegisterSettings settings;
  settings.max_points = 5000;  // enough for 3 degrees of freedom; keeps the sanitizer runs short
  settings.model = CorrectionModel::PerPose;
  RegisterReport per_pose;
  const Eigen::Isometry3d t = registerToConsensus(session, truth, settings, &per_pose, believed);
  // The correction turns every pose back by the heading error and moves it back by the offset,
  // the latter to within the voxels' quantisation: the walls lie on voxel boundaries, so every
  // shift that puts them back into the truth's voxels fits (y in [0.03, 0.08) here).
  const Eigen::AngleAxisd turn(t.linear());
  const double per_pose_yaw = turn.angle() * (turn.axis().z() < 0 ? -1.0 : 1.0);
  EXPECT_NEAR(per_pose_yaw, -yaw, 0.1 * std::numbers::pi / 180.0);
  EXPECT_NEAR(t.translation().x(), -offset.x(), 0.05);
  EXPECT_GE(t.translation().y(), 0.03 - 1e-9);
  EXPECT_LT(t.translation().y(), 0.08);
  EXPECT_NEAR(t.translation().z(), 0.0, 0.01);
  EXPECT_LT(per_pose.mean_shift_after_m, 0.5 * per_pose.mean_shift_before_m);
  // Corrected that way, the session's sensors see the truth's voxels again.
  const PoseCorrection c{t, CorrectionModel::PerPose};
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = believed[10];
  const Eigen::Isometry3d fixed = c.apply(pose);
  EXPECT_LT((fixed.translation() - hall.sensors[10]).norm(), 0.05);
  EXPECT_LT(Eigen::AngleAxisd(fixed.linear()).angle(), 0.1 * std::numbers::pi / 180.0);
  // One rigid motion of the whole session cannot turn the sensors back: turning the hall about
  // one point would move its far end by 8 cm, so the World fit keeps the heading error (and
  // with it the sensors' surroundings turned by up to 2.6 cm at 3 m) and fits worse.
  settings.model = CorrectionModel::World;
  RegisterReport world;
  const Eigen::Isometry3d tw = registerToConsensus(session, truth, settings, &world);
  EXPECT_LT(Eigen::AngleAxisd(tw.linear()).angle(), 0.25 * yaw);
  EXPECT_GT(world.mean_shift_after_m, per_pose.mean_shift_after_m);
  // PerPose needs the positions; they must be finite.
  settings.model = CorrectionModel::PerPose;
  EXPECT_THROW(registerToConsensus(session, truth, settings), UsageError);
  std::vector<Eigen::Vector3d> bad = believed;
  bad[3].x() = std::nan("");
  EXPECT_THROW(registerToConsensus(session, truth, settings, nullptr, bad), UsageError);
}

namespace {

// The hall, turned by 7 degrees against the voxel grid (so that its walls cross the voxels at
// every fraction and the maps show shifts smaller than a voxel), seen by a robot whose position
// estimate wanders during the session: frame j is taken at the true sensor position (the
// surfaces within 3 m as its points) but believed `offsetOf(j)` away, an error of up to 3 cm
// that changes smoothly along the hall.
struct DriftingHall {
  Hall hall = turned(Hall());
  static Hall turned(Hall h) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear() = Eigen::AngleAxisd(7.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    t.translation() = Eigen::Vector3d(0.013, 0.021, 0.0126);
    for (auto& p : h.surface) p = t * p;
    for (auto& c : h.sensors) c = t * c;
    return h;
  }
  FrameVector frames = FrameVector({});
  FrameVector true_frames = FrameVector({});
  static Eigen::Vector3d offsetOf(size_t j, size_t n) {
    const double u = static_cast<double>(j) / static_cast<double>(n - 1);
    return {0.03 * std::sin(2.0 * std::numbers::pi * u), 0.06 * u - 0.03, 0.0};
  }
  DriftingHall() {
    std::vector<Frame> believed, truth;
    const size_t n = hall.sensors.size();
    for (size_t j = 0; j < n; ++j) {
      Frame f;
      for (const Eigen::Vector3d& p : hall.surface) {
        // Every other sample: 4 cm apart, still several per voxel.
        if ((p - hall.sensors[j]).squaredNorm() <= 9.0 && (&p - hall.surface.data()) % 2 == 0) {
          f.cloud.points.push_back((p - hall.sensors[j]).cast<float>());
        }
      }
      f.cloud.width = static_cast<uint32_t>(f.cloud.points.size());
      f.T_world_sensor.translation() = hall.sensors[j];
      truth.push_back(f);
      f.T_world_sensor.translation() += offsetOf(j, n);
      believed.push_back(std::move(f));
    }
    frames = FrameVector(std::move(believed));
    true_frames = FrameVector(std::move(truth));
  }
  // Occupied voxels where the points of `source` land with its poses corrected by `c`.
  static SessionMap seen(const FrameSource& source, const PoseCorrection& c = {}) {
    SessionMap m(0.05);
    for (size_t i = 0; i < source.size(); ++i) {
      const Frame f = source.load(i);
      const Eigen::Isometry3d pose = c.apply(f.T_world_sensor, i);
      for (const Eigen::Vector3f& q : f.cloud.points) {
        if (const auto k = m.grid().keyOf(pose * q.cast<double>())) m.add(*k, occupiedVoxel({100, 100, 100}, 1));
      }
    }
    return m;
  }
  // Mean distance of the corrected sensor positions from the true ones.
  double meanError(const PoseCorrection& c) const {
    double sum = 0.0;
    for (size_t j = 0; j < frames.size(); ++j) {
      sum += (c.apply(frames.poseOf(j), j).translation() - hall.sensors[j]).norm();
    }
    return sum / static_cast<double>(frames.size());
  }
};

}  // namespace

TEST(FitDrift, FollowsAPositionErrorThatWandersAlongTheSession) {
  const DriftingHall d;
  const SessionMap truth = DriftingHall::seen(d.true_frames);
  const SessionMap session = DriftingHall::seen(d.frames);
  const RegistrationTarget target(truth);
  RegisterSettings settings;
  settings.drift_knot_frames = 4;  // 2 m of hall between knots
  RegisterReport report;
  const std::vector<Eigen::Isometry3d> drift = fitDrift(d.frames, session, target, settings, &report);
  ASSERT_EQ(drift.size(), d.frames.size());
  const PoseCorrection corrected{Eigen::Isometry3d::Identity(), CorrectionModel::World, drift};
  const double before = d.meanError({}), after = d.meanError(corrected);
  EXPECT_GT(before, 0.025);
  EXPECT_LT(after, 0.5 * before) << "before " << before << " after " << after;
  EXPECT_LT(report.mean_shift_after_m, report.mean_shift_before_m);
  EXPECT_GT(report.points, d.frames.size() * 50);
  // The headings stay as they were (the error has none).
  for (const auto& c : drift) EXPECT_LT(Eigen::AngleAxisd(c.linear()).angle(), 0.2 * std::numbers::pi / 180.0);
  // One rigid motion cannot follow the error: it changes sign along the hall.
  RegisterSettings rigid;
  const Eigen::Isometry3d t = registerToConsensus(session, target, rigid);
  EXPECT_GT(d.meanError({t, CorrectionModel::World, {}}), 1.5 * after);
  // A session that agrees with the target needs no drift correction.
  const std::vector<Eigen::Isometry3d> none = fitDrift(d.true_frames, truth, target, settings);
  for (const auto& c : none) EXPECT_LT(c.translation().norm(), 0.006);
  // Bad settings and mismatched resolutions are refused.
  settings.drift_knot_frames = 0;
  EXPECT_THROW(fitDrift(d.frames, session, target, settings), UsageError);
  settings.drift_knot_frames = 4;
  settings.drift_per_frame_m = 0.0;
  EXPECT_THROW(fitDrift(d.frames, session, target, settings), UsageError);
  settings.drift_per_frame_m = 0.002;
  EXPECT_THROW(fitDrift(d.frames, SessionMap(0.1), target, settings), UsageError);
  // No frames: nothing to correct.
  EXPECT_TRUE(fitDrift(FrameVector({}), session, target, settings).empty());
}

namespace {

// The hall seen by a robot that stops at each sensor position (every 0.5 m) and moves on,
// staying 8 frames at every third stop (looking round: the same view here) and 1 at the others.
// Its odometry gains error only while moving: every frame of stop j is believed errorAt(j) away,
// one value per stop that steps from stop to stop, whatever the number of frames at each.
struct StopAndGo {
  DriftingHall d;
  FrameVector frames = FrameVector({});
  std::vector<Eigen::Vector3d> truth;  // each frame's true sensor position
  std::vector<size_t> stop;            // each frame's stop
  // Stop j's error: 3 cm, turning once every 6 m of the path.
  static Eigen::Vector3d errorAt(size_t j) {
    const double a = 2.0 * std::numbers::pi * 0.5 * static_cast<double>(j) / 6.0;
    return {0.03 * std::cos(a), 0.03 * std::sin(a), 0.0};
  }
  StopAndGo() {
    std::vector<Frame> believed;
    const size_t n = d.hall.sensors.size();
    for (size_t j = 0; j < n; ++j) {
      const size_t repeats = j % 3 == 0 ? 8 : 1;
      for (size_t r = 0; r < repeats; ++r) {
        Frame f = d.true_frames.load(j);
        f.T_world_sensor.translation() += errorAt(j);
        believed.push_back(std::move(f));
        truth.push_back(d.hall.sensors[j]);
        stop.push_back(j);
      }
    }
    frames = FrameVector(std::move(believed));
  }
  double meanError(const std::vector<Eigen::Isometry3d>& drift) const {
    const PoseCorrection c{Eigen::Isometry3d::Identity(), CorrectionModel::World, drift};
    double sum = 0.0;
    for (size_t i = 0; i < frames.size(); ++i) sum += (c.apply(frames.poseOf(i), i).translation() - truth[i]).norm();
    return sum / static_cast<double>(frames.size());
  }
};

}  // namespace

TEST(FitDrift, KnotsAlongThePathFollowAnOdometryThatStopsAndMoves) {
  const StopAndGo s;
  const SessionMap truth = DriftingHall::seen(s.d.true_frames);
  const SessionMap session = DriftingHall::seen(s.frames);
  const RegistrationTarget target(truth);
  // About as many knots both ways: every metre of the 18 m path (two stops; 20 knots), or every
  // frames / 19 frames (23).
  RegisterSettings by_frames;
  by_frames.drift_knot_frames = static_cast<int>(s.frames.size() / 19);
  RegisterSettings by_path;
  by_path.drift_knot_m = 1.0;
  const std::vector<Eigen::Isometry3d> f = fitDrift(s.frames, session, target, by_frames);
  const std::vector<Eigen::Isometry3d> p = fitDrift(s.frames, session, target, by_path);
  ASSERT_EQ(p.size(), s.frames.size());
  const double before = s.meanError(std::vector<Eigen::Isometry3d>(s.frames.size(), Eigen::Isometry3d::Identity()));
  const double frames_after = s.meanError(f), path_after = s.meanError(p);
  // Measured: 30.0 mm before, 15.6 mm with knots by frames, 10.7 mm by path.
  EXPECT_LT(path_after, 0.5 * before);
  EXPECT_LT(path_after, frames_after);
  // A stop's frames lie at one place on the path: one correction, bit for bit.
  for (size_t i = 1; i < p.size(); ++i) {
    if (s.stop[i] == s.stop[i - 1]) {
      EXPECT_TRUE(p[i].isApprox(p[i - 1], 0.0)) << "frame " << i;
    }
  }
  // Knots a millimetre apart: 18,000 along the hall, of which only those next to a frame are
  // solved for (the others, held by the prior alone, fold into it), so this stays small.
  RegisterSettings fine = by_path;
  fine.drift_knot_m = 0.001;
  const std::vector<Eigen::Isometry3d> dense = fitDrift(s.frames, session, target, fine);
  ASSERT_EQ(dense.size(), s.frames.size());
  EXPECT_LT(s.meanError(dense), 0.5 * before);
  // A camera that never moves gets one correction for every frame (one place on the path).
  std::vector<Frame> still(4, s.frames.load(0));
  const std::vector<Eigen::Isometry3d> one = fitDrift(FrameVector(still), session, target, by_path);
  ASSERT_EQ(one.size(), 4u);
  for (const auto& c : one) EXPECT_TRUE(c.isApprox(one.front(), 0.0));
  // Bad settings are refused: both kinds of knots, a spacing out of range, no prior.
  RegisterSettings bad = by_path;
  bad.drift_knot_frames = 4;
  EXPECT_THROW(fitDrift(s.frames, session, target, bad), UsageError);
  for (double m : {-1.0, std::nan(""), 2000.0}) {
    bad = by_path;
    bad.drift_knot_m = m;
    EXPECT_THROW(fitDrift(s.frames, session, target, bad), UsageError) << m;
  }
  bad = by_path;
  bad.drift_per_m = 0.0;
  EXPECT_THROW(fitDrift(s.frames, session, target, bad), UsageError);
  bad = by_path;
  bad.drift_yaw_per_m_deg = std::nan("");
  EXPECT_THROW(fitDrift(s.frames, session, target, bad), UsageError);
}

TEST(FitDrift, KnotsAlongThePathThatNoFrameTouchesFoldIntoThePrior) {
  // The hall's frames 0.5 m apart along the path, each believed turned by a heading error that
  // wanders (positions exact, so the path is too). Knots every 0.5 m put a frame on every knot;
  // knots every 0.1 m add four between frames that no frame touches. Left out, with the prior
  // between their neighbours over five spacings, the two are the same system (but for the
  // solver's damping): the same corrections.
  const DriftingHall d;
  std::vector<Frame> believed;
  for (size_t j = 0; j < d.true_frames.size(); ++j) {
    Frame f = d.true_frames.load(j);
    const double yaw = 0.4 * std::numbers::pi / 180.0 * std::sin(2.0 * std::numbers::pi * static_cast<double>(j) / 12.0);
    f.T_world_sensor.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * f.T_world_sensor.linear();
    believed.push_back(std::move(f));
  }
  const FrameVector frames(std::move(believed));
  const SessionMap truth = DriftingHall::seen(d.true_frames);
  const SessionMap session = DriftingHall::seen(frames);
  const RegistrationTarget target(truth);
  RegisterSettings coarse;
  coarse.drift_knot_m = 0.5;
  RegisterSettings fine = coarse;
  fine.drift_knot_m = 0.1;
  const std::vector<Eigen::Isometry3d> a = fitDrift(frames, session, target, coarse);
  const std::vector<Eigen::Isometry3d> b = fitDrift(frames, session, target, fine);
  ASSERT_EQ(a.size(), frames.size());
  ASSERT_EQ(b.size(), frames.size());
  double turned = 0.0;
  for (size_t j = 0; j < a.size(); ++j) {
    turned = std::max(turned, Eigen::AngleAxisd(a[j].linear()).angle());
    EXPECT_LT((a[j].translation() - b[j].translation()).norm(), 1e-6) << j;
    EXPECT_LT(Eigen::AngleAxisd(a[j].linear().transpose() * b[j].linear()).angle(), 1e-7) << j;
  }
  EXPECT_GT(turned, 0.1 * std::numbers::pi / 180.0);  // the fit did turn the frames
  // A path cut into more knots than one session's dense system should hold is refused: 1,100
  // frames a centimetre apart, knots every millimetre (2,200 kept).
  std::vector<Frame> many(1100, Frame{});
  for (size_t i = 0; i < many.size(); ++i) many[i].T_world_sensor.translation() = Eigen::Vector3d(0.01 * i, 2.0, 0.5);
  RegisterSettings tiny;
  tiny.drift_knot_m = 0.001;
  EXPECT_THROW(fitDrift(FrameVector(std::move(many)), session, target, tiny), UsageError);
}

TEST(RegistrationTarget, AddsThePointsThatFallIntoItsSurface) {
  SessionMap consensus(0.05);
  consensus.add(at(100, 100, 100), occupiedVoxel({1, 1, 1}, 5));
  RegistrationTarget target(consensus);
  const Eigen::Vector3d centre = consensus.grid().centerOf(at(100, 100, 100));
  Frame f;
  f.T_world_sensor.translation() = centre - Eigen::Vector3d(1.0, 0.0, 0.0);
  // Two points in the surface voxel, one in a free neighbour, one beyond the range, one NaN.
  for (const Eigen::Vector3d& w : {Eigen::Vector3d(centre + Eigen::Vector3d(0.01, 0.02, -0.01)),
                                   Eigen::Vector3d(centre + Eigen::Vector3d(-0.01, 0.0, 0.01)),
                                   Eigen::Vector3d(centre + Eigen::Vector3d(0.05, 0.0, 0.0))}) {
    f.cloud.points.push_back((w - f.T_world_sensor.translation()).cast<float>());
  }
  f.cloud.points.push_back(Eigen::Vector3f(5.0f, 0.0f, 0.0f));
  f.cloud.points.push_back(Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f));
  target.addPoints(FrameVector({f}), 3.0);
  ASSERT_EQ(target.points().size(), 1u);
  const Eigen::Vector4d* found = target.points().find(mortonEncode(at(100, 100, 100)));
  ASSERT_NE(found, nullptr);
  const Eigen::Vector4d sum = *found;
  EXPECT_EQ(sum.w(), 2.0);
  EXPECT_TRUE((sum.head<3>() / 2.0).isApprox(centre + Eigen::Vector3d(0.0, 0.01, 0.0), 1e-6));
}

TEST(FitDrift, OnPointsFollowsTheErrorAcrossTheHallMoreClosely) {
  // The same wandering error, measured against the points of the true frames instead of voxel
  // centres. Across the hall (what its long walls show) the points follow it more closely;
  // along it only the pillars' small faces tell, about equally badly for both.
  const DriftingHall d;
  const SessionMap truth = DriftingHall::seen(d.true_frames);
  const SessionMap session = DriftingHall::seen(d.frames);
  RegistrationTarget target(truth);
  RegisterSettings settings;
  settings.drift_knot_frames = 4;
  const PoseCorrection on_voxels{Eigen::Isometry3d::Identity(), CorrectionModel::World,
                                 fitDrift(d.frames, session, target, settings)};
  target.addPoints(d.true_frames, settings.drift_max_range_m);
  settings.drift_points = true;
  settings.planar = true;
  RegisterReport report;
  const std::vector<Eigen::Isometry3d> drift = fitDrift(d.frames, session, target, settings, &report);
  const PoseCorrection on_points{Eigen::Isometry3d::Identity(), CorrectionModel::World, drift};
  // Mean error across the hall (it is turned by 7 degrees).
  const double turn = 7.0 * std::numbers::pi / 180.0;
  const Eigen::Vector3d across(-std::sin(turn), std::cos(turn), 0.0);
  auto acrossError = [&](const PoseCorrection& c) {
    double sum = 0.0;
    for (size_t j = 0; j < d.frames.size(); ++j) {
      sum += std::abs(across.dot(c.apply(d.frames.poseOf(j), j).translation() - d.hall.sensors[j]));
    }
    return sum / static_cast<double>(d.frames.size());
  };
  const double before = acrossError({}), voxels = acrossError(on_voxels), points = acrossError(on_points);
  // Measured: 17.6 mm before, 1.57 mm on voxels, 0.70 mm on points.
  EXPECT_GT(before, 0.01);
  EXPECT_LT(points, 0.001) << "on voxels " << voxels << ", on points " << points;
  EXPECT_LT(points, voxels);
  EXPECT_LT(d.meanError(on_points), 0.5 * d.meanError({}));
  EXPECT_GT(report.matched, d.frames.size() * 20);
  // Planar: no vertical part in any frame's correction.
  for (const auto& c : drift) EXPECT_EQ(c.translation().z(), 0.0);
  // The true frames against their own points need nothing (their own surface's pull cancels
  // what the neighbourhood of an edge does to the plane fit).
  for (const auto& c : fitDrift(d.true_frames, truth, target, settings)) EXPECT_LT(c.translation().norm(), 0.001);
}

TEST(RegisterSessions, CorrectsDriftFromTheFramesAndReintegrates) {
  const DriftingHall d;
  // Two sessions with the true poses and the drifting one.
  const std::vector<const FrameSource*> sources = {&d.true_frames, &d.true_frames, &d.frames};
  std::vector<SessionMap> sessions;
  for (const FrameSource* s : sources) sessions.push_back(DriftingHall::seen(*s));
  RegisterSettings settings;
  settings.max_points = 5000;
  settings.drift_knot_frames = 4;
  settings.drift_rounds = 1;
  const auto reintegrate = [&](size_t k, const PoseCorrection& c, bool) {
    return DriftingHall::seen(*sources[k], c);
  };
  const auto frames = [&](size_t k) -> std::unique_ptr<FrameSource> {
    return std::make_unique<FrameVector>(static_cast<const FrameVector*>(sources[k])->frames());
  };
  const auto corrections = registerSessions(sessions, reintegrate, 1, settings, nullptr, {}, frames);
  ASSERT_EQ(corrections.size(), 3u);
  ASSERT_EQ(corrections[2].per_frame.size(), d.frames.size());
  // (The consensus holds the drifting session too, so this is less exact than against the truth.)
  EXPECT_LT(d.meanError(corrections[2]), 0.65 * d.meanError({}));
  EXPECT_EQ(sessions[2], DriftingHall::seen(d.frames, corrections[2]));  // re-integrated with it
  // Drift needs the frames.
  EXPECT_THROW(registerSessions(sessions, reintegrate, 1, settings), UsageError);
}

namespace {

// Every sixth point of the hall's frames (enough for the fit, in a fraction of the time), the
// poses moved by `dx` metres in x.
FrameVector thinned(const FrameVector& frames, double dx = 0.0) {
  std::vector<Frame> out = frames.frames();
  for (Frame& f : out) {
    std::vector<Eigen::Vector3f> kept;
    for (size_t j = 0; j < f.cloud.points.size(); j += 6) kept.push_back(f.cloud.points[j]);
    f.cloud.points = std::move(kept);
    f.cloud.width = static_cast<uint32_t>(f.cloud.points.size());
    f.T_world_sensor.translation().x() += dx;
  }
  return FrameVector(std::move(out));
}

}  // namespace

TEST(RegisterSessions, OnePassForPointsAndSamplesGivesTheCorrectionsOfSeparatePasses) {
  // registerSessions reads every frame once per drift round for both the target's point sums and
  // the drift samples, in parallel batches; the reference reads them twice, serially
  // (RegistrationTarget::addPoints session after session, then fitDrift). Bit for bit the same.
  const DriftingHall d;
  const FrameVector truth = thinned(d.true_frames), drifting = thinned(d.frames);
  const std::vector<const FrameVector*> sources = {&truth, &drifting, &drifting};
  std::vector<SessionMap> sessions;
  for (const FrameSource* s : sources) sessions.push_back(DriftingHall::seen(*s));
  RegisterSettings settings;
  settings.max_points = 2000;
  settings.drift_knot_frames = 4;
  settings.drift_rounds = 2;
  settings.drift_points = true;
  settings.planar = true;
  const auto reintegrate = [&](size_t k, const PoseCorrection& c, bool) {
    return DriftingHall::seen(*sources[k], c);
  };
  const auto frames = [&](size_t k) -> std::unique_ptr<FrameSource> {
    return std::make_unique<FrameVector>(sources[k]->frames());
  };
  std::vector<SessionMap> reference = sessions;
  const auto found = registerSessions(sessions, reintegrate, 1, settings, nullptr, {}, frames);
  // The reference: one rigid round, then the drift rounds with two passes over the frames.
  std::vector<PoseCorrection> expected(reference.size(), PoseCorrection{});
  {
    const RegistrationTarget target(consensus(std::span<const SessionMap>(reference)));
    for (size_t k = 0; k < reference.size(); ++k) {
      expected[k] = expected[k].then({registerToConsensus(reference[k], target, settings), settings.model, {}});
    }
    for (size_t k = 0; k < reference.size(); ++k) reference[k] = reintegrate(k, expected[k], false);
  }
  for (int round = 0; round < settings.drift_rounds; ++round) {
    RegistrationTarget target(consensus(std::span<const SessionMap>(reference)));
    for (size_t k = 0; k < reference.size(); ++k) {
      target.addPoints(CorrectedFrames(*sources[k], expected[k]), settings.drift_max_range_m);
    }
    std::vector<PoseCorrection> drift;
    for (size_t k = 0; k < reference.size(); ++k) {
      drift.push_back({Eigen::Isometry3d::Identity(), settings.model,
                       fitDrift(CorrectedFrames(*sources[k], expected[k]), reference[k], target, settings)});
    }
    for (size_t k = 0; k < reference.size(); ++k) {
      expected[k] = expected[k].then(drift[k]);
      reference[k] = reintegrate(k, expected[k], round + 1 == settings.drift_rounds);
    }
  }
  ASSERT_EQ(found.size(), expected.size());
  for (size_t k = 0; k < found.size(); ++k) {
    EXPECT_TRUE(found[k].motion.matrix() == expected[k].motion.matrix()) << k;
    ASSERT_EQ(found[k].per_frame.size(), d.frames.size());
    ASSERT_EQ(expected[k].per_frame.size(), d.frames.size());
    for (size_t i = 0; i < d.frames.size(); ++i) {
      EXPECT_TRUE(found[k].per_frame[i].matrix() == expected[k].per_frame[i].matrix()) << k << " " << i;
    }
    EXPECT_EQ(sessions[k], reference[k]);
  }
  // The drifting sessions were corrected (the test compares a fit, not identities).
  EXPECT_LT(d.meanError(found[1]), 0.8 * d.meanError({}));
  EXPECT_LT(d.meanError(found[2]), 0.8 * d.meanError({}));
  // More frames than one batch of the pass.
  EXPECT_GT(sources.size() * d.frames.size(), 16u);
}

// A night of the streaming build: the night's sessions registered against the consensus of the
// sessions stored before (the prior). Two sessions that agree with each other, 5 cm off the
// stored ones: among themselves nothing moves; with the prior both are brought into the stored
// sessions' voxels, and keep_mean (which would take their shared motion out again) is not
// applied.
TEST(RegisterSessions, APriorConsensusAnchorsTheNightsSessions) {
  const std::vector<Eigen::Isometry3d> poses = threeAndAnOddOne();
  const Eigen::Isometry3d& shift = poses[3];
  const std::vector<SessionMap> stored = {room(poses[0]), room(poses[1]), room(poses[2])};
  const SessionMap prior = consensus(std::span<const SessionMap>(stored));
  const auto again = [&](size_t, const PoseCorrection& c, bool) { return room(c.motion * shift); };
  std::vector<SessionMap> among = {room(shift), room(shift)};
  for (const PoseCorrection& c : registerSessions(among, again, 3)) EXPECT_LT(c.motion.translation().norm(), 1e-9);
  for (bool keep_mean : {false, true}) {
    RegisterSettings settings;
    settings.keep_mean = keep_mean;
    std::vector<SessionMap> night = {room(shift), room(shift)};
    const auto corrections = registerSessions(night, again, 3, settings, nullptr, {}, {}, &prior);
    ASSERT_EQ(corrections.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      const Eigen::Isometry3d& m = corrections[k].motion;
      EXPECT_GT(m.translation().x(), -0.0626) << keep_mean;
      EXPECT_LT(m.translation().x(), -0.0126) << keep_mean;
      EXPECT_LT(std::abs(m.translation().y()), 0.005) << keep_mean;
      EXPECT_LT(std::abs(m.translation().z()), 0.005) << keep_mean;
      EXPECT_LT(Eigen::AngleAxisd(m.linear()).angle(), 1e-3) << keep_mean;
      EXPECT_NE(night[k], room(shift)) << keep_mean;  // integrated again with the correction
    }
  }
  const SessionMap coarse(0.1);
  std::vector<SessionMap> night = {room(shift)};
  EXPECT_THROW(registerSessions(night, again, 1, {}, nullptr, {}, {}, &coarse), UsageError);
}

// A stored consensus has no frames: its hits count as points at their mean position in the voxel.
TEST(RegistrationTarget, AddsAMapsHitsAtTheirMeanPosition) {
  SessionMap map(0.05);
  VoxelCounters hit = occupiedVoxel({1, 1, 1}, 4);
  hit.offset[0] = 0.4f;  // voxels, summed over the 4 hits: a mean of 0.1 voxel
  hit.offset[1] = -0.2f;
  map.add(at(100, 100, 100), hit);
  VoxelCounters no_offsets = occupiedVoxel({1, 1, 1}, 2);
  no_offsets.offset[2] = 5.0f;  // impossible for 2 hits: the centre stands in
  map.add(at(102, 100, 100), no_offsets);
  SessionMap target_map = map;
  target_map.add(at(104, 100, 100), occupiedVoxel({1, 1, 1}, 3));  // in the surface, not in `map`
  RegistrationTarget target(target_map);
  SessionMap outside = map;
  outside.add(at(110, 100, 100), occupiedVoxel({1, 1, 1}, 3));  // not in the surface: left out
  target.addMapPoints(outside);
  ASSERT_EQ(target.points().size(), 2u);
  const Eigen::Vector4d* a = target.points().find(mortonEncode(at(100, 100, 100)));
  const Eigen::Vector4d* b = target.points().find(mortonEncode(at(102, 100, 100)));
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(a->w(), 4.0);
  EXPECT_TRUE((a->head<3>() / 4.0).isApprox(map.grid().centerOf(at(100, 100, 100)) + Eigen::Vector3d(0.005, -0.0025, 0.0), 1e-9));
  EXPECT_EQ(b->w(), 2.0);
  EXPECT_TRUE((b->head<3>() / 2.0).isApprox(map.grid().centerOf(at(102, 100, 100)), 1e-9));
  EXPECT_THROW(target.addMapPoints(SessionMap(0.1)), UsageError);
}

TEST(RegisterSessions, KeepMeanMovesTheSessionsAgainstEachOtherNotTheMap) {
  // Three sessions agree and one lies 5 cm off in x. Registration alone brings the odd one to the
  // three (RegisterSessions.BringsTheOddSessionToTheOthersAndReintegratesIt); with keep_mean the
  // four meet where their mean lay: the corrections add up to nothing and still bring the odd
  // session into the others' voxels.
  const std::vector<Eigen::Isometry3d> poses = threeAndAnOddOne();
  std::vector<SessionMap> sessions;
  for (const auto& p : poses) sessions.push_back(room(p));
  RegisterSettings settings;
  settings.keep_mean = true;
  const auto corrections = registerSessions(
      sessions, [&](size_t k, const PoseCorrection& c, bool) { return room(c.motion * poses[k]); }, 3, settings);
  ASSERT_EQ(corrections.size(), poses.size());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double turn = 0.0;
  for (const PoseCorrection& c : corrections) {
    sum += c.motion.translation();
    turn += Eigen::AngleAxisd(c.motion.linear()).angle();
  }
  EXPECT_LT(sum.norm(), 1e-4) << sum.transpose();
  EXPECT_LT(turn, 1e-3);
  // The three moved by a quarter of the offset, the odd one by three quarters.
  for (size_t k = 0; k < 3; ++k) EXPECT_GT(corrections[k].motion.translation().x(), 0.005);
  const double apart = corrections[3].motion.translation().x() - corrections[0].motion.translation().x();
  EXPECT_GT(apart, -0.0626);
  EXPECT_LT(apart, -0.0126);
  EXPECT_EQ(sessions[3], sessions[0]);
}

namespace {

// Registers the hall sessions `sources` (one rigid round with keep_mean as asked, then one drift
// round, planar, on the voxels or on the points) and returns how the map as a whole moved, every
// frame's correction (rigid and drift parts together) counted once: the mean turn (radians) and
// the mean move of the sensors (metres).
std::pair<double, double> meanMapMotion(const std::vector<const FrameVector*>& sources, bool keep_mean,
                                        bool drift_points = false) {
  std::vector<SessionMap> sessions;
  for (const FrameSource* s : sources) sessions.push_back(DriftingHall::seen(*s));
  RegisterSettings settings;
  settings.max_points = 2000;
  settings.drift_knot_frames = 4;
  settings.drift_rounds = 1;
  settings.planar = true;
  settings.radius_voxels = 3.0;
  settings.keep_mean = keep_mean;
  settings.drift_points = drift_points;
  const auto corrections = registerSessions(
      sessions, [&](size_t k, const PoseCorrection& c, bool) { return DriftingHall::seen(*sources[k], c); }, 1,
      settings, nullptr, {},
      [&](size_t k) -> std::unique_ptr<FrameSource> { return std::make_unique<FrameVector>(sources[k]->frames()); });
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
  double n = 0.0;
  for (size_t k = 0; k < sources.size(); ++k) {
    EXPECT_EQ(corrections[k].per_frame.size(), sources[k]->size());
    for (size_t i = 0; i < sources[k]->size(); ++i) {
      const Eigen::Isometry3d before = sources[k]->poseOf(i), after = corrections[k].apply(before, i);
      const Eigen::AngleAxisd turn(after.linear() * before.linear().transpose());
      const Eigen::Vector3d wi = turn.angle() * turn.axis();
      w += wi;
      v += after.translation() - before.translation();
      n += 1.0;
    }
  }
  return {(w / n).norm(), (v / n).norm()};
}

}  // namespace

TEST(RegisterSessions, KeepMeanTakesTheSharedMotionOutOfTheDriftRounds) {
  // Two sessions with the true poses and a drifting one that also lies 2 cm off in x: without
  // keep_mean the two pull the third to them and the map as a whole moves (the sensors 3.4 mm on
  // average with the drift fitted on the voxels, 7.1 mm on the points, measured); with it, every
  // frame's correction, rigid and drift parts together, leaves the map where it was (0.03 and
  // 0.02 mm).
  const DriftingHall d;
  const FrameVector truth = thinned(d.true_frames, 0.0), drifting = thinned(d.frames, 0.02);
  const std::vector<const FrameVector*> sources = {&truth, &truth, &drifting};
  for (const bool points : {false, true}) {
    SCOPED_TRACE(points ? "drift fitted on the points" : "drift fitted on the voxels");
    const auto [free_turn, free_move] = meanMapMotion(sources, false, points);
    EXPECT_GT(free_move, 0.002);  // the map followed the two
    const auto [kept_turn, kept_move] = meanMapMotion(sources, true, points);
    EXPECT_LT(kept_move, 0.0005) << "without keep_mean " << free_move;
    EXPECT_LT(kept_turn, 1e-4) << "without keep_mean " << free_turn;
  }
}

TEST(RegisterSessions, KeepMeanTakesASharedTurnOut) {
  // The third session turned 0.6 degrees about the hall's middle: without keep_mean the map turns
  // (1.0e-3 rad on average over the frames, measured) and moves (11 mm) as the two pull the third
  // back; with it the mean turn stays at nothing (1e-18 rad) and the mean move under a millimetre
  // (0.13 mm), through the rigid round's turn and the drift round's alike.
  const DriftingHall d;
  const FrameVector truth = thinned(d.true_frames, 0.0);
  std::vector<Frame> turned = truth.frames();
  const Eigen::Vector3d middle = 0.5 * (d.hall.sensors.front() + d.hall.sensors.back());
  const Eigen::Isometry3d turn = Eigen::Translation3d(middle) *
                                 Eigen::AngleAxisd(0.6 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()) *
                                 Eigen::Translation3d(-middle);
  for (Frame& f : turned) f.T_world_sensor = turn * f.T_world_sensor;
  const FrameVector turned_frames(std::move(turned));
  const std::vector<const FrameVector*> sources = {&truth, &truth, &turned_frames};
  const auto [free_turn, free_move] = meanMapMotion(sources, false);
  EXPECT_GT(free_turn, 0.0005);  // radians: the map turned with the two
  const auto [kept_turn, kept_move] = meanMapMotion(sources, true);
  EXPECT_LT(kept_turn, 1e-5) << "without keep_mean " << free_turn;
  EXPECT_LT(kept_move, 0.001) << "without keep_mean " << free_move;
}

TEST(RegisterSessions, FineRadiusRefinesTheLaterDriftRounds) {
  // Three sessions of the hall with the true poses and one that drifts, registered with a wide
  // neighbourhood (4 voxels) and three drift rounds on the points: the rounds after the first at
  // 2 voxels (RegisterSettings::fine_radius_voxels) bring every session closer to the truth.
  const DriftingHall d;
  const FrameVector truth = thinned(d.true_frames), drifting = thinned(d.frames);
  const std::vector<const FrameVector*> sources = {&truth, &truth, &truth, &drifting};
  auto run = [&](double fine) {
    std::vector<SessionMap> sessions;
    for (const FrameSource* s : sources) sessions.push_back(DriftingHall::seen(*s));
    RegisterSettings settings;
    settings.max_points = 2000;
    settings.radius_voxels = 4.0;
    settings.drift_knot_frames = 4;
    settings.drift_rounds = 3;
    settings.drift_points = true;
    settings.planar = true;
    settings.fine_radius_voxels = fine;
    const auto corrections = registerSessions(
        sessions, [&](size_t k, const PoseCorrection& c, bool) { return DriftingHall::seen(*sources[k], c); }, 1,
        settings, nullptr, {},
        [&](size_t k) -> std::unique_ptr<FrameSource> { return std::make_unique<FrameVector>(sources[k]->frames()); });
    // Mean distance of every corrected sensor position from the truth, every session.
    double sum = 0.0, n = 0.0;
    for (size_t k = 0; k < sources.size(); ++k) {
      for (size_t j = 0; j < sources[k]->size(); ++j) {
        sum += (corrections[k].apply(sources[k]->poseOf(j), j).translation() - d.hall.sensors[j]).norm();
        n += 1.0;
      }
    }
    return sum / n;
  };
  // The wide neighbourhood throughout leaves the sensors 6.42 mm from the truth on average; with
  // the later two rounds at 2 voxels, 6.22 mm (measured).
  const double wide = run(0.0), fine = run(2.0);
  EXPECT_LT(fine, wide - 0.0001);
  EXPECT_LT(fine, 0.0064);
}
