#include "chronomap/align/register.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <unordered_map>
#include <vector>

#include <Eigen/Cholesky>

#include "chronomap/align/consensus.h"
#include "chronomap/core/error.h"
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
}

namespace {

/// The small motion that best moves each point `a[i]` by its pull `b[i] - a[i]` along the
/// pull's own direction (point-to-plane least squares: a pull says how far the surface lies
/// along its normal, not where along the surface the point belongs), slightly damped: a
/// translation v and a rotation vector w, point i moving by v + w x (a[i] - pivot[i]). Yaw and
/// translation (w along z) or all six degrees of freedom.
Eigen::Matrix<double, 6, 1> fitStep(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                                    const std::vector<Eigen::Vector3d>& pivot, bool yaw_only) {
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
  const int dof = yaw_only ? 4 : 6;  // yaw only: translation and rotation about z (index 5)
  Eigen::MatrixXd m(dof, dof);
  Eigen::VectorXd v(dof);
  const int index[6] = {0, 1, 2, 5, 3, 4};
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

using HitMap = std::unordered_map<uint64_t, uint32_t>;

/// Occupied unit voxels of a map and their hits; their centres, in Morton order, go to `centres`
/// when given.
HitMap surfaceOf(const SessionMap& map, std::vector<Eigen::Vector3d>* centres = nullptr) {
  HitMap out;
  map.forEachLeaf([&](const LeafView& l) {
    if (l.level != 0 || l.counters.state() != VoxelState::Occupied) return;
    out.emplace(mortonEncode(l.key), l.counters.hits);
    if (centres) centres->push_back(map.grid().centerOf(l.key));
  });
  return out;
}

/// The centre of the voxels of `surface` around `p`, weighted by their hits and a Gaussian of
/// the distance (sigma half the radius; nothing beyond the radius), so that it moves smoothly
/// with `p`.
std::optional<Eigen::Vector3d> centroidNear(const HitMap& surface, const KeyGrid& grid, const Eigen::Vector3d& p,
                                            double radius_voxels) {
  const auto k = grid.keyOf(p);
  if (!k) return std::nullopt;
  const int r = static_cast<int>(std::ceil(radius_voxels));
  const double radius_m = radius_voxels * grid.resolution_m();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const auto n = offsetKey(*k, dx, dy, dz);
        if (!n) continue;
        const auto found = surface.find(mortonEncode(*n));
        if (found == surface.end()) continue;
        const Eigen::Vector3d c = grid.centerOf(*n);
        const double d2 = (c - p).squaredNorm();
        if (d2 > radius_m * radius_m) continue;
        const double w = static_cast<double>(found->second) * std::exp(-2.0 * d2 / (radius_m * radius_m));
        sum += w * c;
        weight += w;
      }
    }
  }
  if (weight <= 0.0) return std::nullopt;
  return sum / weight;
}

}  // namespace

RegistrationTarget::RegistrationTarget(const SessionMap& consensus)
    : grid_(consensus.grid()), surface_(surfaceOf(consensus)) {}

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
    const Eigen::Matrix<double, 6, 1> x = fitStep(from, to, pivot, settings.yaw_only);
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

std::vector<PoseCorrection> registerSessions(std::vector<SessionMap>& sessions, const Reintegrate& reintegrate,
                                             int rounds, const RegisterSettings& settings,
                                             std::vector<RegisterReport>* reports,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions) {
  settings.validate();
  if (sessions.empty()) throw UsageError("registration of no sessions");
  if (rounds < 1 || rounds > 10) throw UsageError("registration: rounds must lie in [1, 10]");
  const bool per_pose = settings.model == CorrectionModel::PerPose;
  if (per_pose && sensor_positions.size() != sessions.size()) {
    throw UsageError("registration per pose needs the sensor positions of every session");
  }
  std::vector<PoseCorrection> corrections(sessions.size(), PoseCorrection{Eigen::Isometry3d::Identity(), settings.model});
  if (reports) reports->assign(sessions.size(), {});
  for (int round = 0; round < rounds; ++round) {
    const RegistrationTarget target(consensus(std::span<const SessionMap>(sessions)));
    std::vector<RegisterReport> found(sessions.size());
    // Each session against the same target: independent, so in parallel (each writes its own slot).
    parallelFor(sessions.size(), 0, [&](size_t k) {
      std::vector<Eigen::Vector3d> positions;
      if (per_pose) {
        // Where the sensor was in the session as integrated last round.
        positions = sensor_positions[k];
        for (Eigen::Vector3d& c : positions) c += corrections[k].motion.translation();
      }
      const Eigen::Isometry3d t = registerToConsensus(sessions[k], target, settings, &found[k], positions);
      corrections[k] = corrections[k].then(PoseCorrection{t, settings.model});
    });
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
    parallelFor(sessions.size(), 0, [&](size_t k) { sessions[k] = reintegrate(k, corrections[k]); });
  }
  return corrections;
}

}  // namespace chronomap
