#include "chronomap/align/register.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "chronomap/align/consensus.h"
#include "chronomap/core/error.h"
#include "chronomap/core/key_ball.h"
#include "chronomap/core/parallel.h"

namespace chronomap {

void RegisterSettings::validate() const {
  if (!std::isfinite(radius_voxels) || radius_voxels < 1.0 || radius_voxels > 8.0) {
    throw UsageError("registration: the radius must lie in [1, 8] voxels");
  }
  if (max_iterations < 1 || max_iterations > 1000) throw UsageError("registration: iterations must lie in [1, 1000]");
  if (!std::isfinite(min_step_m) || min_step_m < 0.0) throw UsageError("registration: the least step must be >= 0");
  if (max_points < 3) throw UsageError("registration: at least 3 points are needed");
  if (!std::isfinite(observer_range_m) || observer_range_m <= 0.0) {
    throw UsageError("registration: the observer range must be > 0");
  }
  if (drift_knot_frames < 0 || drift_knot_frames > 1000000) {
    throw UsageError("registration: the drift knot spacing must lie in [0, 1000000] frames");
  }
  if (!std::isfinite(drift_knot_m) || drift_knot_m < 0.0 || drift_knot_m > 1000.0) {
    throw UsageError("registration: the drift knot spacing along the path must lie in [0, 1000] m");
  }
  if (drift_knot_frames > 0 && drift_knot_m > 0.0) {
    throw UsageError("registration: drift knots either by frames or along the path, not both");
  }
  if (!std::isfinite(drift_per_m) || drift_per_m <= 0.0 || !std::isfinite(drift_yaw_per_m_deg) ||
      drift_yaw_per_m_deg <= 0.0) {
    throw UsageError("registration: the drift per metre must be > 0");
  }
  if (drift_rounds < 1 || drift_rounds > 10) throw UsageError("registration: drift rounds must lie in [1, 10]");
  if (!std::isfinite(fine_radius_voxels) || (fine_radius_voxels != 0.0 && (fine_radius_voxels < 1.0 || fine_radius_voxels > 8.0))) {
    throw UsageError("registration: the fine radius must be 0 (none) or lie in [1, 8] voxels");
  }
  if (!std::isfinite(drift_per_frame_m) || drift_per_frame_m <= 0.0 || !std::isfinite(drift_yaw_per_frame_deg) ||
      drift_yaw_per_frame_deg <= 0.0) {
    throw UsageError("registration: the drift per frame must be > 0");
  }
  if (drift_samples_per_frame < 1) throw UsageError("registration: at least one drift sample per frame is needed");
  if (!std::isfinite(drift_max_range_m) || drift_max_range_m <= 0.0) {
    throw UsageError("registration: the drift range must be > 0");
  }
}

namespace {

/// The small motion that best moves each point `a[i]` by its pull `b[i] - a[i]` along the
/// pull's own direction (point-to-plane least squares: a pull says how far the surface lies
/// along its normal, not where along the surface the point belongs), slightly damped: a
/// translation v and a rotation vector w, point i moving by v + w x (a[i] - pivot[i]). Yaw and
/// translation (w along z) or all six degrees of freedom.
Eigen::Matrix<double, 6, 1> fitStep(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                                    const std::vector<Eigen::Vector3d>& pivot, bool yaw_only, bool planar) {
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector3d pull = b[i] - a[i];
    const double r = pull.norm();
    if (r < 1e-9) continue;
    const Eigen::Vector3d n = pull / r;
    Eigen::Matrix<double, 6, 1> j;
    j << n, (a[i] - pivot[i]).cross(n);
    ata += j * j.transpose();
    atb += j * r;
  }
  // The unknowns solved for: all six; yaw only: translation and rotation about z (index 5);
  // planar: x, y and yaw.
  const int dof = planar ? 3 : (yaw_only ? 4 : 6);
  Eigen::MatrixXd m(dof, dof);
  Eigen::VectorXd v(dof);
  static constexpr int kAll[6] = {0, 1, 2, 5, 3, 4}, kPlanar[3] = {0, 1, 5};
  const int* index = planar ? kPlanar : kAll;
  for (int i = 0; i < dof; ++i) {
    v(i) = atb(index[i]);
    for (int k = 0; k < dof; ++k) m(i, k) = ata(index[i], index[k]);
  }
  m += 1e-6 * (m.trace() / dof + 1.0) * Eigen::MatrixXd::Identity(dof, dof);
  const Eigen::VectorXd x = m.ldlt().solve(v);
  Eigen::Matrix<double, 6, 1> step = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < dof; ++i) step(index[i]) = x(i);
  return step;
}

Eigen::Matrix3d rotationOf(const Eigen::Vector3d& omega) {
  if (omega.norm() == 0.0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
}

/// A small rigid motion of the whole map, linearised: p moves by w x p + v (w a rotation vector
/// about the world's origin), fitted to many frames' corrections: its turn is their mean turn,
/// and it moves the mean of their sensor positions as they move it on average.
struct CommonMotion {
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), t = Eigen::Vector3d::Zero(), s = Eigen::Vector3d::Zero();
  double count = 0.0;

  static Eigen::Vector3d rotationVector(const Eigen::Matrix3d& r) {
    const Eigen::AngleAxisd a(r);
    return a.angle() * a.axis();
  }
  /// A frame's correction `c` (a turn about the sensor at `sensor`, then a translation).
  void addPerPose(const Eigen::Isometry3d& c, const Eigen::Vector3d& sensor) {
    w += rotationVector(c.linear());
    t += c.translation();
    s += sensor;
    count += 1.0;
  }
  Eigen::Isometry3d mean() const {
    Eigen::Isometry3d g = Eigen::Isometry3d::Identity();
    if (count == 0.0) return g;
    const Eigen::Vector3d turn = w / count;
    g.linear() = rotationOf(turn);
    g.translation() = t / count - turn.cross(s / count);
    return g;
  }
};

/// Takes the motion the sessions' rigid corrections `steps` share out of each (keep_mean): their
/// mean rotation vector and translation, as a motion of the map frame (World) or of every pose
/// (PerPose).
void removeCommonMotion(std::vector<Eigen::Isometry3d>& steps, CorrectionModel model) {
  if (steps.size() < 2) return;
  // Each step is a turn about the origin, then a translation (World), or the same about each
  // pose (PerPose): the mean of the turns and translations either way.
  CommonMotion common;
  for (const Eigen::Isometry3d& t : steps) common.addPerPose(t, Eigen::Vector3d::Zero());
  const Eigen::Isometry3d g = common.mean();
  for (Eigen::Isometry3d& t : steps) {
    if (model == CorrectionModel::World) {
      t = g.inverse() * t;
    } else {
      Eigen::Isometry3d inverse_turn = Eigen::Isometry3d::Identity();
      inverse_turn.linear() = g.linear().transpose();
      inverse_turn.translation() = -g.translation();
      t = PoseCorrection::perPose(inverse_turn, t);
    }
  }
}

