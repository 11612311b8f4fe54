#include "chronomap/analysis/rhythm.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <optional>
#include <unordered_map>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/temporal/coverage.h"
#include "day_kind.h"
#include "union_find.h"

namespace chronomap {

namespace {

constexpr double kHour_s = 3600.0;

using analysis_detail::kindOfDay;

/// The two-hour bin (0..11) of the UTC hour of day.
int hourBin(double time_s) {
  const double in_day = time_s - 86400.0 * std::floor(time_s / 86400.0);
  return std::clamp(static_cast<int>(in_day / (2.0 * kHour_s)), 0, 11);
}

double markov(const VoxelRhythm& v, double time_s) {
  const double rate = static_cast<double>(v.rate_in_per_h) + static_cast<double>(v.rate_out_per_h);
  if (rate <= 0.0) return v.last_occupied;
  const double stationary = v.rate_in_per_h / rate;
  const double hours = std::abs(time_s - v.last_time_s) / kHour_s;
  return stationary + (v.last_occupied - stationary) * std::exp(-rate * hours);
}

double periodic(const VoxelRhythm& v, double time_s) {
  double p = v.mean;
  for (int k = 0; k < 2; ++k) {
    if (v.period[static_cast<size_t>(k)] >= kRhythmPeriods_h.size()) continue;
    const double w = 2.0 * std::numbers::pi / (kRhythmPeriods_h[v.period[static_cast<size_t>(k)]] * kHour_s);
    p += v.amplitude[static_cast<size_t>(k)][0] * std::cos(w * time_s) +
         v.amplitude[static_cast<size_t>(k)][1] * std::sin(w * time_s);
  }
  return std::clamp(p, 0.0, 1.0);
}

/// The hourly profile of bins `seen` and `occ` (per kind of day and two-hour bin) at `time_s`.
template <typename Count>
double hourlyOf(const std::array<std::array<Count, 12>, 2>& seen, const std::array<std::array<Count, 12>, 2>& occ,
                double time_s, double prior) {
  // Neighbouring bins of the same kind of day count less, and less again the more their occupied
  // share differs from the bin's own (when both were observed): a schedule's edge between two
  // bins stays sharp where the data show it (a door open until 18:00 reads open at 17:30 when the
  // 16-18 h bin saw it open), and a bin without observations still borrows from its neighbours.
  // The other kind's same bin counts a little; one pseudo-observation at the voxel's mean keeps
  // bins with little evidence near it.
  static constexpr double kNeighbour[3] = {1.0, 0.25, 0.05};
  static constexpr double kOtherKind = 0.1, kPrior = 1.0;
  const auto kind = static_cast<size_t>(kindOfDay(time_s)), bin = static_cast<size_t>(hourBin(time_s));
  const double own_seen = seen[kind][bin];
  const double own_share = own_seen > 0.0 ? occ[kind][bin] / own_seen : 0.0;
  double observed = kPrior, occupied = kPrior * prior;
  for (int d = -2; d <= 2; ++d) {
    const auto b = (bin + static_cast<size_t>(d + 12)) % 12;
    double w = kNeighbour[std::abs(d)];
    if (d != 0 && own_seen > 0.0 && seen[kind][b] > 0) {
      w *= 1.0 - std::abs(own_share - static_cast<double>(occ[kind][b]) / seen[kind][b]);
    }
    observed += w * seen[kind][b];
    occupied += w * occ[kind][b];
  }
  observed += kOtherKind * seen[1 - kind][bin];
  occupied += kOtherKind * occ[1 - kind][bin];
  return occupied / observed;
}

double hourly(const VoxelRhythm& v, double time_s, double prior) {
  return hourlyOf(v.hour_observed, v.hour_occupied, time_s, prior);
}

uint8_t saturating(uint32_t n) { return static_cast<uint8_t>(std::min<uint32_t>(n, 255)); }

}  // namespace

const char* toString(RhythmModel model) {
  switch (model) {
    case RhythmModel::Latest: return "latest";
    case RhythmModel::Mean: return "mean";
    case RhythmModel::Markov: return "markov";
    case RhythmModel::Periodic: return "periodic";
    case RhythmModel::Hourly: return "hourly";
    case RhythmModel::Combined: return "combined";
  }
  return "unknown";
}

RhythmModel parseRhythmModel(const std::string& name) {
  for (RhythmModel m : kRhythmModels) {
    if (name == toString(m)) return m;
  }
  throw UsageError("unknown model '" + name + "' (latest, mean, markov, periodic, hourly or combined)");
}

std::vector<VoxelSeries> observedSeries(const TemporalMap& map, uint32_t first, uint32_t end, uint32_t min_changes) {
  if (min_changes == 0) throw UsageError("the least number of changes must be at least 1");
  end = std::min<uint32_t>(end, static_cast<uint32_t>(map.sessionCount()));
  if (first >= end) throw UsageError("no session to learn from in the range");
  std::vector<CoverageIndex> coverage;
  coverage.reserve(end - first);
  for (uint32_t r = first; r < end; ++r) coverage.emplace_back(map.sessions()[r].coverage);
  std::vector<VoxelSeries> out;
  map.forEachListChangedIn(first, end, [&](const VoxelKey& corner, int level,
                                            std::span<const TemporalMap::Entry> entries) {
    uint32_t changes = 0;
    for (size_t i = 1; i < entries.size(); ++i) changes += entries[i].session >= first && entries[i].session < end;
    if (changes < min_changes) return;
    VoxelSeries s;
    s.corner = corner;
    s.level = level;
    size_t e = 0;  // entries[e] is the last entry at or before rank r
    for (uint32_t r = first; r < end; ++r) {
      while (e + 1 < entries.size() && entries[e + 1].session <= r) ++e;
      if (entries[e].session > r) continue;  // not yet observed
      if (coverage[r - first].overlap(corner, level) == CoverageIndex::Overlap::None) continue;  // no evidence
      s.ranks.push_back(r);
      s.occupied.push_back(entries[e].value.state() == VoxelState::Occupied ? 1 : 0);
      s.times_s.push_back(map.sessions()[r].time_s);
      s.counters.push_back(entries[e].value);
    }
    if (!s.ranks.empty()) out.push_back(std::move(s));
  });
  return out;
}

namespace {

/// fitVoxel, also giving the leave-one-out Brier sums of the hourly profile and of the mean on
/// the learning observations (0 with fewer than two).
VoxelRhythm fitOne(const VoxelSeries& series, double voxel_m, double& loss_hourly, double& loss_mean) {
  loss_hourly = loss_mean = 0.0;
  VoxelRhythm v;
  v.corner = series.corner;
  v.level = static_cast<uint8_t>(series.level);
  const size_t n = series.times_s.size();
  if (n == 0) return v;
  v.observations = static_cast<uint16_t>(std::min<size_t>(n, 65535));
  double occupied = 0.0;
  for (uint8_t y : series.occupied) occupied += y;
  const double mean = occupied / static_cast<double>(n);
  v.mean = static_cast<float>(mean);
  v.last_occupied = series.occupied.back();
  v.last_time_s = series.times_s.back();

  // Surface evidence: hits per voxel length of ray, over the counters of every observation.
  if (series.counters.size() == n) {
    double hits = 0.0, length_m = 0.0;
    for (const VoxelCounters& c : series.counters) {
      hits += c.hits;
      length_m += c.length_m;
    }
    const double edge_m = voxel_m * static_cast<double>(1 << series.level);
    const double x = length_m > 0.0 ? hits * edge_m / length_m : (hits > 0.0 ? 1e6 : 0.0);
    v.hits_per_voxel = static_cast<float>(std::min(x, 1e6));
  }

  // Markov: transitions between consecutive observations over the time spent in each state,
  // with half a transition and an hour of prior so that a voxel seen once still has rates.
  double in = 0.5, out = 0.5, free_h = 1.0, occupied_h = 1.0;
  for (size_t i = 0; i + 1 < n; ++i) {
    const double dt_h = (series.times_s[i + 1] - series.times_s[i]) / kHour_s;
    if (series.occupied[i]) {
      occupied_h += dt_h;
      out += series.occupied[i + 1] ? 0.0 : 1.0;
    } else {
      free_h += dt_h;
      in += series.occupied[i + 1] ? 1.0 : 0.0;
    }
  }
  v.rate_in_per_h = static_cast<float>(in / free_h);
  v.rate_out_per_h = static_cast<float>(out / occupied_h);

  // Periodic: greedily the two periods whose least-squares sinusoid explains most of what the
  // mean and the components already chosen leave.
  std::vector<double> residual(n);
  for (size_t i = 0; i < n; ++i) residual[i] = series.occupied[i] - mean;
  std::vector<bool> used(kRhythmPeriods_h.size(), false);
  for (size_t k = 0; k < 2 && n >= 3; ++k) {
    double best_gain = 1e-9;
    int best = -1;
    double best_a = 0.0, best_b = 0.0;
    for (size_t p = 0; p < kRhythmPeriods_h.size(); ++p) {
      if (used[p]) continue;
      const double w = 2.0 * std::numbers::pi / (kRhythmPeriods_h[p] * kHour_s);
      double cc = 0, ss = 0, cs = 0, cr = 0, sr = 0;
      for (size_t i = 0; i < n; ++i) {
        const double c = std::cos(w * series.times_s[i]), s = std::sin(w * series.times_s[i]);
        cc += c * c;
        ss += s * s;
        cs += c * s;
        cr += c * residual[i];
        sr += s * residual[i];
      }
      const double det = cc * ss - cs * cs;
      if (std::abs(det) < 1e-9 * std::max(1.0, cc * ss)) continue;  // the samples cannot tell this period
      const double a = (ss * cr - cs * sr) / det, b = (cc * sr - cs * cr) / det;
      const double gain = a * cr + b * sr;  // reduction of the squared residual
      if (gain > best_gain) {
        best_gain = gain;
        best = static_cast<int>(p);
        best_a = a;
        best_b = b;
      }
    }
    if (best < 0) break;
    used[static_cast<size_t>(best)] = true;
    v.period[k] = static_cast<uint8_t>(best);
    v.amplitude[k] = {static_cast<float>(best_a), static_cast<float>(best_b)};
    const double w = 2.0 * std::numbers::pi / (kRhythmPeriods_h[static_cast<size_t>(best)] * kHour_s);
    for (size_t i = 0; i < n; ++i) {
      residual[i] -= best_a * std::cos(w * series.times_s[i]) + best_b * std::sin(w * series.times_s[i]);
    }
  }

  // Hourly: observations by kind of day and two-hour bin.
  std::array<std::array<uint32_t, 12>, 2> seen{}, occ{};
  for (size_t i = 0; i < n; ++i) {
    const auto kind = static_cast<size_t>(kindOfDay(series.times_s[i]));
    const auto bin = static_cast<size_t>(hourBin(series.times_s[i]));
    ++seen[kind][bin];
    occ[kind][bin] += series.occupied[i];
  }
  for (size_t k = 0; k < 2; ++k) {
    for (size_t b = 0; b < 12; ++b) {
      v.hour_observed[k][b] = saturating(seen[k][b]);
      v.hour_occupied[k][b] = saturating(occ[k][b]);
    }
  }

  // Combined: whichever of the hourly profile and the plain mean predicts the learning
  // observations better, each left out in turn (a voxel without a daily rhythm, whose changes
  // were noise, keeps its mean).
  if (n >= 2) {
    for (size_t i = 0; i < n; ++i) {
      const auto kind = static_cast<size_t>(kindOfDay(series.times_s[i]));
      const auto bin = static_cast<size_t>(hourBin(series.times_s[i]));
      const double y = series.occupied[i];
      const double mean_without = (occupied - y) / static_cast<double>(n - 1);
      VoxelRhythm without = v;
      without.mean = static_cast<float>(mean_without);
      if (seen[kind][bin] <= 255) {  // saturated bins cannot be decremented exactly: keep them
        without.hour_observed[kind][bin] = saturating(seen[kind][bin] - 1);
        without.hour_occupied[kind][bin] = saturating(occ[kind][bin] - series.occupied[i]);
      }
      const double ph = hourly(without, series.times_s[i], without.mean);
      loss_hourly += (ph - y) * (ph - y);
      loss_mean += (mean_without - y) * (mean_without - y);
    }
    v.combined_uses_mean = loss_mean < loss_hourly ? 1 : 0;
  }
  return v;
}

constexpr size_t kNoIndex = static_cast<size_t>(-1);

/// The phi coefficient of two series' states over the sessions that observed both, and how
/// many those are; 0 when either state is constant over them.
double correlation(const VoxelSeries& a, const VoxelSeries& b, uint32_t& common) {
  double n11 = 0, n10 = 0, n01 = 0, n00 = 0;
  size_t i = 0, j = 0;
  while (i < a.ranks.size() && j < b.ranks.size()) {
    if (a.ranks[i] < b.ranks[j]) {
      ++i;
    } else if (b.ranks[j] < a.ranks[i]) {
      ++j;
    } else {
      const bool x = a.occupied[i] != 0, y = b.occupied[j] != 0;
      (x ? (y ? n11 : n10) : (y ? n01 : n00)) += 1.0;
      ++i;
      ++j;
    }
  }
  common = static_cast<uint32_t>(n11 + n10 + n01 + n00);
  const double d = (n11 + n10) * (n01 + n00) * (n11 + n01) * (n10 + n00);
  return d > 0.0 ? (n11 * n00 - n10 * n01) / std::sqrt(d) : 0.0;
}

using Bins = std::array<std::array<uint32_t, 12>, 2>;

/// Groups the unit voxels of `series` that change together into objects (RhythmGroupSettings);
/// every voxel of an object with a rhythm whose pooled profile predicts its own observations
/// better (leave-one-out) than its own profile and its mean uses the object's profile.
void groupVoxels(const std::vector<VoxelSeries>& series, std::vector<VoxelRhythm>& fitted,
                 const std::vector<double>& loss_hourly, const std::vector<double>& loss_mean,
                 const RhythmGroupSettings& settings, std::vector<RhythmGroup>& groups) {
  const size_t n = series.size();
  std::unordered_map<uint64_t, size_t> index;
  index.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (series[i].level == 0 && series[i].ranks.size() >= settings.min_common) {
      index[mortonEncode(series[i].corner)] = i;
    }
  }
  UnionFind components(n);
  for (const auto& entry : index) {
    const size_t i = entry.second;  // a plain local: lambdas may not capture structured bindings before C++20
    const VoxelKey k = series[i].corner;
    forEachLaterNeighbour(k, [&](const VoxelKey& other) {  // each touching pair once
      const auto it = index.find(mortonEncode(other));
      if (it == index.end()) return;
      uint32_t common = 0;
      const double phi = correlation(series[i], series[it->second], common);
      if (common >= settings.min_common && phi >= settings.min_correlation) {
        components.join(static_cast<uint32_t>(i), static_cast<uint32_t>(it->second));
      }
    });
  }
  // Members of each component, in the series' order (deterministic).
  std::vector<size_t> slot(n, kNoIndex);
  std::vector<std::vector<size_t>> members;
  for (size_t i = 0; i < n; ++i) {
    if (series[i].level != 0 || series[i].ranks.size() < settings.min_common) continue;
    const size_t root = components.find(static_cast<uint32_t>(i));
    if (slot[root] == kNoIndex) {
      slot[root] = members.size();
      members.emplace_back();
    }
    members[slot[root]].push_back(i);
  }
  for (const std::vector<size_t>& group : members) {
    if (group.size() < std::max<uint32_t>(settings.min_voxels, 2)) continue;
    Bins seen{}, occ{};
    double total = 0, occupied_total = 0;
    for (size_t i : group) {
      const VoxelSeries& s = series[i];
      for (size_t o = 0; o < s.times_s.size(); ++o) {
        const auto kind = static_cast<size_t>(kindOfDay(s.times_s[o]));
        const auto bin = static_cast<size_t>(hourBin(s.times_s[o]));
        ++seen[kind][bin];
        occ[kind][bin] += s.occupied[o];
        total += 1;
        occupied_total += s.occupied[o];
      }
    }
    // Leave one observation out: the pooled profile without it against the pooled mean without it.
    auto without = [&](const VoxelSeries& s, size_t o, Bins& seen_without, Bins& occ_without) {
      const auto kind = static_cast<size_t>(kindOfDay(s.times_s[o]));
      const auto bin = static_cast<size_t>(hourBin(s.times_s[o]));
      seen_without = seen;
      occ_without = occ;
      --seen_without[kind][bin];
      occ_without[kind][bin] -= s.occupied[o];
    };
    double group_hourly = 0, group_mean = 0;
    std::vector<double> own(group.size(), 0.0);
    Bins seen_without{}, occ_without{};
    for (size_t m = 0; m < group.size(); ++m) {
      const VoxelSeries& s = series[group[m]];
      for (size_t o = 0; o < s.times_s.size(); ++o) {
        const double y = s.occupied[o];
        const double mean_without = (occupied_total - y) / (total - 1);
        without(s, o, seen_without, occ_without);
        const double p = hourlyOf(seen_without, occ_without, s.times_s[o], mean_without);
        group_hourly += (p - y) * (p - y);
        group_mean += (mean_without - y) * (mean_without - y);
        own[m] += (p - y) * (p - y);
      }
    }
    // Without enough gain the object's changes were noise, not a rhythm.
    if (!(group_hourly < (1.0 - settings.min_gain) * group_mean)) continue;
    RhythmGroup g;
    for (size_t k = 0; k < 2; ++k) {
      for (size_t b = 0; b < 12; ++b) {
        g.observed[k][b] = static_cast<uint16_t>(std::min<uint32_t>(seen[k][b], 65535));
        g.occupied[k][b] = static_cast<uint16_t>(std::min<uint32_t>(occ[k][b], 65535));
      }
    }
    bool used = false;
    for (size_t m = 0; m < group.size(); ++m) {
      const size_t i = group[m];
      if (!(own[m] < loss_hourly[i] && own[m] < loss_mean[i])) continue;
      VoxelRhythm& v = fitted[i];
      v.group = static_cast<uint32_t>(groups.size());
      v.group_observed = g.observed;
      v.group_occupied = g.occupied;
      used = true;
    }
    if (used) groups.push_back(g);
  }
}

}  // namespace

