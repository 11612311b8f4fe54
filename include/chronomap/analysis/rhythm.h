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
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"
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

/// The fitted parameters of one cube: every model's, 101 bytes in a saved model.
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
};

/// The fitted models of a map: one VoxelRhythm per cube that changed while learning, in the
/// map's traversal order, and what they were learned from.
struct RhythmModels {
  double resolution_m = 0.05;
  double from_s = 0.0, to_s = 0.0;  ///< the learning sessions' times
  uint32_t sessions = 0;            ///< learning sessions
  std::vector<VoxelRhythm> voxels;

  /// Probability that the cube of `rhythm` is occupied at `time_s` under `model`.
  static double predict(const VoxelRhythm& rhythm, RhythmModel model, double time_s);
  /// The fitted cube containing `key`, or null (binary search: voxels are sorted by Morton code
  /// of their corners, which fit() guarantees).
  const VoxelRhythm* find(const VoxelKey& key) const;
  /// Bytes of a saved model: a 44-byte header and 101 bytes per cube (97 in version 1).
  static constexpr size_t kHeaderBytes = 44, kVoxelBytes = 101;
  size_t bytes() const { return kHeaderBytes + voxels.size() * kVoxelBytes; }
};

/// Fits every model to the observations of the sessions with times in [from_s, to_s], for the
/// cubes that changed at least `min_changes` times among them.
/// @throw UsageError when no session lies in the range, or min_changes is 0.
RhythmModels fitRhythm(const TemporalMap& map, double from_s, double to_s, uint32_t min_changes = 1);
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
/// @throw UsageError when the models' resolution differs from the map's.
SessionMap predictMap(const TemporalMap& map, const RhythmModels& models, RhythmModel model, double time_s);

/// Serialises fitted models (little-endian, versioned); deserialise is its inverse.
/// @throw FormatError naming `source` for bytes that are not a valid model.
std::vector<uint8_t> serialize(const RhythmModels& models);
RhythmModels deserializeRhythm(std::span<const uint8_t> bytes, const std::string& source);

}  // namespace chronomap