/// The same for the drift rounds' per-frame steps `per_frame[k][i]` (a turn about the sensor at
/// `sensors[k][i]`, then a translation): the rigid motion of the whole map that best matches
/// every frame's step is taken out of each, exactly (G^-1 applied after the step).
void removeCommonDrift(std::vector<std::vector<Eigen::Isometry3d>>& per_frame,
                       const std::vector<std::vector<Eigen::Vector3d>>& sensors) {
  size_t with_frames = 0;
  CommonMotion common;
  for (size_t k = 0; k < per_frame.size(); ++k) {
    with_frames += per_frame[k].empty() ? 0 : 1;
    for (size_t i = 0; i < per_frame[k].size(); ++i) common.addPerPose(per_frame[k][i], sensors[k][i]);
  }
  if (with_frames < 2) return;
  const Eigen::Isometry3d g = common.mean();
  const Eigen::Matrix3d back = g.linear().transpose();
  for (size_t k = 0; k < per_frame.size(); ++k) {
    for (size_t i = 0; i < per_frame[k].size(); ++i) {
      Eigen::Isometry3d& c = per_frame[k][i];
      const Eigen::Vector3d& s = sensors[k][i];
      c.linear() = back * c.linear();
      c.translation() = back * (s + c.translation() - g.translation()) - s;
    }
  }
}

/// For each point, the mean of the sensor positions within `range` of it, or the nearest one.
std::vector<Eigen::Vector3d> observersOf(const std::vector<Eigen::Vector3d>& points,
                                         std::span<const Eigen::Vector3d> sensors, double range) {
  std::vector<Eigen::Vector3d> out(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    size_t n = 0;
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector3d nearest = sensors.front();
    for (const Eigen::Vector3d& c : sensors) {
      const double d2 = (c - points[i]).squaredNorm();
      if (d2 <= range * range) {
        sum += c;
        ++n;
      }
      if (d2 < best) {
        best = d2;
        nearest = c;
      }
    }
    out[i] = n ? Eigen::Vector3d(sum / static_cast<double>(n)) : nearest;
  }
  return out;
}

using HitMap = VoxelTable<uint32_t>;
using PointSums = VoxelTable<Eigen::Vector4d>;

/// A frame point the registration uses: finite, not at the sensor, within `range2` (squared
/// metres) of it.
bool usablePoint(const Eigen::Vector3f& q, double range2) {
  return q.allFinite() && q.squaredNorm() != 0.0f && q.cast<double>().squaredNorm() <= range2;
}

/// Adds world points to the sums (x, y, z, count) of their voxels, remembering the last voxel:
/// consecutive points of a depth image mostly end in the same one, and then need no lookup.
/// With `only`, points in voxels it lacks are left out. Valid while nothing else changes `sums`.
class PointAdder {
 public:
  explicit PointAdder(PointSums& sums, const HitMap* only = nullptr) : sums_(sums), only_(only) {}
  void add(uint64_t code, const Eigen::Vector3d& w) {
    if (code != last_) {
      last_ = code;
      // The pointer stays valid until the next insertion, which only this line makes. A zero to
      // start from: a default-constructed Eigen vector is uninitialised.
      sum_ = only_ && !only_->contains(code) ? nullptr : &sums_.tryEmplace(code, Eigen::Vector4d::Zero());
    }
    if (sum_) *sum_ += Eigen::Vector4d(w.x(), w.y(), w.z(), 1.0);
  }

 private:
  PointSums& sums_;
  const HitMap* only_;
  uint64_t last_ = PointSums::kEmpty;
  Eigen::Vector4d* sum_ = nullptr;
};

/// Occupied unit voxels of a map and their hits; their centres, in Morton order, go to `centres`
/// when given.
HitMap surfaceOf(const SessionMap& map, std::vector<Eigen::Vector3d>* centres = nullptr) {
  HitMap out;
  map.forEachLeaf([&](const LeafView& l) {
    if (l.level != 0 || l.counters.state() != VoxelState::Occupied) return;
    out.tryEmplace(mortonEncode(l.key), l.counters.hits);
    if (centres) centres->push_back(map.grid().centerOf(l.key));
  });
  return out;
}

/// Calls fn(centre, hits, d2) for every voxel of `surface` within `radius_voxels` of `p`
/// (d2: squared distance of its centre from `p`, in m^2), in the order of forEachKeyWithin().
/// Returns the radius in metres, or a negative value when `p` lies outside the grid.
template <typename Fn>
double forEachNear(const HitMap& surface, const KeyGrid& grid, const Eigen::Vector3d& p, double radius_voxels, Fn fn) {
  const double radius_m = radius_voxels * grid.resolution_m();
  const double radius2 = radius_m * radius_m;
  // The distance first: most of the cube lies outside the sphere, and a lookup costs more.
  const bool inside = forEachFoundWithin(
      surface, grid, p, radius_voxels, false,
      [&](const VoxelKey& n) { return !((grid.centerOf(n) - p).squaredNorm() > radius2); },
      [&](const VoxelKey& n, uint32_t hits) {
        const Eigen::Vector3d c = grid.centerOf(n);
        fn(c, hits, (c - p).squaredNorm());
      });
  return inside ? radius_m : -1.0;
}

/// The centre of the voxels of `surface` around `p`, weighted by their hits and a Gaussian of
/// the distance (sigma half the radius; nothing beyond the radius), so that it moves smoothly
/// with `p` (continuously with `vanishing`).
std::optional<Eigen::Vector3d> centroidNear(const HitMap& surface, const KeyGrid& grid, const Eigen::Vector3d& p,
                                            double radius_voxels, bool vanishing = false) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  const double radius_m = radius_voxels * grid.resolution_m();
  forEachNear(surface, grid, p, radius_voxels, [&](const Eigen::Vector3d& c, uint32_t hits, double d2) {
    // `vanishing`: the Gaussian minus its value at the radius, so that the centre moves
    // continuously as voxels leave the neighbourhood.
    const double w = static_cast<double>(hits) *
                     (std::exp(-2.0 * d2 / (radius_m * radius_m)) - (vanishing ? std::exp(-2.0) : 0.0));
    sum += w * c;
    weight += w;
  });
  if (weight <= 0.0) return std::nullopt;
  return sum / weight;
}

}  // namespace

