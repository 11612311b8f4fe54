#pragma once
/// @file
/// How each part of the place changes with time, learned from a 4D map (thesis §3.3): per-voxel
/// temporal models that give the probability of occupancy at any time, past or future.
///
/// A model learns from a voxel's observations: the sessions whose coverage holds the voxel, each
/// with the state it stored then. A session that did not observe the voxel is no evidence (the
/// 4D map keeps the last state it saw; the models do not read that as a new observation).
///
/// Models, for each voxel that changed at least once while learning:
/// - Latest: the state of the last observation (a static map).
/// - Mean: the share of observations that were occupied.
/// - Markov: a two-state continuous-time Markov chain with an entry rate (free to occupied) and
///   an exit rate, estimated from consecutive observations; from the last observation it decays
///   to its stationary probability (independent Markov chain occupancy grids).
/// - Periodic: the mean plus the two strongest of a fixed set of periodic components (one week,
///   half a week, a day, 12, 8 and 6 hours), each fitted to the observations (a spectral model in
///   the manner of FreMEn).
/// - Hourly: a daily profile per kind of day (weekday, weekend): the observations binned by hour,
///   smoothed over neighbouring hours and drawn towards the voxel's mean where hours hold few
///   observations (an hour never observed says nothing: it gets the mean).
/// - Combined: Markov near the last observation; further away, per voxel the better of Hourly and
///   Mean by their leave-one-out Brier score on the learning observations, weighted by how fast
///   the chain forgets its state. A voxel whose changes were noise, not a rhythm (the mean won),
///   gets the surface evidence of its counters instead of its mean: x² / (x² + x0²), x the hits
///   per voxel length of ray pooled over its observations and x0 = kSurfaceHitsPerVoxel (a static
///   surface that only clips a voxel is hit whenever seen, however many rays pass by its empty
///   part; a free voxel in front of one gets a few noisy hits among many rays through it).
///   Voxels change together when they belong to one object (a door's panel, a chair):
///   neighbouring voxels whose states correlate are grouped (RhythmGroupSettings), and a voxel of
///   an object with a rhythm whose pooled hourly profile predicts the voxel's own observations
///   better than its own profile and its mean (leave-one-out) is predicted from the object's
///   profile. A door voxel whose own profile pose error blurs is then predicted as the door, not
///   as the static surface its counters suggest.
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/analysis/fitted_on.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// One cube's observations, in time order.
struct VoxelSeries {
  VoxelKey corner;
  int level = 0;                   ///< the stored cube (0: a unit voxel)
  std::vector<uint32_t> ranks;     ///< sessions (ranks in time order) that observed it
  std::vector<uint8_t> occupied;   ///< 1 where it was occupied in that session
  std::vector<double> times_s;     ///< those sessions' times
  std::vector<VoxelCounters> counters;  ///< the counters stored for it then (for a cube: its own)
};

/// The observations, by the sessions of rank in [first, end), of every stored cube whose state
/// changed at least `min_changes` times by those sessions.
/// @throw UsageError for an empty range or min_changes 0.
std::vector<VoxelSeries> observedSeries(const TemporalMap& map, uint32_t first, uint32_t end, uint32_t min_changes = 1);

/// The models, by name: "latest", "mean", "markov", "periodic", "hourly", "combined".
enum class RhythmModel : uint8_t { Latest, Mean, Markov, Periodic, Hourly, Combined };
const char* toString(RhythmModel model);
/// @throw UsageError for an unknown name.
RhythmModel parseRhythmModel(const std::string& name);
inline constexpr std::array<RhythmModel, 6> kRhythmModels = {RhythmModel::Latest,   RhythmModel::Mean,
                                                             RhythmModel::Markov,   RhythmModel::Periodic,
                                                             RhythmModel::Hourly,   RhythmModel::Combined};

/// Periods the periodic model chooses from, in hours.
inline constexpr std::array<double, 6> kRhythmPeriods_h = {168.0, 84.0, 24.0, 12.0, 8.0, 6.0};

/// Where Combined's surface evidence is 0.5: hits per voxel length of ray (0.1: one hit per ten
/// rays crossing the voxel).
inline constexpr double kSurfaceHitsPerVoxel = 0.1;

/// The fitted parameters of one cube: every model's, 105 bytes in a saved model (and 96 per object it uses).
struct VoxelRhythm {
  VoxelKey corner;
  uint8_t level = 0;
  uint8_t last_occupied = 0;    ///< state of the last observation
  uint16_t observations = 0;    ///< how many sessions observed it while learning (saturating)
  uint8_t combined_uses_mean = 0;  ///< Combined: 1 when the mean beat the hourly profile
  float mean = 0.0f;            ///< occupied share of the observations
  double last_time_s = 0.0;     ///< time of the last observation
  float rate_in_per_h = 0.0f;   ///< Markov: free to occupied, per hour
  float rate_out_per_h = 0.0f;  ///< Markov: occupied to free, per hour
  /// Periodic: indices into kRhythmPeriods_h (255: unused) and the cosine and sine amplitudes.
  std::array<uint8_t, 2> period = {255, 255};
  std::array<std::array<float, 2>, 2> amplitude = {};
  /// Hourly: per kind of day (0 weekday, 1 weekend) and hour (UTC), observations and occupied
  /// ones, saturating at 255 (12 two-hour bins per kind of day).
  std::array<std::array<uint8_t, 12>, 2> hour_observed = {};
  std::array<std::array<uint8_t, 12>, 2> hour_occupied = {};
  /// Hits per voxel length of ray, summed over the counters of the observations (capped at 1e6;
  /// -1 in models saved before chronomap kept it: Combined then keeps the mean).
  float hits_per_voxel = -1.0f;
  /// Combined, for a voxel of a co-changing object whose pooled profile predicts it best: the
  /// object's index in RhythmModels::groups (kNoGroup: none), and a copy of that object's hour
  /// bins so that predict() needs only the voxel.
  static constexpr uint32_t kNoGroup = 0xffffffffu;
  uint32_t group = kNoGroup;
  std::array<std::array<uint16_t, 12>, 2> group_observed = {};
  std::array<std::array<uint16_t, 12>, 2> group_occupied = {};
};