VoxelRhythm fitVoxel(const VoxelSeries& series, double voxel_m) {
  double loss_hourly = 0.0, loss_mean = 0.0;
  return fitOne(series, voxel_m, loss_hourly, loss_mean);
}

RhythmModels fitSeries(const std::vector<VoxelSeries>& series, double voxel_m, const RhythmGroupSettings& grouping) {
  RhythmModels models;
  models.resolution_m = voxel_m;
  std::vector<VoxelRhythm> fitted(series.size());
  std::vector<double> loss_hourly(series.size()), loss_mean(series.size());
  for (size_t i = 0; i < series.size(); ++i) fitted[i] = fitOne(series[i], voxel_m, loss_hourly[i], loss_mean[i]);
  if (grouping.enabled) groupVoxels(series, fitted, loss_hourly, loss_mean, grouping, models.groups);
  std::sort(fitted.begin(), fitted.end(), [](const VoxelRhythm& a, const VoxelRhythm& b) {
    return mortonEncode(a.corner) < mortonEncode(b.corner);
  });
  models.voxels = std::move(fitted);
  return models;
}

double surfaceEvidence(const VoxelRhythm& v) {
  if (!(v.hits_per_voxel >= 0.0f)) return v.mean;
  const double x = v.hits_per_voxel;
  return x * x / (x * x + kSurfaceHitsPerVoxel * kSurfaceHitsPerVoxel);
}