RegistrationTarget::RegistrationTarget(const SessionMap& consensus)
    : grid_(consensus.grid()), surface_(surfaceOf(consensus)) {}

void RegistrationTarget::addPoints(const FrameSource& frames, double max_range_m) {
  std::vector<KeyedPoint> keyed;
  for (size_t i = 0; i < frames.size(); ++i) {
    keyPoints(frames.load(i), max_range_m, keyed);
    addKeyedPoints(keyed);
  }
}

void RegistrationTarget::keyPoints(const Frame& f, double max_range_m, std::vector<KeyedPoint>& out) const {
  if (!f.T_world_sensor.matrix().allFinite()) throw UsageError(f.source + ": the pose is not finite");
  const double range2 = max_range_m * max_range_m;
  out.clear();
  // Consecutive points mostly share a voxel: one lookup for a run of them.
  uint64_t last = HitMap::kEmpty;
  bool last_in = false;
  for (const Eigen::Vector3f& q : f.cloud.points) {
    if (!usablePoint(q, range2)) continue;
    const Eigen::Vector3d w = f.T_world_sensor * q.cast<double>();
    const auto k = grid_.keyOf(w);
    if (!k) continue;
    const uint64_t code = mortonEncode(*k);
    if (code != last) {
      last = code;
      last_in = surface_.contains(code);
    }
    if (last_in) out.push_back({code, w});
  }
}

void RegistrationTarget::addKeyedPoints(std::span<const KeyedPoint> points) {
  PointAdder adder(points_, &surface_);
  for (const KeyedPoint& p : points) adder.add(p.code, p.point);
}

void RegistrationTarget::addMapPoints(const SessionMap& map) {
  if (map.resolution_m() != resolution_m()) {
    throw UsageError("registration: the prior consensus and the target have different resolutions");
  }
  const double res = resolution_m();
  map.forEachLeaf([&](const LeafView& l) {
    if (l.level != 0 || l.counters.hits == 0) return;
    const uint64_t code = mortonEncode(l.key);
    if (!surface_.contains(code)) return;
    const double hits = l.counters.hits;
    Eigen::Vector3d sum = grid_.centerOf(l.key) * hits;
    if (l.counters.offsetsValid()) {
      for (int a = 0; a < 3; ++a) sum[a] += static_cast<double>(l.counters.offset[a]) * res;
    }
    points_.tryEmplace(code, Eigen::Vector4d::Zero()) += Eigen::Vector4d(sum.x(), sum.y(), sum.z(), hits);
  });
}

Eigen::Isometry3d registerToConsensus(const SessionMap& session, const SessionMap& consensus,
                                      const RegisterSettings& settings, RegisterReport* report,
                                      std::span<const Eigen::Vector3d> sensor_positions) {
  settings.validate();
  if (session.resolution_m() != consensus.resolution_m()) {
    throw UsageError("registration: the session and the consensus have different resolutions");
  }
  return registerToConsensus(session, RegistrationTarget(consensus), settings, report, sensor_positions);
}

Eigen::Isometry3d registerToConsensus(const SessionMap& session, const RegistrationTarget& target,
                                      const RegisterSettings& settings, RegisterReport* report,
                                      std::span<const Eigen::Vector3d> sensor_positions) {
  settings.validate();
  if (session.resolution_m() != target.resolution_m()) {
    throw UsageError("registration: the session and the consensus have different resolutions");
  }
  const bool per_pose = settings.model == CorrectionModel::PerPose;
  if (per_pose && sensor_positions.empty()) {
    throw UsageError("registration per pose needs the session's sensor positions");
  }
  for (const Eigen::Vector3d& c : sensor_positions) {
    if (!c.allFinite()) throw UsageError("registration: a sensor position is not finite");
  }
  const KeyGrid& grid = session.grid();
  const HitMap& surface = target.surface();
  // The session's surface and its occupied voxel centres, evenly thinned.
  std::vector<Eigen::Vector3d> points;
  const HitMap own = surfaceOf(session, &points);
  if (points.size() > settings.max_points) {
    std::vector<Eigen::Vector3d> thinned;
    const double step = static_cast<double>(points.size()) / static_cast<double>(settings.max_points);
    for (size_t i = 0; i < settings.max_points; ++i) thinned.push_back(points[static_cast<size_t>(i * step)]);
    points.swap(thinned);
  }
  // The pull of the session's own surface on each point: near an edge or a corner the centre of
  // the surface around a point lies off the point even where nothing is misaligned, so the pull
  // towards the consensus is measured relative to it (identical maps pull nowhere).
  std::vector<Eigen::Vector3d> own_pull(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    own_pull[i] = centroidNear(own, grid, points[i], settings.radius_voxels).value_or(points[i]) - points[i];
  }
  // PerPose: the sensor positions each point turns about (they move with the translation).
  const std::vector<Eigen::Vector3d> observers =
      per_pose ? observersOf(points, sensor_positions, settings.observer_range_m) : std::vector<Eigen::Vector3d>{};
  RegisterReport rep;
  rep.points = points.size();
  Eigen::Isometry3d total = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> from, to, pivot;
  for (int it = 0; it < settings.max_iterations && !surface.empty(); ++it) {
    from.clear();
    to.clear();
    pivot.clear();
    double shift = 0.0;
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d p =
          per_pose ? Eigen::Vector3d(observers[i] + total.translation() + total.linear() * (points[i] - observers[i]))
                   : Eigen::Vector3d(total * points[i]);
      const auto q = centroidNear(surface, grid, p, settings.radius_voxels);
      if (!q) continue;
      from.push_back(p);
      to.push_back(*q - total.linear() * own_pull[i]);
      if (per_pose) pivot.push_back(observers[i] + total.translation());
      shift += (to.back() - p).norm();
    }
    rep.matched = from.size();
    const double mean_shift = from.empty() ? 0.0 : shift / static_cast<double>(from.size());
    if (it == 0) rep.mean_shift_before_m = mean_shift;
    rep.mean_shift_after_m = mean_shift;
    rep.iterations = it + 1;
    if (from.size() < 3) break;
    if (!per_pose) {
      // One rotation about the centre of the matched points (better conditioned than the origin).
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (const auto& p : from) centre += p;
      centre /= static_cast<double>(from.size());
      pivot.assign(from.size(), centre);
    }
    const Eigen::Matrix<double, 6, 1> x = fitStep(from, to, pivot, settings.yaw_only, settings.planar);
    const Eigen::Matrix3d r = rotationOf(x.tail<3>());
    if (per_pose) {
      total.linear() = r * total.linear();
      total.translation() += x.head<3>();
    } else {
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      step.linear() = r;
      step.translation() = pivot.front() + x.head<3>() - r * pivot.front();
      total = step * total;
    }
    const double moved = x.head<3>().norm() + x.tail<3>().norm() * 1.0;
    if (moved < settings.min_step_m) break;
  }
  if (report) *report = rep;
  return total;
}

