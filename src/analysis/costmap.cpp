#include "chronomap/analysis/costmap.h"

#include <algorithm>
#include <cmath>
#include <queue>
#include <limits>

#include "chronomap/core/error.h"
#include "distance_transform.h"

namespace chronomap {

std::optional<Eigen::Vector2i> Costmap::cellOf(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d f = (p - origin_m) / resolution_m;
  if (!(f.x() >= 0.0 && f.y() >= 0.0 && f.x() < width && f.y() < height)) return std::nullopt;
  return Eigen::Vector2i(static_cast<int>(f.x()), static_cast<int>(f.y()));
}

Eigen::Vector2d Costmap::centerOf(const Eigen::Vector2i& c) const {
  return origin_m + resolution_m * (c.cast<double>() + Eigen::Vector2d::Constant(0.5));
}

Costmap costmap(const SessionMap& map, const CostmapSettings& s, const RhythmModels* models) {
  if (!(s.z_max_m > s.z_min_m) || !std::isfinite(s.z_min_m) || !std::isfinite(s.z_max_m)) {
    throw UsageError("the height band must have --z-max above --z-min");
  }
  if (!(s.robot_radius_m >= 0.0) || !std::isfinite(s.robot_radius_m)) throw UsageError("the robot radius must be >= 0");
  if (!(s.change_weight >= 0.0 && s.change_weight <= 1.0)) throw UsageError("the change weight must lie in [0, 1]");
  if (!(s.lethal_probability > 0.0 && s.lethal_probability < 1.0)) {
    throw UsageError("the lethal probability must lie in (0, 1)");
  }
  const KeyGrid& grid = map.grid();
  const double r = map.resolution_m();
  // The band in keys: voxels whose z range meets [z_min, z_max].
  auto inBand = [&](const VoxelKey& corner, int level) {
    const double z0 = grid.cornerOf(corner).z(), z1 = z0 + r * static_cast<double>(1 << level);
    return z1 > s.z_min_m && z0 < s.z_max_m;
  };
  int kx0 = 1 << 30, ky0 = 1 << 30, kx1 = -1, ky1 = -1;
  map.forEachLeaf([&](const LeafView& leaf) {
    if (!inBand(leaf.key, leaf.level)) return;
    const int size = 1 << leaf.level;
    kx0 = std::min(kx0, static_cast<int>(leaf.key.x));
    ky0 = std::min(ky0, static_cast<int>(leaf.key.y));
    kx1 = std::max(kx1, static_cast<int>(leaf.key.x) + size);
    ky1 = std::max(ky1, static_cast<int>(leaf.key.y) + size);
  });
  Costmap out;
  out.resolution_m = r;
  if (kx1 < 0) return out;  // nothing known in the band
  out.width = kx1 - kx0;
  out.height = ky1 - ky0;
  out.origin_m = grid.cornerOf(VoxelKey{static_cast<uint16_t>(kx0), static_cast<uint16_t>(ky0), 0}).head<2>();
  const size_t cells = static_cast<size_t>(out.width) * static_cast<size_t>(out.height);
  std::vector<uint8_t> known(cells, 0);
  std::vector<float> probability(cells, 0.0f), change(cells, 0.0f);
  auto index = [&](int kx, int ky) { return static_cast<size_t>(ky - ky0) * static_cast<size_t>(out.width) + static_cast<size_t>(kx - kx0); };
  const auto lethal = static_cast<float>(s.lethal_probability);
  // A modelled voxel seen occupied in fewer learning sessions than min_occupied_sessions: not
  // enough evidence for an obstacle.
  auto stray = [&](const LeafView& leaf) {
    if (!models || s.min_occupied_sessions <= 1) return false;
    const VoxelRhythm* v = models->find(leaf.key);
    return v && std::lround(static_cast<double>(v->mean) * v->observations) < static_cast<long>(s.min_occupied_sessions);
  };
  map.forEachLeaf([&](const LeafView& leaf) {
    if (!inBand(leaf.key, leaf.level)) return;
    const int size = 1 << leaf.level;
    auto p = static_cast<float>(leaf.counters.probability());
    if (p > lethal && stray(leaf)) p = lethal;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        const size_t i = index(leaf.key.x + x, leaf.key.y + y);
        known[i] = 1;
        probability[i] = std::max(probability[i], p);
      }
    }
  });
  if (models) {
    for (const VoxelRhythm& v : models->voxels) {
      if (!inBand(v.corner, v.level)) continue;
      // The chance that two observations differ, 2m(1 - m), scaled to 1 at m = 0.5.
      const float share = 4.0f * v.mean * (1.0f - v.mean);
      const int size = 1 << v.level;
      for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
          const int kx = v.corner.x + x, ky = v.corner.y + y;
          if (kx < kx0 || kx >= kx1 || ky < ky0 || ky >= ky1) continue;
          change[index(kx, ky)] = std::max(change[index(kx, ky)], share);
        }
      }
    }
  }
  out.cost.assign(cells, Costmap::kUnknown);
  for (size_t i = 0; i < cells; ++i) {
    if (!known[i]) continue;
    if (probability[i] > lethal) {
      out.cost[i] = Costmap::kLethal;
      continue;
    }
    const double c = (1.0 - s.change_weight) * (probability[i] / lethal) + s.change_weight * change[i];
    out.cost[i] = static_cast<int8_t>(std::lround(98.0 * std::clamp(c, 0.0, 1.0)));
  }
  inflate(out, s.robot_radius_m);
  return out;
}

