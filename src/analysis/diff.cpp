#include "chronomap/analysis/diff.h"

#include "chronomap/temporal/coverage.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <Eigen/Dense>

#include "chronomap/core/error.h"
#include "union_find.h"

namespace chronomap {

namespace {
constexpr int kMaxNeighbourhood = 4;
// The weak-change rule's "same surface": mean hit positions less than half a voxel apart.
constexpr double kKeptSurfaceOffset = 0.5;
}  // namespace

const char* toString(DiffMode mode) {
  switch (mode) {
    case DiffMode::Hard: return "hard";
    case DiffMode::Threshold: return "threshold";
    case DiffMode::Band: return "band";
    case DiffMode::Continuous: return "continuous";
  }
  return "?";
}

DiffMode parseDiffMode(const std::string& name) {
  for (DiffMode m : {DiffMode::Hard, DiffMode::Threshold, DiffMode::Band, DiffMode::Continuous}) {
    if (name == toString(m)) return m;
  }
  throw UsageError("unknown diff mode '" + name + "' (use hard, threshold, band or continuous)");
}

const char* toString(ChangeKind kind) {
  switch (kind) {
    case ChangeKind::Appeared: return "appeared";
    case ChangeKind::Vanished: return "vanished";
    case ChangeKind::Unchanged: return "unchanged";
  }
  return "?";
}

double DiffSettings::effectiveAlpha() const {
  if (alpha >= 0.0) return alpha;
  if (mode == DiffMode::Threshold) return kDefaultThresholdAlpha;
  if (mode == DiffMode::Band) return kDefaultBandAlpha;
  return 0.0;
}

void DiffSettings::validate() const {
  if (mode != DiffMode::Hard && mode != DiffMode::Threshold && mode != DiffMode::Band &&
      mode != DiffMode::Continuous) {
    throw UsageError("invalid diff mode " + std::to_string(static_cast<int>(mode)));
  }
  if (std::isnan(alpha)) throw UsageError("diff alpha must be a number");
  if (neighbourhood_voxels < 0 || neighbourhood_voxels > kMaxNeighbourhood) {
    throw UsageError("diff neighbourhood must lie in 0.." + std::to_string(kMaxNeighbourhood) + " voxels, got " +
                     std::to_string(neighbourhood_voxels));
  }
  if (!std::isfinite(min_shift_voxels) || min_shift_voxels < 0.0) {
    throw UsageError("diff min shift must be a number of voxels >= 0, got " + std::to_string(min_shift_voxels));
  }
  if (!(shift_plane_ratio >= 0.0 && shift_plane_ratio <= 1.0)) {
    throw UsageError("diff shift plane ratio must lie in [0, 1], got " + std::to_string(shift_plane_ratio));
  }
  if (kept_surface_radius_voxels < 0 || kept_surface_radius_voxels > kMaxNeighbourhood) {
    throw UsageError("diff kept-surface radius must lie in 0.." + std::to_string(kMaxNeighbourhood) +
                     " voxels, got " + std::to_string(kept_surface_radius_voxels));
  }
  if (!(kept_surface_share > 0.0 && kept_surface_share <= 1.0)) {
    throw UsageError("diff kept-surface share must lie in (0, 1], got " + std::to_string(kept_surface_share));
  }
  if (dark_surface_radius_voxels < 0 || dark_surface_radius_voxels > kMaxNeighbourhood) {
    throw UsageError("diff dark-surface radius must lie in 0.." + std::to_string(kMaxNeighbourhood) +
                     " voxels, got " + std::to_string(dark_surface_radius_voxels));
  }
  if (!(dark_surface_brightness >= 0.0 && dark_surface_brightness <= 255.0)) {
    throw UsageError("diff dark-surface brightness must lie in [0, 255], got " +
                     std::to_string(dark_surface_brightness));
  }
  if (!(dark_surface_share > 0.0 && dark_surface_share <= 1.0)) {
    throw UsageError("diff dark-surface share must lie in (0, 1], got " + std::to_string(dark_surface_share));
  }
  if (!(dark_surface_contrast > 0.0 && dark_surface_contrast <= 1.0)) {
    throw UsageError("diff dark-surface contrast must lie in (0, 1], got " + std::to_string(dark_surface_contrast));
  }
  const double a = effectiveAlpha();
  if (mode == DiffMode::Threshold && !(a < 1.0)) {
    throw UsageError("threshold alpha must lie in [0, 1), got " + std::to_string(a));
  }
  if (mode == DiffMode::Band && !(a < 0.5)) {
    throw UsageError("band alpha must lie in [0, 0.5), got " + std::to_string(a));
  }
}

namespace {

bool isKnown(const VoxelCounters& c) { return c.length_m > 0.0f || c.hits > 0; }

// Band mode's binning: the grey band around 0.5 reads as unknown.
VoxelState bandState(const VoxelCounters& c, double alpha) {
  if (!isKnown(c)) return VoxelState::Unknown;
  const double p = c.probability();
  if (p > 0.5 + alpha) return VoxelState::Occupied;
  if (p < 0.5 - alpha) return VoxelState::Free;
  return VoxelState::Unknown;
}

}  // namespace

std::optional<ChangeCell> compareVoxel(const VoxelCounters& before, const VoxelCounters& after,
                                       const DiffSettings& settings) {
  if (!isKnown(before) || !isKnown(after)) return std::nullopt;  // unknown is never a change
  const double p1 = before.probability(), p2 = after.probability();
  ChangeCell cell;
  cell.value = static_cast<float>(std::abs(p1 - p2));
  cell.kind = p2 > p1 ? ChangeKind::Appeared : ChangeKind::Vanished;
  switch (settings.mode) {
    case DiffMode::Hard: {
      const VoxelState s1 = before.state(), s2 = after.state();
      if (s1 == s2) return std::nullopt;
      cell.kind = s2 == VoxelState::Occupied ? ChangeKind::Appeared : ChangeKind::Vanished;
      break;
    }
    case DiffMode::Threshold:
      if (!(cell.value > settings.effectiveAlpha())) return std::nullopt;
      break;
    case DiffMode::Band: {
      const double a = settings.effectiveAlpha();
      const VoxelState s1 = bandState(before, a), s2 = bandState(after, a);
      if (s1 == VoxelState::Unknown || s2 == VoxelState::Unknown || s1 == s2) return std::nullopt;
      cell.kind = s2 == VoxelState::Occupied ? ChangeKind::Appeared : ChangeKind::Vanished;
      break;
    }
    case DiffMode::Continuous:
      if (p1 == p2) cell.kind = ChangeKind::Unchanged;
      break;
  }
  // The colour of the occupied side tells what the change was: the new surface, or the lost one.
  const VoxelCounters& first = cell.kind == ChangeKind::Vanished ? before : after;
  const VoxelCounters& second = cell.kind == ChangeKind::Vanished ? after : before;
  cell.colour = first.hits > 0 ? first.meanColour() : second.meanColour();
  return cell;
}

DiffMap::DiffMap(double resolution_m, DiffSettings settings) : grid_(resolution_m), settings_(settings) {
  settings_.validate();
}

DiffMap DiffMap::fromCells(double resolution_m, DiffSettings settings, std::vector<ChangeCell> cells) {
  DiffMap d(resolution_m, settings);
  std::sort(cells.begin(), cells.end(),
            [](const ChangeCell& a, const ChangeCell& b) { return mortonEncode(a.key) < mortonEncode(b.key); });
  uint64_t end = 0;
  for (const ChangeCell& c : cells) {
    if (c.level > kTreeDepth) throw FormatError("diff cell with an impossible level " + std::to_string(c.level));
    const uint64_t size = uint64_t{1} << (3 * c.level);
    const uint64_t code = mortonEncode(c.key);
    if (code % size != 0) throw FormatError("diff cell whose corner does not align with its level");
    if (code < end) throw FormatError("diff cells overlap");
    if (c.kind != ChangeKind::Appeared && c.kind != ChangeKind::Vanished && c.kind != ChangeKind::Unchanged) {
      throw FormatError("diff cell with an unknown kind " + std::to_string(static_cast<int>(c.kind)));
    }
    if (!std::isfinite(c.value) || c.value < 0.0f || c.value > 1.0f) throw FormatError("diff cell with an invalid value");
    end = code + size;
  }
  d.cells_ = std::move(cells);
  return d;
}

uint64_t DiffMap::voxelCount() const {
  uint64_t n = 0;
  for (const ChangeCell& c : cells_) n += uint64_t{1} << (3 * c.level);
  return n;
}

uint64_t DiffMap::voxelCount(ChangeKind kind) const {
  uint64_t n = 0;
  for (const ChangeCell& c : cells_) {
    if (c.kind == kind) n += uint64_t{1} << (3 * c.level);
  }
  return n;
}

bool operator==(const DiffMap& a, const DiffMap& b) {
  return a.resolution_m() == b.resolution_m() && a.settings_.mode == b.settings_.mode &&
         a.settings_.effectiveAlpha() == b.settings_.effectiveAlpha() && a.cells_ == b.cells_;
}

namespace {

// Walks two session maps together. A leaf on one side stands for its whole cube while the
// other side descends: a uniform cube's counters split evenly keep its probability and colour.
struct SessionWalk {
  const SessionMap& a;
  const SessionMap& b;
  const DiffSettings& settings;
  std::vector<ChangeCell>& out;