namespace {

/// One voxel a frame saw (or, with RegisterSettings::drift_points, one of its points), for the
/// drift fit.
struct DriftSample {
  Eigen::Vector3d point;     ///< the voxel centre (or the point), as integrated
  Eigen::Vector3d own_pull;  ///< the pull of the frame's own voxels (points) on it
  Eigen::Vector3d normal;    ///< of the frame's surface here; zero where it is no plane
  uint32_t frame = 0;
};

/// The normal of `surface` around `p` (the direction of least spread of the voxel centres
/// within the radius, weighted as in centroidNear()), or zero where the surface there is no
/// plane (an edge, a corner, too few voxels): its spread across is not below a third of the
/// next smallest.
Eigen::Vector3d normalNear(const HitMap& surface, const KeyGrid& grid, const Eigen::Vector3d& p, double radius_voxels) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  double weight = 0.0;
  int count = 0;
  const double radius_m = radius_voxels * grid.resolution_m();
  forEachNear(surface, grid, p, radius_voxels, [&](const Eigen::Vector3d& centre, uint32_t, double d2) {
    const Eigen::Vector3d c = centre - p;
    const double w = std::exp(-2.0 * d2 / (radius_m * radius_m));
    sum += w * c;
    outer += w * c * c.transpose();
    weight += w;
    ++count;
  });
  if (count < 6) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d mean = sum / weight;
  const Eigen::Matrix3d cov = outer / weight - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d values = eig.eigenvalues();  // ascending
  if (!(values(0) < values(1) / 3.0)) return Eigen::Vector3d::Zero();
  return eig.eigenvectors().col(0);
}

/// The points' surface around `p` (RegisterSettings::drift_points): the mean of the voxel
/// means within the radius, weighted by their point counts and a Gaussian of the distance, and
/// the normal there (least spread of the voxel means), or nothing where there are too few voxels
/// or the surface is no plane.
struct PlaneNear {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
};
std::optional<PlaneNear> pointPlaneNear(const PointSums& points, const KeyGrid& grid, const Eigen::Vector3d& p,
                                        double radius_voxels) {
  const double radius_m = radius_voxels * grid.resolution_m();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  double weight = 0.0;
  int count = 0;
  // A voxel's mean lies inside the voxel: voxels whose box lies beyond the radius are not
  // looked up.
  const auto all = [](const VoxelKey&) { return true; };
  const auto add = [&](const VoxelKey&, const Eigen::Vector4d& found) {
    if (found.w() <= 0.0) return;
    const Eigen::Vector3d m = found.head<3>() / found.w() - p;
    const double d2 = m.squaredNorm();
    if (d2 > radius_m * radius_m) return;
    const double w = found.w() * std::exp(-2.0 * d2 / (radius_m * radius_m));
    sum += w * m;
    outer += w * m * m.transpose();
    weight += w;
    ++count;
  };
  const bool inside = forEachFoundWithin(points, grid, p, radius_voxels, true, all, add);
  if (!inside || count < 6 || weight <= 0.0) return std::nullopt;
  const Eigen::Vector3d mean = sum / weight;
  const Eigen::Matrix3d cov = outer / weight - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d values = eig.eigenvalues();  // ascending
  if (!(values(0) < values(1) / 3.0)) return std::nullopt;
  return PlaneNear{p + mean, eig.eigenvectors().col(0)};
}

/// Tables driftSamplesOf() fills for each frame, kept between frames for their memory.
struct DriftScratch {
  HitMap frame_surface;
  PointSums frame_points;
  std::vector<uint64_t> codes;
  std::vector<Eigen::Vector3d> usable;
};

/// Appends the drift samples of frame `index` (`f`, as integrated) to `out`: the voxels its
/// points end in (with `use_points`, its points), evenly thinned, each with the pull of that
/// frame's own voxels (points) on it (the frame's surface quantised exactly as the consensus is,
/// so that a frame that fits pulls nowhere) and the normal of the frame's surface there.
/// @throw UsageError for a pose that is not finite.
void driftSamplesOf(const Frame& f, uint32_t index, const KeyGrid& grid, const RegisterSettings& settings,
                    bool use_points, DriftScratch& scratch, std::vector<DriftSample>& out) {
  if (!f.T_world_sensor.matrix().allFinite()) throw UsageError(f.source + ": the pose is not finite");
  const double range2 = settings.drift_max_range_m * settings.drift_max_range_m;
  if (use_points) {
    // The frame's own points by voxel (sums and counts), for the pull of its own surface.
    PointSums& frame_points = scratch.frame_points;
    frame_points.clear();
    PointAdder adder(frame_points);
    size_t valid = 0;
    for (const Eigen::Vector3f& q : f.cloud.points) {
      if (!usablePoint(q, range2)) continue;
      ++valid;
      const Eigen::Vector3d w = f.T_world_sensor * q.cast<double>();
      if (const auto k = grid.keyOf(w)) adder.add(mortonEncode(*k), w);
    }
    // Frame points, evenly thinned, as integrated (sub-voxel positions).
    const size_t take = std::min(valid, settings.drift_samples_per_frame);
    size_t seen = 0, next_index = 0, taken = 0;
    for (const Eigen::Vector3f& q : f.cloud.points) {
      if (taken >= take) break;
      if (!usablePoint(q, range2)) continue;
      if (seen++ != next_index) continue;
      DriftSample d;
      d.point = f.T_world_sensor * q.cast<double>();
      // Where the frame's own points put the plane near the point: a frame that fits its
      // target pulls nowhere, at edges and corners too.
      const auto own = pointPlaneNear(frame_points, grid, d.point, settings.radius_voxels);
      ++taken;
      next_index = taken * valid / take;
      if (!own) continue;
      d.own_pull = own->point - d.point;
      d.normal = own->normal;
      d.frame = index;
      out.push_back(d);
    }
    return;
  }
  HitMap& frame_surface = scratch.frame_surface;
  frame_surface.clear();
  for (const Eigen::Vector3f& q : f.cloud.points) {
    if (!usablePoint(q, range2)) continue;
    const auto k = grid.keyOf(f.T_world_sensor * q.cast<double>());
    if (k) ++frame_surface.tryEmplace(mortonEncode(*k), 0);
  }
  std::vector<uint64_t>& codes = scratch.codes;
  codes.clear();
  frame_surface.forEach([&](uint64_t code, uint32_t) { codes.push_back(code); });
  std::sort(codes.begin(), codes.end());
  const size_t take = std::min(codes.size(), settings.drift_samples_per_frame);
  for (size_t j = 0; j < take; ++j) {
    const uint64_t code = codes[j * codes.size() / take];
    DriftSample d;
    d.point = grid.centerOf(mortonDecode(code));
    d.own_pull = centroidNear(frame_surface, grid, d.point, settings.radius_voxels, true).value_or(d.point) - d.point;
    d.normal = normalNear(frame_surface, grid, d.point, settings.radius_voxels);
    d.frame = index;
    out.push_back(d);
  }
}

