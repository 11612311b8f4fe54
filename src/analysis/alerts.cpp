#include "chronomap/core/format.h"
#include "chronomap/analysis/alerts.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/temporal/coverage.h"
#include "day_kind.h"

namespace chronomap {

namespace {

/// How near a time must lie to a session's to name it: half a millisecond, the rounding of the
/// printed times, plus what the decimal digits lose.
constexpr double kSessionMatch_s = TemporalMap::kTimeSlack_s;

using analysis_detail::kindOfDay;

/// Distance between two hours of the day, around midnight.
double hourDistance(double a, double b) {
  const double d = std::abs(a - b);
  return std::min(d, 24.0 - d);
}

std::string hhmm(double time_s) {
  const auto minutes = static_cast<int>(std::floor(hourOfDay(time_s) * 60.0 + 0.5)) % (24 * 60);
  char buf[8];
  std::snprintf(buf, sizeof buf, "%02d:%02d", minutes / 60, minutes % 60);
  return buf;
}

/// A space's earlier observations.
struct Series {
  std::vector<double> times_s;
  std::vector<uint8_t> occupied;
  bool both_states = false;  ///< seen occupied and seen not occupied
};

/// The history sessions and their coverage.
struct History {
  const TemporalMap& map;
  std::vector<double> times_s;
  std::vector<CoverageIndex> coverage;
};

const char* stateName(bool occupied) { return occupied ? "occupied" : "free"; }

std::string reasonFor(const Alert& a, bool occupied_now, double time_s, double resolution_m) {
  const StateEvidence& e = a.evidence;
  const bool old_state = !occupied_now;
  const std::string days = kindOfDay(time_s) ? "weekends" : "weekdays";
  const std::string at = hhmm(time_s);
  char buf[400];
  if (e.observations == 0) {
    return "this space was never observed before";
  }
  if (a.neighbour_distance_voxels > 0) {
    std::snprintf(buf, sizeof buf,
                  "the same space %.0f cm away was %s in %u of %u earlier observations within %.1f h of %s on %s "
                  "(%u of %u at any time)",
                  100.0 * a.neighbour_distance_voxels * resolution_m, stateName(occupied_now), e.window_in_state,
                  e.window_observations, kAlertWindow_h, at.c_str(), days.c_str(), e.in_state, e.observations);
    return buf;
  }
  if (e.in_state == 0) {
    if (e.observations == 1) {
      std::snprintf(buf, sizeof buf, "this space was %s in its one earlier observation", stateName(old_state));
    } else {
      std::snprintf(buf, sizeof buf, "this space was %s in all %u earlier observations", stateName(old_state),
                    e.observations);
    }
    return buf;
  }
  if (e.window_observations == 0) {
    std::snprintf(buf, sizeof buf,
                  "this space was never observed within %.1f h of %s on %s; %s in %u of %u earlier observations at "
                  "other times",
                  kAlertWindow_h, at.c_str(), days.c_str(), stateName(occupied_now), e.in_state, e.observations);
    return buf;
  }
  // The state most observations in the window held, and how many held it.
  const bool usual_new = 2 * e.window_in_state > e.window_observations;
  const uint32_t usual = usual_new ? e.window_in_state : e.window_observations - e.window_in_state;
  const bool usual_state = usual_new ? occupied_now : old_state;
  std::snprintf(buf, sizeof buf,
                "this space is usually %s at %s: %s in %u of %u earlier observations within %.1f h of it on %s "
                "(%s in %u of %u at any time)",
                stateName(usual_state), at.c_str(), stateName(usual_state), usual, e.window_observations,
                kAlertWindow_h, days.c_str(), stateName(occupied_now), e.in_state, e.observations);
  return buf;
}

std::string place(const Eigen::Vector3d& p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "(%.2f, %.2f, %.2f)", p.x(), p.y(), p.z());
  return buf;
}

/// Joins the two halves of every move findChanges() found (its moved objects: the vanished
/// component, then the appeared one). A move is at most as likely as its less likely half (the
/// largest joint probability its two halves allow, whatever ties them), so both halves get the
/// larger score, and a reason that names the other half.
void pairMovedHalves(std::vector<Alert>& alerts, const std::vector<ChangedObject>& objects) {
  auto alertOf = [&alerts](uint32_t component) -> Alert& {
    return *std::find_if(alerts.begin(), alerts.end(), [&](const Alert& a) { return a.component.id == component; });
  };
  for (const ChangedObject& moved : objects) {
    if (moved.kind != ObjectChange::Moved) continue;
    Alert& gone = alertOf(moved.components[0]);
    Alert& come = alertOf(moved.components[1]);
    gone.moved_with = come.component.id;
    come.moved_with = gone.component.id;
    const double distance_m = (come.component.centroid_m - gone.component.centroid_m).norm();
    char far[32];
    std::snprintf(far, sizeof far, "%.1f m away at ", distance_m);
    const bool come_decides = come.own_score_bits >= gone.own_score_bits;
    const std::string gone_reason = gone.reason, come_reason = come.reason;
    if (come_decides) {
      gone.reason = "moved: it appeared " + std::string(far) + place(come.component.centroid_m) + ", where " + come_reason;
      come.reason = "moved from " + std::string(far) + place(gone.component.centroid_m) + ": " + come_reason;
    } else {
      come.reason = "moved: it vanished " + std::string(far) + place(gone.component.centroid_m) + ", where " + gone_reason;
      gone.reason = "moved to " + std::string(far) + place(come.component.centroid_m) + ": " + gone_reason;
    }
    const double bits = std::max(gone.own_score_bits, come.own_score_bits);
    for (Alert* a : {&gone, &come}) {
      a->score_bits = bits;
      a->probability = std::exp2(-bits);
    }
  }
}

}  // namespace