void inflate(Costmap& m, double radius_m) {
  // The nearest lethal cell decides whether a cell is inscribed, so one exact distance transform,
  // linear in the grid whatever the radius, answers for every cell. (Stamping a disk of offsets
  // around each lethal cell grew with the radius's square: 4e8 offsets, 3.2 GB, for --robot-radius
  // 100 at 0.01 m.) The comparison is the disk's, term for term, so that results stay as they were.
  if (m.cost.empty()) return;
  const double r = m.resolution_m;
  const double limit = radius_m * radius_m + 1e-12;
  std::vector<uint8_t> lethal(m.cost.size());
  for (size_t i = 0; i < m.cost.size(); ++i) lethal[i] = m.cost[i] == Costmap::kLethal;
  analysis_detail::forEachSquaredDistance(lethal, m.width, m.height, [&](int j, const int64_t* d2) {
    for (int i = 0; i < m.width; ++i) {
      const int64_t d = d2[i];
      if (d == 0 || d == analysis_detail::kNoSource || static_cast<double>(d) * r * r > limit) continue;
      m.at(i, j) = Costmap::kInscribed;
    }
  });
}

std::optional<std::vector<Eigen::Vector2i>> planPath(const Costmap& m, const Eigen::Vector2i& start,
                                                     const Eigen::Vector2i& goal) {
  auto inside = [&](const Eigen::Vector2i& c) { return c.x() >= 0 && c.y() >= 0 && c.x() < m.width && c.y() < m.height; };
  if (!inside(start) || !inside(goal)) return std::nullopt;
  auto passable = [&](const Eigen::Vector2i& c) {
    const int8_t v = m.at(c.x(), c.y());
    return v >= 0 && v < Costmap::kInscribed;
  };
  if (!passable(goal)) return std::nullopt;
  const auto w = static_cast<size_t>(m.width);
  auto id = [&](const Eigen::Vector2i& c) { return static_cast<size_t>(c.y()) * w + static_cast<size_t>(c.x()); };
  auto heuristic = [&](const Eigen::Vector2i& c) {  // octile distance: each step costs at least its length
    const double dx = std::abs(c.x() - goal.x()), dy = std::abs(c.y() - goal.y());
    return std::max(dx, dy) + (std::sqrt(2.0) - 1.0) * std::min(dx, dy);
  };
  std::vector<double> g(m.cost.size(), std::numeric_limits<double>::infinity());
  std::vector<int64_t> parent(m.cost.size(), -1);
  using Item = std::pair<double, size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  g[id(start)] = 0.0;
  open.emplace(heuristic(start), id(start));
  while (!open.empty()) {
    const auto [f, current] = open.top();
    open.pop();
    const Eigen::Vector2i c(static_cast<int>(current % w), static_cast<int>(current / w));
    if (f > g[current] + heuristic(c) + 1e-9) continue;  // a stale entry
    if (c == goal) break;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if (!dx && !dy) continue;
        const Eigen::Vector2i n(c.x() + dx, c.y() + dy);
        if (!inside(n) || !passable(n)) continue;
        const double step = (dx && dy ? std::sqrt(2.0) : 1.0) * (1.0 + m.at(n.x(), n.y()) / 25.0);
        if (g[current] + step < g[id(n)]) {
          g[id(n)] = g[current] + step;
          parent[id(n)] = static_cast<int64_t>(current);
          open.emplace(g[id(n)] + heuristic(n), id(n));
        }
      }
    }
  }
  if (!std::isfinite(g[id(goal)])) return std::nullopt;
  std::vector<Eigen::Vector2i> path;
  for (int64_t at = static_cast<int64_t>(id(goal)); at >= 0; at = parent[static_cast<size_t>(at)]) {
    path.emplace_back(static_cast<int>(static_cast<size_t>(at) % w), static_cast<int>(static_cast<size_t>(at) / w));
  }
  std::reverse(path.begin(), path.end());
  return path;
}

}  // namespace chronomap