/// What RegistrationTarget::keyPoints() and driftSamplesOf() with points give for one frame (in
/// `keyed` and appended to `samples`), in one walk over its points: each point's world position
/// and voxel once for both (the session's grid is the target's: the same resolution).
/// @throw UsageError for a pose that is not finite.
void keyPointsAndSamplesOf(const Frame& f, uint32_t index, const RegistrationTarget& target,
                           const RegisterSettings& settings, DriftScratch& scratch,
                           std::vector<RegistrationTarget::KeyedPoint>& keyed, std::vector<DriftSample>& samples) {
  if (!f.T_world_sensor.matrix().allFinite()) throw UsageError(f.source + ": the pose is not finite");
  const double range2 = settings.drift_max_range_m * settings.drift_max_range_m;
  const KeyGrid& grid = target.grid();
  const HitMap& surface = target.surface();
  keyed.clear();
  std::vector<Eigen::Vector3d>& usable = scratch.usable;
  usable.clear();
  PointSums& frame_points = scratch.frame_points;
  frame_points.clear();
  PointAdder adder(frame_points);
  uint64_t last = HitMap::kEmpty;
  bool last_in = false;
  for (const Eigen::Vector3f& q : f.cloud.points) {
    if (!usablePoint(q, range2)) continue;
    const Eigen::Vector3d w = f.T_world_sensor * q.cast<double>();
    usable.push_back(w);
    const auto k = grid.keyOf(w);
    if (!k) continue;
    const uint64_t code = mortonEncode(*k);
    adder.add(code, w);
    if (code != last) {
      last = code;
      last_in = surface.contains(code);
    }
    if (last_in) keyed.push_back({code, w});
  }
  // The usable points at t * valid / take, t = 0 .. take - 1: those driftSamplesOf() takes.
  const size_t valid = usable.size();
  const size_t take = std::min(valid, settings.drift_samples_per_frame);
  for (size_t t = 0; t < take; ++t) {
    DriftSample d;
    d.point = usable[t * valid / take];
    const auto own = pointPlaneNear(frame_points, grid, d.point, settings.radius_voxels);
    if (!own) continue;
    d.own_pull = own->point - d.point;
    d.normal = own->normal;
    d.frame = index;
    samples.push_back(d);
  }
}

// Drift knots: frame i lies at u[i] (in knot spacings: i / spacing by frames, the path to the
// frame over the spacing in metres along the path) between knots floor(u) and floor(u) + 1,
// each with kDriftDof unknowns (x, y, z offset and yaw).
constexpr int kDriftDof = 4;
struct DriftKnots {
  size_t spacing = 0;  // knots by frames: every `spacing` frames
  // Knots by path: frame i's knot (an index into the knots kept) and its weight on the next.
  // Only the knots a frame lies next to are kept: between two frames far apart along the path
  // the knots no frame touches would be held by the prior alone, and a random walk over g
  // spacings is one step with g times the variance, so leaving them out changes nothing but the
  // solver's damping, whose scale follows the system's size (`gap`: the spacings from each kept
  // knot to the next). The system grows with the frames, not with the path's length.
  std::vector<std::pair<size_t, double>> at;
  std::vector<double> gap;
  size_t count = 0;
  /// Knots every `spacing` frames.
  static DriftKnots byFrames(size_t n_frames, size_t spacing) {
    DriftKnots k;
    k.spacing = spacing;
    k.count = (n_frames - 1) / spacing + 2;
    return k;
  }
  /// Knots every `spacing_m` metres along the path through `sensors` (a frame at the same place
  /// as the one before lies at the same u).
  static DriftKnots byPath(const std::vector<Eigen::Vector3d>& sensors, double spacing_m) {
    DriftKnots k;
    std::vector<double> u(sensors.size(), 0.0);  // in spacings along the path, non-decreasing
    double path = 0.0;
    for (size_t i = 1; i < sensors.size(); ++i) {
      path += (sensors[i] - sensors[i - 1]).norm();
      u[i] = path / spacing_m;
    }
    // Knots floor(u) and floor(u) + 1 of every frame, numbered in path order.
    std::vector<double> kept;  // the kept knots' positions (whole spacings)
    for (double ui : u) {
      const double first = std::floor(ui);
      // Make first and first + 1 the last two kept knots (u does not decrease).
      if (kept.empty() || kept.back() < first) kept.push_back(first);  // after knots no frame touches
      if (kept.back() == first) kept.push_back(first + 1.0);
      const size_t index = kept.size() - 2;
      k.at.emplace_back(index, ui - kept[index]);
    }
    k.count = kept.size();
    for (size_t j = 0; j + 1 < kept.size(); ++j) k.gap.push_back(kept[j + 1] - kept[j]);
    return k;
  }
  /// Frame i's first knot and its weight on the second.
  std::pair<size_t, double> of(size_t i) const {
    if (spacing > 0) {
      const size_t k = i / spacing;
      return std::pair<size_t, double>{k, static_cast<double>(i - k * spacing) / static_cast<double>(spacing)};
    }
    return at[i];
  }
  /// Spacings between kept knots k and k + 1 (the prior's variance grows with it).
  double gapAfter(size_t k) const { return gap.empty() ? 1.0 : gap[k]; }
};

/// One Gauss-Newton step's normal equations over the knots, and how far the samples were pulled.
struct DriftSystem {
  Eigen::MatrixXd ata;
  Eigen::VectorXd atb;
  double shift = 0.0;
  size_t matched = 0;
};