void AlertSettings::validate() const {
  if (neighbourhood_voxels < 0 || neighbourhood_voxels > 6) {
    throw UsageError("the alerts' neighbourhood must lie between 0 and 6 voxels");
  }
  if (max_voxels_per_object == 0) throw UsageError("at least one voxel per object must be scored");
  if (!(free_share >= 0.0 && free_share <= 0.5)) {
    throw UsageError("the share of a free space's voxels that may be occupied must lie in 0..0.5");
  }
  if (std::isnan(history_to_s)) throw UsageError("the end of the history must be a time");
  diff.validate();
  segment.validate();
  evidence.validate();
  moves.validate();
}

void EvidenceSettings::validate() const {
  if (!(other_kind_weight >= 0.0 && other_kind_weight <= 1.0)) {
    throw UsageError("the weight of the other kind of day must lie between 0 and 1");
  }
  if (!(all_hours_observations > 0.0) || !std::isfinite(all_hours_observations)) {
    throw UsageError("the strength of the all-hours evidence must be a positive number of observations");
  }
}

StateEvidence stateEvidence(const std::vector<double>& times_s, const std::vector<uint8_t>& occupied,
                            bool occupied_now, double time_s, const EvidenceSettings& settings) {
  // The window's evidence shrunk towards the all-hours share (a Beta prior of strength
  // all_hours_observations): few observations at the hour fall back to the space's whole history.
  StateEvidence e;
  const double hour = hourOfDay(time_s);
  const int kind = kindOfDay(time_s);
  double weight = 0.0, in_state = 0.0;
  for (size_t i = 0; i < times_s.size() && i < occupied.size(); ++i) {
    const bool match = (occupied[i] != 0) == occupied_now;
    ++e.observations;
    e.in_state += match;
    if (hourDistance(hourOfDay(times_s[i]), hour) > kAlertWindow_h) continue;
    double w = settings.other_kind_weight;
    if (kindOfDay(times_s[i]) == kind) {
      w = 1.0;
      ++e.window_observations;
      e.window_in_state += match;
    }
    weight += w;
    in_state += w * match;
  }
  e.all_hours_probability = (e.in_state + 0.5) / (e.observations + 1.0);
  const double k = settings.all_hours_observations;
  e.probability = (in_state + k * e.all_hours_probability) / (weight + k);
  return e;
}