  using Ref = SessionMap::Ref;
  static bool isLeaf(Ref r) { return (r & SessionMap::kLeafBit) != 0; }

  void walk(Ref ra, Ref rb, int level, const VoxelKey& corner) {
    if (ra == SessionMap::kEmpty || rb == SessionMap::kEmpty) return;
    if (isLeaf(ra) && isLeaf(rb)) {
      const auto cell = compareVoxel(a.leaf(ra), b.leaf(rb), settings);
      if (cell) {
        out.push_back(*cell);
        out.back().key = corner;
        out.back().level = static_cast<uint8_t>(level);
      }
      return;
    }
    for (int slot = 0; slot < 8; ++slot) {
      const Ref ca = isLeaf(ra) ? ra : a.innerPool()[ra][slot];
      const Ref cb = isLeaf(rb) ? rb : b.innerPool()[rb][slot];
      walk(ca, cb, level - 1, childCorner(corner, slot, level - 1));
    }
  }
};

// The points lie along a line (a pole, an edge, a row of voxels) when their middle spread is under
// this share of the largest: no plane, so the whole move counts.
constexpr double kLineShare = 0.1;

// The mean position of the hits within r of `key` on each side (each at its voxel's centre plus
// the offset the voxel recorded for it), over the voxels known on both sides; their distance in
// voxels, or nothing when a side has no hits there. With plane_ratio > 0, only the part of that
// move along the normal of the plane the voxels with hits share, where they lie on one
// (DiffSettings::shift_plane_ratio). `before` and `after` give a voxel's counters (zero when
// unknown).
template <class CountersBefore, class CountersAfter>
std::optional<double> shiftInVoxels(const VoxelKey& key, int r, double plane_ratio, CountersBefore before,
                                    CountersAfter after) {
  // Per map: the hits' sum and count; for the plane, the voxels with hits (each at its hits' mean
  // position) with their sum and sum of squares.
  const bool plane_wanted = plane_ratio > 0.0;
  Eigen::Vector3d hit_sum[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  double hits[2] = {0.0, 0.0};
  Eigen::Vector3d point_sum[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  Eigen::Matrix3d point_squares[2] = {Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero()};
  int points[2] = {0, 0};
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const auto k = offsetKey(key, dx, dy, dz);
        if (!k) continue;
        const VoxelCounters side[2] = {before(*k), after(*k)};
        if (!isKnown(side[0]) || !isKnown(side[1])) continue;
        const Eigen::Vector3d offset(dx, dy, dz);
        for (int m = 0; m < 2; ++m) {
          const VoxelCounters& v = side[m];
          if (v.hits == 0) continue;
          // Each hit where it ended: the voxel's centre plus its offset from it.
          const Eigen::Vector3d ended(v.offset[0], v.offset[1], v.offset[2]);
          hit_sum[m] += v.hits * offset + ended;
          hits[m] += v.hits;
          if (!plane_wanted) continue;
          const Eigen::Vector3d p = offset + ended / v.hits;
          point_sum[m] += p;
          point_squares[m] += p * p.transpose();
          ++points[m];
        }
      }
    }
  }
  if (hits[0] == 0.0 || hits[1] == 0.0) return std::nullopt;
  const Eigen::Vector3d moved = hit_sum[1] / hits[1] - hit_sum[0] / hits[0];
  if (plane_wanted && points[0] >= 3 && points[1] >= 3) {
    // The spread of each map's points about its own mean, pooled: the surface's shape, without
    // the offset between the maps (which is the move being measured).
    Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
    for (int m = 0; m < 2; ++m) spread += point_squares[m] - point_sum[m] * point_sum[m].transpose() / points[m];
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> plane(spread / (points[0] + points[1]));
    // A plane: the least spread at most plane_ratio of the middle one, the points not along one
    // line (kLineShare). Only its move across itself counts.
    const Eigen::Vector3d spreads = plane.eigenvalues();
    if (spreads[1] > kLineShare * spreads[2] && spreads[0] <= plane_ratio * spreads[1]) {
      return std::abs(moved.dot(plane.eigenvectors().col(0)));
    }
  }
  return moved.norm();
}

// The neighbourhood rule (DiffSettings::neighbourhood_voxels, min_shift_voxels): drops appeared
// cells with an occupied voxel near them in the first map, and vanished cells with one near
// them in the second, unless the surface there moved by at least min_shift_voxels.
template <class CountersBefore, class CountersAfter>
void dropNearSurfaces(std::vector<ChangeCell>& cells, const DiffSettings& settings, CountersBefore before,
                      CountersAfter after) {
  const int r = settings.neighbourhood_voxels;
  if (r <= 0) return;
  auto occupiedNear = [r](const VoxelKey& k, auto&& counters) {
    return anyKeyWithin(k, r, [&](const VoxelKey& n) { return counters(n).state() == VoxelState::Occupied; });
  };
  auto moved = [&](const VoxelKey& k) {
    if (settings.min_shift_voxels <= 0.0) return false;
    const auto shift = shiftInVoxels(k, r, settings.shift_plane_ratio, before, after);
    return shift && *shift >= settings.min_shift_voxels;
  };
  std::erase_if(cells, [&](const ChangeCell& c) {
    if (c.level != 0) return false;
    if (c.kind == ChangeKind::Appeared) return occupiedNear(c.key, before) && !moved(c.key);
    if (c.kind == ChangeKind::Vanished) return occupiedNear(c.key, after) && !moved(c.key);
    return false;
  });
}

// The weak-change rule (DiffSettings::kept_surface_radius_voxels): drops an appeared cell when
// the first map's occupied voxels within the radius are (almost) all still occupied in the
// second map, and a vanished one when the second map's are all occupied in the first.
template <class CountersBefore, class CountersAfter>
void dropKeptSurfaces(std::vector<ChangeCell>& cells, const DiffSettings& settings, CountersBefore before,
                      CountersAfter after) {
  const int r = settings.kept_surface_radius_voxels;
  if (r <= 0) return;
  // `near` holds the surface around k; is it still there, as it was, in `other`?
  auto kept = [&](const VoxelKey& k, auto&& near, auto&& other) {
    int surface = 0, still = 0;
    forEachKeyInCube(k, r, [&](const VoxelKey& n) {
      const VoxelCounters was = near(n);
      if (was.state() != VoxelState::Occupied) return;
      ++surface;
      const VoxelCounters is = other(n);
      if (is.state() != VoxelState::Occupied) return;
      // Where in the voxel the rays ended: a surface moved by a fraction of a voxel (a chair
      // pushed by 4 cm) is not the same surface.
      double d2 = 0.0;
      for (int i = 0; i < 3; ++i) {
        const double d = is.meanOffset(i) - was.meanOffset(i);
        d2 += d * d;
      }
      still += d2 < kKeptSurfaceOffset * kKeptSurfaceOffset;
    });
    return surface > 0 && still >= settings.kept_surface_share * surface;
  };
  std::erase_if(cells, [&](const ChangeCell& c) {
    if (c.level != 0) return false;
    if (c.kind == ChangeKind::Appeared) return kept(c.key, before, after);
    if (c.kind == ChangeKind::Vanished) return kept(c.key, after, before);
    return false;
  });
}

bool hasColour(const VoxelCounters& c) { return c.red != 0 || c.green != 0 || c.blue != 0; }

// The dark-surface rule (DiffSettings::dark_surface_radius_voxels), by object: the unit cells
// of one kind that touch (26-neighbourhood, as vertex connectivity) form an object; an object is
// dropped when every one of its voxels has an occupied voxel of the other map within the radius
// (a layer along a surface the other map sees) and at least dark_surface_share of them are dark
// and darker than the other map's surface around them. An appeared cell's own surface is the
// second map's, a vanished cell's the first map's.
template <class CountersBefore, class CountersAfter>
void dropDarkSurfaces(std::vector<ChangeCell>& cells, const DiffSettings& settings, CountersBefore before,
                      CountersAfter after) {
  const int r = settings.dark_surface_radius_voxels;
  if (r <= 0) return;
  // Is the surface `own` holds at k dark? All-zero colour sums are black only where the map
  // holds colour around k; a map integrated without colour has none anywhere.
  auto dark = [&](const VoxelKey& k, auto&& own) {
    const VoxelCounters c = own(k);
    if (c.hits == 0) return false;
    const double brightness = (static_cast<double>(c.red) + c.green + c.blue) / (3.0 * c.hits);
    if (!(brightness < settings.dark_surface_brightness)) return false;
    return hasColour(c) || anyKeyWithin(k, r, [&](const VoxelKey& n) { return hasColour(own(n)); });
  };
  // ... and darker than the surface the other map sees around it: that view returned little
  // light. A dark object seen as dark by both maps (moved under the same light) keeps its cells.
  auto darker = [&](const VoxelKey& k, auto&& own, auto&& other) {
    const VoxelCounters c = own(k);
    double sum = 0.0, hits = 0.0;
    forEachKeyInCube(k, r, [&](const VoxelKey& n) {
      const VoxelCounters o = other(n);
      if (o.state() != VoxelState::Occupied || !hasColour(o)) return;
      sum += (static_cast<double>(o.red) + o.green + o.blue) / 3.0;
      hits += o.hits;
    });
    const double brightness = (static_cast<double>(c.red) + c.green + c.blue) / (3.0 * c.hits);
    return hits > 0.0 && brightness < settings.dark_surface_contrast * (sum / hits);
  };
  auto occupiedNear = [r](const VoxelKey& k, auto&& counters) {
    return anyKeyWithin(k, r, [&](const VoxelKey& n) { return counters(n).state() == VoxelState::Occupied; });
  };
  // The unit cells that may be dropped, and their objects.
  std::vector<uint32_t> unit;  // indices into cells
  std::unordered_map<uint64_t, uint32_t> index_of;  // Morton code -> position in `unit`
  for (size_t i = 0; i < cells.size(); ++i) {
    const ChangeCell& c = cells[i];
    if (c.level != 0 || (c.kind != ChangeKind::Appeared && c.kind != ChangeKind::Vanished)) continue;
    index_of.emplace(mortonEncode(c.key), static_cast<uint32_t>(unit.size()));
    unit.push_back(static_cast<uint32_t>(i));
  }
  if (unit.empty()) return;
  UnionFind objects(unit.size());
  std::vector<uint8_t> is_dark(unit.size(), 0);
  for (size_t u = 0; u < unit.size(); ++u) {
    const ChangeCell& c = cells[unit[u]];
    forEachLaterNeighbour(c.key, [&](const VoxelKey& k) {  // each touching pair once
      const auto it = index_of.find(mortonEncode(k));
      if (it != index_of.end() && cells[unit[it->second]].kind == c.kind) {
        objects.join(static_cast<uint32_t>(u), it->second);
      }
    });
    is_dark[u] = c.kind == ChangeKind::Appeared ? dark(c.key, after) && darker(c.key, after, before)
                                                : dark(c.key, before) && darker(c.key, before, after);
  }
  std::vector<uint32_t> size(unit.size(), 0), dark_count(unit.size(), 0);
  for (size_t u = 0; u < unit.size(); ++u) {
    const uint32_t root = objects.find(static_cast<uint32_t>(u));
    ++size[root];
    dark_count[root] += is_dark[u];
  }
  // 0: not decided, 1: dropped, 2: kept.
  std::vector<uint8_t> verdict(unit.size(), 0);
  for (size_t u = 0; u < unit.size(); ++u) {
    const uint32_t root = objects.find(static_cast<uint32_t>(u));
    if (static_cast<double>(dark_count[root]) < settings.dark_surface_share * size[root]) verdict[root] = 2;
  }
  // Dark enough: is every voxel within the radius of a surface the other map sees?
  for (size_t u = 0; u < unit.size(); ++u) {
    const uint32_t root = objects.find(static_cast<uint32_t>(u));
    if (verdict[root] == 2) continue;
    const ChangeCell& c = cells[unit[u]];
    const bool near = c.kind == ChangeKind::Appeared ? occupiedNear(c.key, before) : occupiedNear(c.key, after);
    if (!near) verdict[root] = 2;
  }
  std::vector<uint8_t> drop(cells.size(), 0);
  for (size_t u = 0; u < unit.size(); ++u) drop[unit[u]] = verdict[objects.find(static_cast<uint32_t>(u))] != 2;
  size_t out = 0;
  for (size_t i = 0; i < cells.size(); ++i) {
    if (!drop[i]) cells[out++] = cells[i];
  }
  cells.resize(out);
}

// The rules that read the voxels around each cell, in order: the neighbourhood rule, the
// weak-change rule, then the dark-surface rule. Continuous mode keeps every cell.
template <class CountersBefore, class CountersAfter>
void applyRules(std::vector<ChangeCell>& cells, const DiffSettings& settings, CountersBefore before,
                CountersAfter after) {
  if (settings.mode == DiffMode::Continuous) return;
  dropNearSurfaces(cells, settings, before, after);
  dropKeptSurfaces(cells, settings, before, after);
  dropDarkSurfaces(cells, settings, before, after);
}

auto countersOf(const SessionMap& m) {
  return [&m](const VoxelKey& k) { return m.find(k).value_or(VoxelCounters{}); };
}

}  // namespace