double RhythmModels::predict(const VoxelRhythm& v, RhythmModel model, double time_s) {
  switch (model) {
    case RhythmModel::Latest: return v.last_occupied;
    case RhythmModel::Mean: return v.mean;
    case RhythmModel::Markov: return markov(v, time_s);
    case RhythmModel::Periodic: return periodic(v, time_s);
    case RhythmModel::Hourly: return hourly(v, time_s, v.mean);
    case RhythmModel::Combined: {
      // The chain's memory of the last observation fades at the sum of its rates.
      const double rate = static_cast<double>(v.rate_in_per_h) + static_cast<double>(v.rate_out_per_h);
      const double w = std::exp(-rate * std::abs(time_s - v.last_time_s) / kHour_s);
      const double base = v.group != VoxelRhythm::kNoGroup
                              ? hourlyOf(v.group_observed, v.group_occupied, time_s, v.mean)
                          : v.combined_uses_mean ? surfaceEvidence(v)
                                                 : hourly(v, time_s, surfaceEvidence(v));
      return w * markov(v, time_s) + (1.0 - w) * base;
    }
  }
  return v.mean;
}

const VoxelRhythm* RhythmModels::find(const VoxelKey& key) const {
  const uint64_t code = mortonEncode(key);
  auto it = std::upper_bound(voxels.begin(), voxels.end(), code,
                             [](uint64_t c, const VoxelRhythm& v) { return c < mortonEncode(v.corner); });
  if (it == voxels.begin()) return nullptr;
  --it;
  const uint32_t size = 1u << it->level;
  const bool inside = key.x >= it->corner.x && key.x < it->corner.x + size && key.y >= it->corner.y &&
                      key.y < it->corner.y + size && key.z >= it->corner.z && key.z < it->corner.z + size;
  return inside ? &*it : nullptr;
}