AlertReport findAlerts(const TemporalMap& map, double time_s, const AlertSettings& settings) {
  settings.validate();
  const auto& sessions = map.sessions();
  // The session at `time_s` to the half millisecond: the times chronomap prints (formatTime,
  // ISO-8601 to the millisecond) name their session when given back.
  size_t rank = sessions.size();
  for (size_t i = 0; i < sessions.size(); ++i) {
    const double off = std::abs(sessions[i].time_s - time_s);
    if (off <= kSessionMatch_s && (rank == sessions.size() || off < std::abs(sessions[rank].time_s - time_s))) rank = i;
  }
  if (rank == sessions.size()) {
    std::string msg = "no session of the map lies at " + formatTime(time_s);
    if (!sessions.empty()) {
      size_t nearest = 0;
      for (size_t i = 1; i < sessions.size(); ++i) {
        if (std::abs(sessions[i].time_s - time_s) < std::abs(sessions[nearest].time_s - time_s)) nearest = i;
      }
      msg.append(" (the nearest is ").append(formatTime(sessions[nearest].time_s)).append("; ");
      msg.append(countOf(sessions.size(), "session")).append(" from ").append(formatTime(sessions.front().time_s));
      msg.append(" to ").append(formatTime(sessions.back().time_s)).append(")");
    }
    throw UsageError(msg);
  }
  if (rank == 0) throw UsageError("the first session has no history to compare with");
  AlertReport report;
  report.time_s = sessions[rank].time_s;
  report.previous_time_s = sessions[rank - 1].time_s;

  History history{map, {}, {}};
  for (size_t j = 0; j < rank && sessions[j].time_s < settings.history_to_s; ++j) {
    history.times_s.push_back(sessions[j].time_s);
    history.coverage.emplace_back(sessions[j].coverage);
  }
  if (history.times_s.empty()) throw UsageError("no session lies before the end of the history");
  report.history_sessions = static_cast<uint32_t>(history.times_s.size());

  Changes changes = findChanges(map, report.previous_time_s, report.time_s,
                                ChangeSettings{settings.diff, settings.segment, settings.moves});
  report.diff = std::move(changes.diff);
  report.segmentation = std::move(changes.segmentation);
  report.objects = std::move(changes.objects);

  const int r = settings.neighbourhood_voxels;
  const double t = report.time_s;
  for (const Component& c : report.segmentation.components) {
    const bool occupied_now = c.kind == ChangeKind::Appeared;
    // The object's unit voxels, evenly thinned to at most max_voxels_per_object.
    std::vector<VoxelKey> voxels;
    for (uint32_t i : c.cells) {
      const ChangeCell& cell = report.diff.cells()[i];
      const int n = 1 << cell.level;
      for (int dz = 0; dz < n; ++dz) {
        for (int dy = 0; dy < n; ++dy) {
          for (int dx = 0; dx < n; ++dx) {
            voxels.push_back(VoxelKey{static_cast<uint16_t>(cell.key.x + dx), static_cast<uint16_t>(cell.key.y + dy),
                                      static_cast<uint16_t>(cell.key.z + dz)});
          }
        }
      }
    }
    if (voxels.size() > settings.max_voxels_per_object) {
      std::vector<VoxelKey> thinned;
      const double step = static_cast<double>(voxels.size()) / static_cast<double>(settings.max_voxels_per_object);
      for (size_t k = 0; k < settings.max_voxels_per_object; ++k) {
        thinned.push_back(voxels[static_cast<size_t>(static_cast<double>(k) * step)]);
      }
      voxels.swap(thinned);
    }
    // The object's space (shifted by dx, dy) as one series: in each earlier session that observed
    // at least a quarter of it, occupied when at least half of what it observed was occupied.
    auto objectSeries = [&](int dx, int dy) {
      std::vector<uint32_t> seen(history.times_s.size(), 0), occupied(history.times_s.size(), 0);
      bool inside = true;
      for (const VoxelKey& v : voxels) {
        const int x = v.x + dx, y = v.y + dy;
        if (x < 0 || y < 0 || x > 65535 || y > 65535) {
          inside = false;
          break;
        }
        const VoxelKey u{static_cast<uint16_t>(x), static_cast<uint16_t>(y), v.z};
        const std::vector<HistoryEntry> entries = map.history(u);
        if (entries.empty()) continue;
        size_t e = 0;
        for (size_t j = 0; j < history.times_s.size(); ++j) {
          while (e + 1 < entries.size() && entries[e + 1].time_s <= history.times_s[j]) ++e;
          if (entries[e].time_s > history.times_s[j]) continue;
          const VoxelState state = entries[e].counters.state();
          if (state == VoxelState::Unknown || !history.coverage[j].contains(u)) continue;
          ++seen[j];
          occupied[j] += state == VoxelState::Occupied;
        }
      }
      Series out;
      if (!inside) return out;
      for (size_t j = 0; j < history.times_s.size(); ++j) {
        if (4 * seen[j] < voxels.size() || seen[j] == 0) continue;
        // Occupied from a half of what was seen, free up to free_share; in between the space
        // was partly occupied (a copy shifted half off a box): no evidence either way.
        const double share = static_cast<double>(occupied[j]) / static_cast<double>(seen[j]);
        if (share < 0.5 && share > settings.free_share) continue;
        out.times_s.push_back(history.times_s[j]);
        out.occupied.push_back(share >= 0.5 ? 1 : 0);
      }
      const auto n_occupied = std::count(out.occupied.begin(), out.occupied.end(), uint8_t{1});
      out.both_states = n_occupied > 0 && n_occupied < static_cast<long>(out.occupied.size());
      return out;
    };
    const Series own = objectSeries(0, 0);
    Alert a;
    a.component = c;
    a.evidence = stateEvidence(own.times_s, own.occupied, occupied_now, t, settings.evidence);
    // The same shape nearby: where it stood at this time of day before, the change is ordinary.
    // A shifted copy counts when it was seen in both states within the window: in the new one
    // (it stood there at this hour) and in the old one (a space that is always free at this hour
    // says nothing about this one emptying).
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const Series shifted = objectSeries(dx, dy);
        if (!shifted.both_states) continue;
        const StateEvidence e = stateEvidence(shifted.times_s, shifted.occupied, occupied_now, t, settings.evidence);
        if (e.window_in_state == 0 || e.window_observations == e.window_in_state) continue;
        if (e.probability > a.evidence.probability) {
          a.evidence = e;
          a.neighbour_distance_voxels = std::max(std::abs(dx), std::abs(dy));
        }
      }
    }
    a.score_bits = -std::log2(std::max(a.evidence.probability, 1e-12));
    a.probability = std::exp2(-a.score_bits);
    a.own_score_bits = a.score_bits;
    a.reason = reasonFor(a, occupied_now, t, map.resolution_m());
    report.alerts.push_back(std::move(a));
  }
  pairMovedHalves(report.alerts, report.objects);
  std::stable_sort(report.alerts.begin(), report.alerts.end(),
                   [](const Alert& x, const Alert& y) { return x.score_bits > y.score_bits; });
  return report;
}

}  // namespace chronomap