/// The samples' rows of the normal equations, with every frame moved by `frame_params`.
DriftSystem driftRows(const std::vector<Eigen::Vector3d>& sensors, const std::vector<DriftSample>& samples,
                      const std::vector<Eigen::Vector4d>& frame_params, const DriftKnots& knots, bool use_points,
                      const KeyGrid& grid, const RegistrationTarget& target, const RegisterSettings& settings) {
  constexpr int kDof = kDriftDof;
  const int dim = static_cast<int>(knots.count) * kDof;
  const HitMap& surface = target.surface();
  DriftSystem sys;
  sys.ata = Eigen::MatrixXd::Zero(dim, dim);
  sys.atb = Eigen::VectorXd::Zero(dim);
  Eigen::MatrixXd& ata = sys.ata;
  Eigen::VectorXd& atb = sys.atb;
  for (const DriftSample& d : samples) {
    const Eigen::Vector4d& fp = frame_params[d.frame];
    const Eigen::Matrix3d r = Eigen::AngleAxisd(fp(3), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d arm = r * (d.point - sensors[d.frame]);
    const Eigen::Vector3d p = sensors[d.frame] + fp.head<3>() + arm;
    // Plain variables, not a structured binding: the lambda below captures them.
    const std::pair<size_t, double> knot = knots.of(d.frame);
    const size_t k = knot.first;
    const double w = knot.second;
    const Eigen::Index a = static_cast<Eigen::Index>(k) * kDof, b = a + kDof;
    const auto addRow = [&](const Eigen::Vector3d& n, double residual) {
      Eigen::Vector4d j;
      j << n, arm.x() * n.y() - arm.y() * n.x();  // d(p . n) / d yaw = (z x arm) . n
      if (settings.planar) j(2) = 0.0;  // no vertical offset: its unknowns stay 0
      const Eigen::Vector4d ja = (1.0 - w) * j, jb = w * j;
      ata.block<kDof, kDof>(a, a) += ja * ja.transpose();
      ata.block<kDof, kDof>(a, b) += ja * jb.transpose();
      ata.block<kDof, kDof>(b, a) += jb * ja.transpose();
      ata.block<kDof, kDof>(b, b) += jb * jb.transpose();
      atb.segment<kDof>(a) += ja * residual;
      atb.segment<kDof>(b) += jb * residual;
    };
    if (use_points) {
      // Point to plane against the points' surface, relative to the frame's own plane there;
      // no plane, no sample.
      const auto plane = pointPlaneNear(target.points(), grid, p, settings.radius_voxels);
      if (!plane) continue;
      ++sys.matched;
      const double residual = plane->normal.dot(plane->point - r * d.own_pull - p);
      addRow(plane->normal, residual);
      sys.shift += std::abs(residual);
      continue;
    }
    const auto q = centroidNear(surface, grid, p, settings.radius_voxels, true);
    if (!q) continue;
    // Where the frame's surface is a plane, the pull counts along its normal only (it says
    // how far the surface lies, not where along it the voxel belongs); elsewhere in full.
    // Voxels that already fit count too: they hold the frame where it is.
    const Eigen::Vector3d pull = *q - r * d.own_pull - p;
    ++sys.matched;
    if (d.normal.squaredNorm() > 0.0) {
      const Eigen::Vector3d n = r * d.normal;
      addRow(n, n.dot(pull));
      sys.shift += std::abs(n.dot(pull));
    } else {
      for (int c = 0; c < 3; ++c) addRow(Eigen::Vector3d::Unit(c), pull(c));
      sys.shift += pull.norm();
    }
  }
  return sys;
}

/// The prior on the totals x + step: lambda |x[k+1] + s[k+1] - x[k] - s[k]|^2.
void addDriftPrior(DriftSystem& sys, const Eigen::VectorXd& x, const double lambda[kDriftDof],
                   const DriftKnots& knots) {
  constexpr int kDof = kDriftDof;
  Eigen::MatrixXd& ata = sys.ata;
  Eigen::VectorXd& atb = sys.atb;
  for (size_t k = 0; k + 1 < knots.count; ++k) {
    const Eigen::Index a = static_cast<Eigen::Index>(k) * kDof, b = a + kDof;
    const double gap = knots.gapAfter(k);
    for (int c = 0; c < kDof; ++c) {
      const double l = lambda[c] / gap;  // gap 1 (always, by frames) divides exactly
      const double diff = x(b + c) - x(a + c);
      ata(a + c, a + c) += l;
      ata(b + c, b + c) += l;
      ata(a + c, b + c) -= l;
      ata(b + c, a + c) -= l;
      atb(a + c) += l * diff;
      atb(b + c) -= l * diff;
    }
  }
}

/// The drift of one session from its samples (driftSamplesOf(), in frame order) and its
/// `sensors` (one position per frame, as integrated): fitDrift() without the frames.
std::vector<Eigen::Isometry3d> solveDrift(const std::vector<Eigen::Vector3d>& sensors,
                                          const std::vector<DriftSample>& samples, bool use_points,
                                          const KeyGrid& grid, const RegistrationTarget& target,
                                          const RegisterSettings& settings, RegisterReport* report) {
  const size_t n_frames = sensors.size();
  std::vector<Eigen::Isometry3d> out(n_frames, Eigen::Isometry3d::Identity());
  RegisterReport rep;
  rep.points = samples.size();
  const bool by_path = settings.drift_knot_m > 0.0;
  const DriftKnots knots = by_path ? DriftKnots::byPath(sensors, settings.drift_knot_m)
                                   : DriftKnots::byFrames(n_frames, static_cast<size_t>(settings.drift_knot_frames));
  // The normal equations are solved dense: 4 unknowns a knot, so 2,048 knots hold 512 MiB.
  constexpr size_t kMaxPathKnots = 2048;
  if (by_path && knots.count > kMaxPathKnots) {
    throw UsageError("registration: drift knots every " + std::to_string(settings.drift_knot_m) + " m of path give " +
                     std::to_string(knots.count) + " knots for one session of " + std::to_string(n_frames) +
                     " frames (at most " + std::to_string(kMaxPathKnots) + "): give a larger spacing");
  }
  constexpr int kDof = kDriftDof;
  const int dim = static_cast<int>(knots.count) * kDof;
  // The prior: knot differences of a random walk over one spacing (`spacing` frames, or
  // drift_knot_m metres of path), against a pull noise of half a voxel (both in the
  // least-squares units of the data).
  const double noise = 0.5 * grid.resolution_m();
  const double spacing = by_path ? settings.drift_knot_m : static_cast<double>(settings.drift_knot_frames);
  const double step_m = by_path ? settings.drift_per_m : settings.drift_per_frame_m;
  const double yaw_step =
      (by_path ? settings.drift_yaw_per_m_deg : settings.drift_yaw_per_frame_deg) * std::numbers::pi / 180.0;
  const double lambda_t = noise * noise / (spacing * step_m * step_m);
  const double lambda_yaw = noise * noise / (spacing * yaw_step * yaw_step);
  const double lambda[kDof] = {lambda_t, lambda_t, lambda_t, lambda_yaw};
  Eigen::VectorXd x = Eigen::VectorXd::Zero(dim);
  // Frame i's offset and yaw: its two knots' values, linearly interpolated.
  const auto paramsOf = [&](size_t i) -> Eigen::Vector4d {
    const auto [k, w] = knots.of(i);
    return (1.0 - w) * x.segment<kDof>(static_cast<Eigen::Index>(k) * kDof) +
           w * x.segment<kDof>(static_cast<Eigen::Index>(k + 1) * kDof);
  };
  const HitMap& surface = target.surface();
  std::vector<Eigen::Vector4d> frame_params(n_frames);
  for (int it = 0; it < settings.max_iterations && !surface.empty() && !samples.empty(); ++it) {
    for (size_t i = 0; i < n_frames; ++i) frame_params[i] = paramsOf(i);
    DriftSystem sys = driftRows(sensors, samples, frame_params, knots, use_points, grid, target, settings);
    rep.matched = sys.matched;
    const double mean_shift = sys.matched ? sys.shift / static_cast<double>(sys.matched) : 0.0;
    if (it == 0) rep.mean_shift_before_m = mean_shift;
    rep.mean_shift_after_m = mean_shift;
    rep.iterations = it + 1;
    if (sys.matched < 3) break;
    addDriftPrior(sys, x, lambda, knots);
    Eigen::MatrixXd& ata = sys.ata;
    ata.diagonal().array() += 1e-6 * (ata.trace() / dim + 1.0);
    const Eigen::VectorXd step = ata.ldlt().solve(sys.atb);
    if (!step.allFinite()) break;
    x += step;
    double moved = 0.0;
    for (size_t k = 0; k < knots.count; ++k) {
      const Eigen::Index a = static_cast<Eigen::Index>(k) * kDof;
      moved = std::max(moved, step.segment<3>(a).norm() + std::abs(step(a + 3)));
    }
    if (moved < settings.min_step_m) break;
  }
  for (size_t i = 0; i < n_frames; ++i) {
    const Eigen::Vector4d fp = paramsOf(i);
    out[i].linear() = Eigen::AngleAxisd(fp(3), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    out[i].translation() = fp.head<3>();
  }
  if (report) *report = rep;
  return out;
}

}  // namespace

std::vector<Eigen::Isometry3d> fitDrift(const FrameSource& frames, const SessionMap& session,
                                        const RegistrationTarget& target, const RegisterSettings& settings,
                                        RegisterReport* report) {
  settings.validate();
  if (!settings.drift()) throw UsageError("registration: the drift knot spacing must be >= 1 frame or > 0 m of path");
  if (session.resolution_m() != target.resolution_m()) {
    throw UsageError("registration: the session and the consensus have different resolutions");
  }
  const size_t n_frames = frames.size();
  if (n_frames == 0) {
    if (report) *report = RegisterReport{};
    return {};
  }
  std::vector<DriftSample> samples;
  std::vector<Eigen::Vector3d> sensors(n_frames);
  DriftScratch scratch;
  const bool use_points = settings.drift_points && !target.points().empty();
  for (size_t i = 0; i < n_frames; ++i) {
    const Frame f = frames.load(i);
    sensors[i] = f.T_world_sensor.translation();
    driftSamplesOf(f, static_cast<uint32_t>(i), session.grid(), settings, use_points, scratch, samples);
  }
  return solveDrift(sensors, samples, use_points, session.grid(), target, settings, report);
}

namespace {

/// What the drift fit of one session needs from its frames (driftSamplesOf()).
struct SessionDriftInput {
  std::vector<Eigen::Vector3d> sensors;  ///< one per frame
  std::vector<DriftSample> samples;      ///< in frame order
};

/// One pass over every frame of every session (as corrected by `corrections`) for both the
/// target's point sums (RegistrationTarget::addPoints(), session after session: the same sums)
/// and each session's drift samples with points (what fitDrift() would take). Frames are read
/// and prepared in parallel, a batch at a time; their points are added to `target` in order.
/// @throw UsageError for missing frames, resolutions that differ or poses that are not finite;
/// whatever the frames' load throws.
std::vector<SessionDriftInput> pointsAndSamples(const std::vector<SessionMap>& sessions, const SessionFrames& frames,
                                                const std::vector<PoseCorrection>& corrections,
                                                RegistrationTarget& target, const RegisterSettings& settings) {
  std::vector<std::unique_ptr<FrameSource>> sources(sessions.size());
  std::vector<std::unique_ptr<CorrectedFrames>> corrected(sessions.size());
  std::vector<SessionDriftInput> inputs(sessions.size());
  std::vector<std::pair<uint32_t, uint32_t>> items;  // (session, frame), in the order of addPoints()
  for (size_t k = 0; k < sessions.size(); ++k) {
    sources[k] = frames(k);
    if (!sources[k]) throw UsageError("registration with drift: no frames for session " + std::to_string(k));
    if (sessions[k].resolution_m() != target.resolution_m()) {
      throw UsageError("registration: the session and the consensus have different resolutions");
    }
    corrected[k] = std::make_unique<CorrectedFrames>(*sources[k], corrections[k]);
    inputs[k].sensors.resize(sources[k]->size());
    for (size_t i = 0; i < sources[k]->size(); ++i) items.emplace_back(k, i);
  }
  struct Slot {
    std::vector<RegistrationTarget::KeyedPoint> points;
    std::vector<DriftSample> samples;
    Eigen::Vector3d sensor;
    DriftScratch scratch;
  };
  // A few frames per core in flight: each holds up to one point per pixel.
  constexpr size_t kBatch = 16;
  std::vector<Slot> slots(std::min(kBatch, items.size()));
  for (size_t begin = 0; begin < items.size(); begin += kBatch) {
    const size_t n = std::min(kBatch, items.size() - begin);
    parallelFor(n, 0, [&](size_t j) {
      const auto [k, i] = items[begin + j];
      Slot& slot = slots[j];
      const Frame f = corrected[k]->load(i);
      slot.sensor = f.T_world_sensor.translation();
      slot.samples.clear();
      keyPointsAndSamplesOf(f, i, target, settings, slot.scratch, slot.points, slot.samples);
    });
    for (size_t j = 0; j < n; ++j) {
      const auto [k, i] = items[begin + j];
      target.addKeyedPoints(slots[j].points);
      inputs[k].sensors[i] = slots[j].sensor;
      inputs[k].samples.insert(inputs[k].samples.end(), slots[j].samples.begin(), slots[j].samples.end());
    }
  }
  return inputs;
}

}  // namespace

std::vector<PoseCorrection> registerSessions(std::vector<SessionMap>& sessions, const Reintegrate& reintegrate,
                                             int rounds, const RegisterSettings& settings,
                                             std::vector<RegisterReport>* reports,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions,
                                             const SessionFrames& frames, const SessionMap* prior) {
  settings.validate();
  if (sessions.empty()) throw UsageError("registration of no sessions");
  if (prior && prior->resolution_m() != sessions.front().resolution_m()) {
    throw UsageError("registration: the prior consensus has another resolution than the sessions");
  }
  // Every round's consensus: the sessions as they are now, after the prior when there is one.
  const auto consensusNow = [&] {
    if (!prior) return consensus(std::span<const SessionMap>(sessions));
    std::vector<const SessionMap*> all{prior};
    for (const SessionMap& m : sessions) all.push_back(&m);
    return consensus(std::span<const SessionMap* const>(all));
  };
  const bool keep_mean = settings.keep_mean && !prior;
  if (rounds < 1 || rounds > 10) throw UsageError("registration: rounds must lie in [1, 10]");
  const bool per_pose = settings.model == CorrectionModel::PerPose;
  if (per_pose && sensor_positions.size() != sessions.size()) {
    throw UsageError("registration per pose needs the sensor positions of every session");
  }
  if (settings.drift() && !frames) {
    throw UsageError("registration with drift needs the frames of every session");
  }
  std::vector<PoseCorrection> corrections(sessions.size(),
                                          PoseCorrection{Eigen::Isometry3d::Identity(), settings.model, {}});
  if (reports) reports->assign(sessions.size(), {});
  for (int round = 0; round < rounds; ++round) {
    const RegistrationTarget target(consensusNow());
    std::vector<RegisterReport> found(sessions.size());
    std::vector<Eigen::Isometry3d> steps(sessions.size(), Eigen::Isometry3d::Identity());
    // Each session against the same target: independent, so in parallel (each writes its own slot).
    parallelFor(sessions.size(), 0, [&](size_t k) {
      std::vector<Eigen::Vector3d> positions;
      if (per_pose) {
        // Where the sensor was in the session as integrated last round.
        positions = sensor_positions[k];
        for (Eigen::Vector3d& c : positions) c += corrections[k].motion.translation();
      }
      steps[k] = registerToConsensus(sessions[k], target, settings, &found[k], positions);
    });
    if (keep_mean) removeCommonMotion(steps, settings.model);
    for (size_t k = 0; k < sessions.size(); ++k) {
      corrections[k] = corrections[k].then(PoseCorrection{steps[k], settings.model, {}});
    }
    if (reports) {
      for (size_t k = 0; k < sessions.size(); ++k) {
        const RegisterReport& r = found[k];
        if (round == 0) (*reports)[k].mean_shift_before_m = r.mean_shift_before_m;
        (*reports)[k].iterations += r.iterations;
        (*reports)[k].points = r.points;
        (*reports)[k].matched = r.matched;
        (*reports)[k].mean_shift_after_m = r.mean_shift_after_m;
      }
    }
    const bool last = round + 1 == rounds && !settings.drift();
    parallelFor(sessions.size(), 0, [&](size_t k) { sessions[k] = reintegrate(k, corrections[k], last); });
  }
  if (settings.drift()) {
    for (int round = 0; round < settings.drift_rounds; ++round) {
      RegisterSettings now = settings;
      if (round > 0 && settings.fine_radius_voxels > 0.0) now.radius_voxels = settings.fine_radius_voxels;
      RegistrationTarget target(consensusNow());
      std::vector<RegisterReport> found(sessions.size());
      std::vector<SessionDriftInput> inputs;
      if (settings.drift_points && prior) target.addMapPoints(*prior);
      if (settings.drift_points) inputs = pointsAndSamples(sessions, frames, corrections, target, now);
      // The samples were taken for the points' surface; without points they are the voxels'.
      const bool prepared = !inputs.empty() && !target.points().empty();
      std::vector<std::vector<Eigen::Isometry3d>> steps(sessions.size());
      // Each frame's sensor position as corrected so far (for keep_mean), gathered in the same pass.
      std::vector<std::vector<Eigen::Vector3d>> sensors(sessions.size());
      parallelFor(sessions.size(), 0, [&](size_t k) {
        std::vector<Eigen::Isometry3d>& per_frame = steps[k];
        if (prepared) {
          per_frame = inputs[k].sensors.empty() ? std::vector<Eigen::Isometry3d>{}
                                                : solveDrift(inputs[k].sensors, inputs[k].samples, true,
                                                             sessions[k].grid(), target, now, &found[k]);
          if (keep_mean) sensors[k] = std::move(inputs[k].sensors);
        } else {
          const std::unique_ptr<FrameSource> source = frames(k);
          if (!source) throw UsageError("registration with drift: no frames for session " + std::to_string(k));
          const CorrectedFrames corrected(*source, corrections[k]);
          per_frame = fitDrift(corrected, sessions[k], target, now, &found[k]);
          if (keep_mean) {
            sensors[k].reserve(per_frame.size());
            for (size_t i = 0; i < per_frame.size(); ++i) sensors[k].push_back(corrected.poseOf(i).translation());
          }
        }
      });
      if (keep_mean) removeCommonDrift(steps, sensors);
      for (size_t k = 0; k < sessions.size(); ++k) {
        PoseCorrection drift{Eigen::Isometry3d::Identity(), settings.model, std::move(steps[k])};
        corrections[k] = corrections[k].then(drift);
      }
      if (reports) {
        for (size_t k = 0; k < sessions.size(); ++k) {
          (*reports)[k].iterations += found[k].iterations;
          (*reports)[k].mean_shift_after_m = found[k].mean_shift_after_m;
        }
      }
      const bool last = round + 1 == settings.drift_rounds;
      parallelFor(sessions.size(), 0, [&](size_t k) { sessions[k] = reintegrate(k, corrections[k], last); });
    }
  }
  return corrections;
}

}  // namespace chronomap
