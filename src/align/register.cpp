#include "chronomap/align/register.h"

#include <algorithm>
#include <cmath>
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
}

namespace {

/// The small rigid motion that best moves each point `a[i]` by its pull `b[i] - a[i]` along the
/// pull's own direction (point-to-plane least squares: a pull says how far the surface lies
/// along its normal, not where along the surface the point belongs), yaw and translation or
/// all six degrees of freedom, slightly damped.
Eigen::Isometry3d fitRigid(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b, bool yaw_only) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : a) centre += p;
  centre /= static_cast<double>(a.size());
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector3d pull = b[i] - a[i];
    const double r = pull.norm();
    if (r < 1e-9) continue;
    const Eigen::Vector3d n = pull / r;
    Eigen::Matrix<double, 6, 1> j;
    j << n, (a[i] - centre).cross(n);
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
  const Eigen::Vector3d omega = step.tail<3>();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  if (omega.norm() > 0.0) t.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
  t.translation() = centre + step.head<3>() - t.linear() * centre;
  return t;
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
                                      const RegisterSettings& settings, RegisterReport* report) {
  settings.validate();
  if (session.resolution_m() != consensus.resolution_m()) {
    throw UsageError("registration: the session and the consensus have different resolutions");
  }
  return registerToConsensus(session, RegistrationTarget(consensus), settings, report);
}

Eigen::Isometry3d registerToConsensus(const SessionMap& session, const RegistrationTarget& target,
                                      const RegisterSettings& settings, RegisterReport* report) {
  settings.validate();
  if (session.resolution_m() != target.resolution_m()) {
    throw UsageError("registration: the session and the consensus have different resolutions");
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
  RegisterReport rep;
  rep.points = points.size();
  Eigen::Isometry3d total = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> from, to;
  for (int it = 0; it < settings.max_iterations && !surface.empty(); ++it) {
    from.clear();
    to.clear();
    double shift = 0.0;
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d p = total * points[i];
      const auto q = centroidNear(surface, grid, p, settings.radius_voxels);
      if (!q) continue;
      from.push_back(p);
      to.push_back(*q - total.linear() * own_pull[i]);
      shift += (to.back() - p).norm();
    }
    rep.matched = from.size();
    const double mean_shift = from.empty() ? 0.0 : shift / static_cast<double>(from.size());
    if (it == 0) rep.mean_shift_before_m = mean_shift;
    rep.mean_shift_after_m = mean_shift;
    rep.iterations = it + 1;
    if (from.size() < 3) break;
    const Eigen::Isometry3d step = fitRigid(from, to, settings.yaw_only);
    total = step * total;
    const double moved = step.translation().norm() + Eigen::AngleAxisd(step.linear()).angle() * 1.0;
    if (moved < settings.min_step_m) break;
  }
  if (report) *report = rep;
  return total;
}

std::vector<Eigen::Isometry3d> registerSessions(std::vector<SessionMap>& sessions, const Reintegrate& reintegrate,
                                                int rounds, const RegisterSettings& settings,
                                                std::vector<RegisterReport>* reports) {
  settings.validate();
  if (sessions.empty()) throw UsageError("registration of no sessions");
  if (rounds < 1 || rounds > 10) throw UsageError("registration: rounds must lie in [1, 10]");
  std::vector<Eigen::Isometry3d> corrections(sessions.size(), Eigen::Isometry3d::Identity());
  if (reports) reports->assign(sessions.size(), {});
  for (int round = 0; round < rounds; ++round) {
    const RegistrationTarget target(consensus(std::span<const SessionMap>(sessions)));
    std::vector<RegisterReport> found(sessions.size());
    // Each session against the same target: independent, so in parallel (each writes its own slot).
    parallelFor(sessions.size(), 0, [&](size_t k) {
      corrections[k] = registerToConsensus(sessions[k], target, settings, &found[k]) * corrections[k];
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
