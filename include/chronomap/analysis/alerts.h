#pragma once
/// @file
/// Which observed changes are unusual (thesis §3.3): each changed object of a session scored by
/// how unlikely its change was under the history of the space it occupies and of the space
/// around it, with a reason a person can read.
///
/// A session at time T is compared with the map as observed by the session before it (a
/// diff of the two snapshots, then its connected components: the changed objects). The evidence
/// for an object is the history of its space: in every earlier session that observed at least a
/// quarter of its voxels (its coverage; a session that did not observe them says nothing), the
/// space counts as occupied when at least half of what was observed of it was occupied. The
/// probability of its new state at T is the share of those observations in that state, weighted
/// towards observations at the same time of day (within 1.5 h, the same kind of day: weekday or
/// weekend), with one pseudo-observation at the overall share (plus half an observation, so a
/// state never seen keeps a small probability). The neighbourhood counts too: the same space
/// shifted by up to `neighbourhood_voxels` in x and y, when it was seen in both states within the
/// window, can make the change ordinary (a chair moved a
/// few centimetres from where it stood at this hour before). The score is -log2 of the larger
/// probability, in bits.

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// Settings of findAlerts().
struct AlertSettings {
  /// The diff between the previous session and the session at T. Default: hard, with the
  /// neighbourhood rule of registered sessions (1 voxel, surfaces moved by half a voxel).
  DiffSettings diff = [] {
    DiffSettings d;
    d.neighbourhood_voxels = 1;
    d.min_shift_voxels = DiffSettings::kRecommendedMinShift;
    return d;
  }();
  /// Its components; smaller ones are not objects (default 20 voxels, 2.5 litres).
  SegmentSettings segment = [] {
    SegmentSettings s;
    s.min_voxels = 20;
    return s;
  }();
  /// How far the object's space is shifted (x and y, voxels) to look for the same change nearby (0..6).
  int neighbourhood_voxels = 3;
  /// Only sessions with times before this are history (default: every session before T).
  double history_to_s = std::numeric_limits<double>::infinity();
  /// Voxels read per object at most (evenly spaced among its voxels), for speed.
  size_t max_voxels_per_object = 800;

  /// @throw UsageError for a neighbourhood outside 0..6, a zero max_voxels_per_object, bad diff
  /// or segment settings.
  void validate() const;
};

/// Half-width of the time-of-day window whose observations count fully, in hours.
inline constexpr double kAlertWindow_h = 1.5;

/// What a space's history says about a state at a time.
struct StateEvidence {
  uint32_t observations = 0;      ///< earlier observations
  uint32_t in_state = 0;          ///< of those, in the state asked about
  uint32_t window_observations = 0;  ///< earlier observations within the window of the hour, same kind of day
  uint32_t window_in_state = 0;      ///< of those, in the state asked about
  double probability = 0.0;          ///< of the state at that time
};

/// The evidence of observations (`times_s`, `occupied`) for the state `occupied_now` at `time_s`,
/// as findAlerts() weighs it (see the file comment). Exposed for tests.
StateEvidence stateEvidence(const std::vector<double>& times_s, const std::vector<uint8_t>& occupied,
                            bool occupied_now, double time_s);

/// One changed object of the session, scored.
struct Alert {
  Component component;
  double score_bits = 0.0;    ///< -log2 of the probability of its change
  double probability = 1.0;   ///< how likely its change was
  /// The evidence: its own space's history, or that of the same space shifted by
  /// `neighbour_distance_voxels` (0: its own) that made the change likelier.
  StateEvidence evidence;
  int neighbour_distance_voxels = 0;
  /// "this space was free in all 41 earlier observations", ...
  std::string reason;
};

/// The alerts of one session.
struct AlertReport {
  double time_s = 0.0;           ///< the session's time
  double previous_time_s = 0.0;  ///< the session it is compared with
  uint32_t history_sessions = 0;  ///< sessions whose observations were evidence
  DiffMap diff;
  Segmentation segmentation;
  /// Every component of the segmentation, by decreasing score (ties: by id).
  std::vector<Alert> alerts;
};

/// The changed objects of the session at `time_s` (a session of the map, to the microsecond),
/// scored against the history before it.
/// @throw UsageError when no session lies at `time_s`, it is the first session, no session lies
/// before history_to_s, or for bad settings.
AlertReport findAlerts(const TemporalMap& map, double time_s, const AlertSettings& settings = {});

}  // namespace chronomap