RhythmModels fitRhythm(const TemporalMap& map, double from_s, double to_s, uint32_t min_changes,
                       const RhythmGroupSettings& grouping) {
  uint32_t first = 0;
  while (first < map.sessionCount() && map.sessions()[first].time_s < from_s) ++first;
  const uint32_t end = map.ranksThrough(to_s);
  if (first >= end) throw UsageError("no session of the map lies in the learning interval");
  RhythmModels models = fitSeries(observedSeries(map, first, end, min_changes), map.resolution_m(), grouping);
  models.from_s = map.sessions()[first].time_s;
  models.to_s = map.sessions()[end - 1].time_s;
  models.sessions = end - first;
  models.fitted_on = fittedOn(map, models.from_s, models.to_s);
  return models;
}

namespace {

/// The colour of the latest stored state of `key` with hits, at or before `time_s` if there is
/// one, else the earliest after it; black when it was never hit.
Rgb lastSeenColour(const TemporalMap& map, const VoxelKey& key, double time_s) {
  std::optional<Rgb> before, after;
  for (const HistoryEntry& e : map.history(key)) {
    if (e.counters.hits == 0) continue;
    if (e.time_s <= time_s) {
      before = e.counters.meanColour();
    } else if (!after) {
      after = e.counters.meanColour();
    }
  }
  return before ? *before : after.value_or(Rgb{});
}

}  // namespace

