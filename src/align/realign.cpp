#include "chronomap/align/realign.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>

#include "chronomap/core/error.h"

namespace chronomap {

void RealignSettings::validate() const {
  auto finite_in = [](double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; };
  if (!finite_in(alpha, 0.0, 1e300)) throw UsageError("re-alignment: alpha must be a finite number >= 0");
  if (!finite_in(weight_distance, 0.0, 10.0) || !finite_in(weight_colour, 0.0, 10.0) ||
      !finite_in(weight_probability, 0.0, 10.0)) {
    throw UsageError("re-alignment: the weights must lie in [0, 10]");
  }
  if (!finite_in(max_distance_voxels, 0.0, 8.0)) {
    throw UsageError("re-alignment: the largest move (d_max) must lie in [0, 8] voxels");
  }
  if (!finite_in(epsilon, 1e-6, 1.0)) throw UsageError("re-alignment: epsilon must lie in [1e-6, 1]");
  if (!finite_in(consensus_occupied_above, 0.5, 1.0) || consensus_occupied_above >= 1.0) {
    throw UsageError("re-alignment: the consensus probability threshold must lie in [0.5, 1)");
  }
}

double realignScore(double distance_voxels, double colour_distance, double probability_difference,
                    const RealignSettings& s) {
  auto term = [&](double x, double weight) { return std::pow(std::max(x, s.epsilon), weight); };
  return 1.0 / (term(distance_voxels, s.weight_distance) * term(colour_distance, s.weight_colour) *
                term(probability_difference, s.weight_probability));
}

double colourDistance(const Rgb& a, const Rgb& b) {
  const double dr = (double(a.r) - double(b.r)) / 255.0;
  const double dg = (double(a.g) - double(b.g)) / 255.0;
  const double db = (double(a.b) - double(b.b)) / 255.0;
  return std::sqrt(dr * dr + dg * dg + db * db);
}

double realignScore(const VoxelCounters& moved, const VoxelCounters& consensus_there, double distance_voxels,
                    const RealignSettings& s) {
  return realignScore(distance_voxels, colourDistance(moved.meanColour(), consensus_there.meanColour()),
                      std::abs(moved.probability() - consensus_there.probability()), s);
}

namespace {

struct Offset {
  int dx, dy, dz;
  double distance;
};

std::vector<Offset> offsetsWithin(double d_max) {
  std::vector<Offset> out;
  const int r = static_cast<int>(std::floor(d_max));
  for (int dz = -r; dz <= r; ++dz) {
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const int sq = dx * dx + dy * dy + dz * dz;
        const double d = std::sqrt(static_cast<double>(sq));
        if (sq > 0 && d <= d_max) out.push_back({dx, dy, dz, d});
      }
    }
  }
  return out;
}

/// Voxels of one role (the session's occupied voxels; the consensus' occupied voxels where the
/// session is not occupied) in Morton order, with an index by Morton code.
struct VoxelSet {
  std::vector<VoxelKey> keys;
  std::vector<VoxelCounters> values;  // the counters that the score reads
  std::vector<uint8_t> used;
  std::unordered_map<uint64_t, uint32_t> index;

  void add(const VoxelKey& k, const VoxelCounters& v) {
    keys.push_back(k);
    values.push_back(v);
  }
  void finish() {
    used.assign(keys.size(), 0);
    index.reserve(keys.size() * 2);
    for (uint32_t i = 0; i < keys.size(); ++i) index.emplace(mortonEncode(keys[i]), i);
  }
  void markUsed(const VoxelKey& k) {
    const auto it = index.find(mortonEncode(k));
    if (it != index.end()) used[it->second] = 1;
  }
  std::optional<uint32_t> find(const VoxelKey& k) const {
    const auto it = index.find(mortonEncode(k));
    if (it == index.end() || used[it->second]) return std::nullopt;
    return it->second;
  }
};

}  // namespace

