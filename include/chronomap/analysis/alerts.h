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
/// space counts as occupied when at least half of what was observed of it was occupied, free when at
/// most `free_share` was (in between: partly occupied, no evidence). The
/// probability of its new state at T is the share of the observations at that time of day
/// (within 1.5 h, the same kind of day: weekday or weekend) in that state, shrunk towards the
/// share over all hours by as many observations as EvidenceSettings::all_hours_observations: few
/// observations at that hour fall back to the all-hours evidence, many speak for themselves.
/// The neighbourhood counts too: the same space shifted by up to `neighbourhood_voxels` in x and
/// y, when it was seen in both states within the window, can make the change ordinary (a chair
/// moved a few centimetres from where it stood at this hour before). The score is -log2 of the
/// larger probability, in bits. A vanished and an appeared object of the session that look
/// alike (size, height, colour: MoveSettings, pairMoves() in analysis/moves.h) are one object moved, scored as one: the move is
/// at most as likely as its less likely half, and both halves get that score.

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "chronomap/analysis/change_preset.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/moves.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// How a space's history is weighed (stateEvidence()).
struct EvidenceSettings {
  /// Weight of an observation within the window of the hour but on the other kind of day
  /// (a weekend's at a weekday's hour): routines differ between the two, yet not entirely.
  double other_kind_weight = 0.25;
  /// Strength of the all-hours evidence, in observations (a Beta prior centred on the share of
  /// the state over all hours): the window's share weighs as much as the all-hours share when
  /// the window holds this many observations, more beyond. Default 3: about what the window of
  /// an hour holds on average in three weeks of two sessions a day (42 * 3 h / 24 h * 5 / 7).
  double all_hours_observations = 3.0;
  /// @throw UsageError for a weight outside 0..1 or a strength that is not positive and finite.
  void validate() const;
};

/// Settings of findAlerts().
struct AlertSettings {
  /// The changes between the previous session and the session at T, found as every front door
  /// finds them (findChanges, analysis/changes.h): the recommended diff and objects by default.
  DiffSettings diff = recommendedChangeSettings().diff;
  /// Its components; smaller ones are not objects (the recommended 20 voxels, 2.5 litres).
  SegmentSettings segment = recommendedChangeSettings().segment;
  /// How far the object's space is shifted (x and y, voxels) to look for the same change nearby (0..6).
  int neighbourhood_voxels = 3;
  /// Only sessions with times before this are history (default: every session before T).
  double history_to_s = std::numeric_limits<double>::infinity();
  /// Voxels read per object at most (evenly spaced among its voxels), for speed.
  size_t max_voxels_per_object = 800;
  /// In an earlier session, a space counts as occupied when at least half of what was observed
  /// of it was occupied, and as free when at most this share was; in between it was partly
  /// occupied (the space shifted half off a box: part surface, part air) and says nothing
  /// either way. Default a quarter: a shifted copy of an object that stood still is near a half,
  /// an object's own space when it is gone near none. 0.5: no band (every session counts).
  double free_share = 0.25;
  /// How the history's observations are weighed.
  EvidenceSettings evidence;
  /// Which objects are the two halves of a move.
  MoveSettings moves;

  /// @throw UsageError for a neighbourhood outside 0..6, a zero max_voxels_per_object, a
  /// free_share outside 0..0.5, bad diff,
  /// segment, evidence or move settings.
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
  double all_hours_probability = 0.0;  ///< of the state at any time: (in_state + 0.5) / (observations + 1)
  double probability = 0.0;          ///< of the state at that time
};

/// The evidence of observations (`times_s`, `occupied`) for the state `occupied_now` at `time_s`,
/// as findAlerts() weighs it: with W the window's weight (1 per observation within the window on
/// the same kind of day, other_kind_weight on the other kind) and K the weight of those in the
/// state, p_all the all-hours share and k = all_hours_observations,
///   probability = (K + k * p_all) / (W + k).
/// Exposed for tests.
StateEvidence stateEvidence(const std::vector<double>& times_s, const std::vector<uint8_t>& occupied,
                            bool occupied_now, double time_s, const EvidenceSettings& settings = {});

/// One changed object of the session, scored.
struct Alert {
  Component component;
  double score_bits = 0.0;    ///< -log2 of the probability of its change
  double probability = 1.0;   ///< how likely its change was
  /// The evidence: its own space's history, or that of the same space shifted by
  /// `neighbour_distance_voxels` (0: its own) that made the change likelier.
  StateEvidence evidence;
  int neighbour_distance_voxels = 0;
  /// The score of its own change, before a move joined it with its other half.
  double own_score_bits = 0.0;
  /// The id of the other half of its move (the vanished object for an appeared one and back);
  /// 0: no move.
  uint32_t moved_with = 0;
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
  /// The changed objects, as findChanges() gives them (a move's two components are one object).
  std::vector<ChangedObject> objects;
  /// Every component of the segmentation, by decreasing score (ties: by id).
  std::vector<Alert> alerts;
};

/// The changed objects of the session at `time_s` (a session of the map, to the half millisecond:
/// a time as chronomap prints it, ISO-8601 to the millisecond, names its session), scored against
/// the history before it.
/// @throw UsageError when no session lies at `time_s`, it is the first session, no session lies
/// before history_to_s, or for bad settings.
AlertReport findAlerts(const TemporalMap& map, double time_s, const AlertSettings& settings = {});

}  // namespace chronomap