/// A co-changing object's pooled hourly profile: the hour bins of its voxels summed
/// (observations and occupied ones, saturating at 65535).
struct RhythmGroup {
  std::array<std::array<uint16_t, 12>, 2> observed = {};
  std::array<std::array<uint16_t, 12>, 2> occupied = {};
};

/// How fitRhythm groups voxels into objects: two neighbouring unit voxels (sharing a face, an
/// edge or a corner) join when at least `min_common` sessions observed both and their states in
/// those sessions correlate at least `min_correlation` (phi coefficient); the connected
/// components of that relation with at least `min_voxels` voxels whose pooled hourly profile
/// beats their pooled mean (leave-one-out) are objects with a rhythm (a door's panel, a chair).
struct RhythmGroupSettings {
  bool enabled = true;
  uint32_t min_common = 6;
  double min_correlation = 0.5;
  uint32_t min_voxels = 3;
  /// An object has a rhythm when its pooled profile's leave-one-out Brier score is at most
  /// (1 - min_gain) times its pooled mean's.
  double min_gain = 0.5;
};

/// The fitted models of a map: one VoxelRhythm per cube that changed while learning, in the
/// map's traversal order, and what they were learned from.
struct RhythmModels {
  double resolution_m = 0.05;
  double from_s = 0.0, to_s = 0.0;  ///< the learning sessions' times
  uint32_t sessions = 0;            ///< learning sessions
  FittedOn fitted_on;               ///< their times and the map's fingerprint (fitRhythm())
  std::vector<VoxelRhythm> voxels;
  std::vector<RhythmGroup> groups;  ///< objects whose pooled profile some voxel's Combined uses

  /// Probability that the cube of `rhythm` is occupied at `time_s` under `model`.
  static double predict(const VoxelRhythm& rhythm, RhythmModel model, double time_s);
  /// The fitted cube containing `key`, or null (binary search: voxels are sorted by Morton code
  /// of their corners, which fit() guarantees).
  const VoxelRhythm* find(const VoxelKey& key) const;
  /// Bytes of a saved model (version 4): a 60-byte header and 8 bytes per recorded learning
  /// session's time, 105 bytes per cube, then an 8-byte group count and 96 bytes per group.
  /// Older versions: a 44-byte header without the fingerprint and times; 97 bytes per cube in
  /// version 1, 101 in version 2; no groups before version 3.
  static constexpr size_t kHeaderBytes = 60, kVoxelBytes = 105, kGroupBytes = 96;
  size_t bytes() const {
    return kHeaderBytes + 8 * fitted_on.times_s.size() + voxels.size() * kVoxelBytes + 8 + groups.size() * kGroupBytes;
  }
};

/// Fits every model to the observations of the sessions with times in [from_s, to_s], for the
/// cubes that changed at least `min_changes` times among them.
/// @throw UsageError when no session lies in the range, or min_changes is 0.
RhythmModels fitRhythm(const TemporalMap& map, double from_s, double to_s, uint32_t min_changes = 1,
                       const RhythmGroupSettings& grouping = {});
/// Fits the models of a set of cubes' observations (what fitRhythm does once it has them): each
/// cube alone, then the co-changing objects among them (`grouping`); sorted by Morton code.
RhythmModels fitSeries(const std::vector<VoxelSeries>& series, double voxel_m,
                       const RhythmGroupSettings& grouping = {});
/// Fits one cube's models to its observations (what fitRhythm does per cube); `voxel_m`: the
/// map's resolution (the unit voxel's edge), for the surface evidence.
VoxelRhythm fitVoxel(const VoxelSeries& series, double voxel_m = 0.05);
/// Combined's surface evidence of a cube: x² / (x² + x0²) as above; its mean when unknown.
double surfaceEvidence(const VoxelRhythm& rhythm);

/// The predicted map at `time_s`: the map as last observed then (TemporalMap::snapshot) with
/// every modelled voxel's counters replaced by one hit over the length that gives the model's
/// probability (P = 1 - exp(-hits / length)), coloured as it looked when last seen occupied.
/// Voxels without a model keep
/// their last observed state; unknown stays unknown.
/// Saved models belong to the map they were fitted on: check them first (checkFittedOn()).
/// @throw UsageError when the models' resolution differs from the map's (sameResolution()).
SessionMap predictMap(const TemporalMap& map, const RhythmModels& models, RhythmModel model, double time_s);



}  // namespace chronomap