SessionMap realign(const SessionMap& session, const SessionMap& consensus, const RealignSettings& settings,
                   RealignReport* report) {
  settings.validate();
  if (session.resolution_m() != consensus.resolution_m()) {
    throw UsageError("re-alignment: the session and the consensus have different resolutions");
  }
  RealignReport rep;
  // The session's occupied voxels: sources of moves (compressed leaves are never occupied).
  VoxelSet occupied;
  std::vector<uint8_t> occupied_disagrees;  // the consensus is known and not occupied there
  session.forEachLeaf([&](const LeafView& l) {
    if (l.level != 0 || l.counters.state() != VoxelState::Occupied) return;
    occupied.add(l.key, l.counters);
    const auto avg = consensus.find(l.key);
    occupied_disagrees.push_back(avg && avg->state() != VoxelState::Unknown && !settings.consensusOccupied(*avg));
  });
  occupied.finish();
  // Where the consensus is occupied and the session is not: targets of moves.
  VoxelSet targets;
  std::vector<uint8_t> target_session_free;
  consensus.forEachLeaf([&](const LeafView& l) {
    if (l.level != 0 || !settings.consensusOccupied(l.counters)) return;
    const auto mine = session.find(l.key);
    const VoxelState state = mine ? mine->state() : VoxelState::Unknown;
    if (state == VoxelState::Occupied && settings.move == RealignSettings::Move::Swap) return;
    targets.add(l.key, l.counters);
    target_session_free.push_back(state == VoxelState::Free);
  });
  targets.finish();
  const std::vector<Offset> offsets = offsetsWithin(settings.max_distance_voxels);

  // Best unused partner of `key` in `set` (its value scored by `score(partner index, distance)`).
  auto best = [&](const VoxelKey& key, const VoxelSet& set, auto&& score) {
    std::optional<uint32_t> best_index;
    double best_score = -1.0;
    uint64_t best_code = 0;
    for (const Offset& o : offsets) {
      const auto k = offsetKey(key, o.dx, o.dy, o.dz);
      if (!k) continue;
      const auto j = set.find(*k);
      if (!j) continue;
      const double s = score(*j, o.distance);
      const uint64_t code = mortonEncode(*k);
      if (s > best_score || (s == best_score && code < best_code)) {
        best_index = j;
        best_score = s;
        best_code = code;
      }
    }
    return std::make_pair(best_index, best_score);
  };

  // Records a move; each voxel takes part in one move at most, and a voxel can be in both sets
  // (Move::Transfer).
  auto record = [&](const VoxelKey& from, const VoxelKey& to, double score, bool occupied_pass) {
    rep.moves.push_back({from, to, score, occupied_pass});
    for (VoxelSet* set : {&occupied, &targets}) {
      set->markUsed(from);
      set->markUsed(to);
    }
    ++(occupied_pass ? rep.moved_occupied : rep.moved_free);
  };

  // Pass 1: occupied here, not occupied in the consensus.
  for (uint32_t i = 0; i < occupied.keys.size(); ++i) {
    if (!occupied_disagrees[i]) continue;
    ++rep.occupied_disagreeing;
    const auto [j, s] = best(occupied.keys[i], targets, [&](uint32_t t, double d) {
      return realignScore(occupied.values[i], targets.values[t], d, settings);
    });
    if (!j || !(s > settings.alpha)) continue;
    record(occupied.keys[i], targets.keys[*j], s, true);
  }
  // Pass 2: free here, occupied in the consensus.
  for (uint32_t t = 0; t < targets.keys.size(); ++t) {
    if (!target_session_free[t]) continue;
    ++rep.free_disagreeing;
    if (targets.used[t]) continue;
    const auto [j, s] = best(targets.keys[t], occupied, [&](uint32_t o, double d) {
      return realignScore(occupied.values[o], targets.values[t], d, settings);
    });
    if (!j || !(s > settings.alpha)) continue;
    record(occupied.keys[*j], targets.keys[t], s, false);
  }

  SessionMap out = session;
  if (!rep.moves.empty()) {
    for (const RealignMove& m : rep.moves) {
      const std::optional<VoxelCounters> here = session.find(m.from), there = session.find(m.to);
      if (settings.move == RealignSettings::Move::Swap) {
        out.assign(m.to, here);
        out.assign(m.from, there);
      } else {
        VoxelCounters moved = *here;
        if (there && there->state() == VoxelState::Occupied) moved += *there;
        out.assign(m.to, moved);
        out.assign(m.from, std::nullopt);
      }
    }
    out.compressFree();
  }
  if (report) *report = std::move(rep);
  return out;
}

}  // namespace chronomap