SessionMap predictMap(const TemporalMap& map, const RhythmModels& models, RhythmModel model, double time_s) {
  if (!sameResolution(models.resolution_m, map.resolution_m())) {
    throw UsageError("the model was fitted at " + exactNumber(models.resolution_m) + " m, the map has " +
                     exactNumber(map.resolution_m()) + " m voxels");
  }
  SessionMap out = map.snapshot(time_s);
  for (const VoxelRhythm& v : models.voxels) {
    const double p = std::clamp(RhythmModels::predict(v, model, time_s), 0.0, 1.0);
    const int side = 1 << v.level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          const VoxelKey key{static_cast<uint16_t>(v.corner.x + dx), static_cast<uint16_t>(v.corner.y + dy),
                             static_cast<uint16_t>(v.corner.z + dz)};
          const std::optional<VoxelCounters> before = out.find(key);
          VoxelCounters c;
          if (p <= 0.0) {
            c.length_m = static_cast<float>(map.resolution_m());  // seen through, never hit
          } else {
            c.hits = 1;
            c.length_m = p >= 1.0 ? 0.0f : static_cast<float>(-1.0 / std::log1p(-p));
            const Rgb colour = before && before->hits > 0 ? before->meanColour() : lastSeenColour(map, key, time_s);
            c.red = colour.r;
            c.green = colour.g;
            c.blue = colour.b;
          }
          out.assign(key, c);
        }
      }
    }
  }
  out.compressFree();
  return out;
}

}  // namespace chronomap