void applyNeighbourhoodRule(std::vector<ChangeCell>& cells, const DiffSettings& settings,
                            const std::function<VoxelCounters(const VoxelKey&)>& before,
                            const std::function<VoxelCounters(const VoxelKey&)>& after) {
  applyRules(cells, settings, before, after);
}

DiffMap diff(const SessionMap& before, const SessionMap& after, const DiffSettings& settings) {
  if (before.resolution_m() != after.resolution_m()) {
    throw UsageError("cannot compare maps of different resolutions (" + std::to_string(before.resolution_m()) +
                     " m and " + std::to_string(after.resolution_m()) + " m)");
  }
  DiffMap d(before.resolution_m(), settings);
  SessionWalk w{before, after, settings, d.cells_};
  w.walk(0, 0, kTreeDepth, VoxelKey{});  // inner node 0 is the root of both
  applyRules(d.cells_, settings, countersOf(before), countersOf(after));
  return d;
}

DiffMap diff(const TemporalMap& map, double t1_s, double t2_s, const DiffSettings& settings, DiffStats* stats) {
  if (!std::isfinite(t1_s) || !std::isfinite(t2_s)) throw UsageError("diff times must be finite");
  DiffMap d(map.resolution_m(), settings);
  const auto r1 = map.rankAtOrBefore(t1_s), r2 = map.rankAtOrBefore(t2_s);
  // With seen_at_both: what the two sessions in effect observed (none: nothing was).
  std::optional<CoverageIndex> seen1, seen2;
  if (settings.seen_at_both) {
    seen1.emplace(r1 ? map.sessions()[*r1].coverage : Coverage{});
    seen2.emplace(r2 ? map.sessions()[*r2].coverage : Coverage{});
  }
  auto seen = [](const std::optional<CoverageIndex>& c, const VoxelKey& k, int level) {
    return !c || c->overlap(k, level) == CoverageIndex::Overlap::Full;
  };
  // Entry valid at rank r (none before the list's first entry, or before any session). The
  // search gallops back from the newest entry, so its cost follows how far back in the list the
  // time lies, not how long the history is: a diff of recent times stays as fast as the map grows.
  auto valueAt = [](std::span<const TemporalMap::Entry> e, std::optional<uint32_t> r) -> VoxelCounters {
    if (!r) return {};
    size_t lo = 0, hi = e.size();  // first entry with session > r lies in [lo, hi]
    for (size_t step = 1; hi > 0; step *= 2) {
      const size_t probe = hi > step ? hi - step : 0;
      if (e[probe].session <= *r) {
        lo = probe + 1;
        break;
      }
      hi = probe;
    }
    while (lo < hi) {
      const size_t mid = (lo + hi) / 2;
      if (e[mid].session <= *r) {
        lo = mid + 1;
      } else {
        hi = mid;
      }
    }
    return lo == 0 ? VoxelCounters{} : e[lo - 1].value;
  };
  DiffStats local;
  auto compare = [&](const VoxelKey& k, int level, std::span<const TemporalMap::Entry> e) {
    ++local.lists_compared;
    const VoxelCounters none{};
    auto cell = compareVoxel(seen(seen1, k, level) ? valueAt(e, r1) : none,
                             seen(seen2, k, level) ? valueAt(e, r2) : none, settings);
    if (!cell) return;
    cell->key = k;
    cell->level = static_cast<uint8_t>(level);
    d.cells_.push_back(*cell);
  };
  if (settings.mode == DiffMode::Continuous) {
    map.forEachList(compare);  // unchanged voxels are part of the answer: every list counts
  } else {
    // Only lists with a change by a session in (min rank, max rank] can differ.
    const uint32_t n1 = map.ranksThrough(t1_s), n2 = map.ranksThrough(t2_s);
    const uint32_t lo = std::min(n1, n2), hi = std::max(n1, n2);
    local.inner_nodes_visited = map.forEachListChangedIn(lo, hi, compare);
  }
  auto countersAt = [&map, &seen](double t, const std::optional<CoverageIndex>& c) {
    return [&map, &seen, &c, t](const VoxelKey& k) {
      return seen(c, k, 0) ? map.valueAt(k, t).value_or(VoxelCounters{}) : VoxelCounters{};
    };
  };
  applyRules(d.cells_, settings, countersAt(t1_s, seen1), countersAt(t2_s, seen2));
  // Both walks visit lists in slot order, which is Morton order: the cells are sorted already.
  if (stats) *stats = local;
  return d;
}

std::optional<double> surfaceShift(const SessionMap& before, const SessionMap& after, const VoxelKey& key,
                                   int radius_voxels, double plane_ratio) {
  if (before.resolution_m() != after.resolution_m()) throw UsageError("cannot compare maps of different resolutions");
  if (radius_voxels < 0 || radius_voxels > kMaxNeighbourhood) {
    throw UsageError("surface shift radius must lie in 0.." + std::to_string(kMaxNeighbourhood) + " voxels");
  }
  if (!(plane_ratio >= 0.0 && plane_ratio <= 1.0)) {
    throw UsageError("surface shift plane ratio must lie in [0, 1], got " + std::to_string(plane_ratio));
  }
  return shiftInVoxels(key, radius_voxels, plane_ratio, countersOf(before), countersOf(after));
}

}  // namespace chronomap
