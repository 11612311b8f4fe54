#pragma once
/// @file
/// Colour by time of day (thesis §3.3): how each surface's colour depends on the hour, learned
/// from the colour changes a 4D map keeps (ChangeCriterion::colour_distance), and a colour
/// comparison that a change of light does not fool.
///
/// The model: a voxel's colour at hour h, per channel c, is
///   colour_c(v, h) = sum_j A[v, j, c] * L[j, c](h),   j = 0 .. components - 1,
/// a few illumination curves L shared by the whole map (per channel, piecewise linear over
/// `bins` knots per day, circular) and per voxel the weights A: with one component, A is the
/// voxel's albedo under one light; with two, a voxel mixes two lights (the lamps and the
/// daylight through the windows, in a proportion that depends on where it is). Fitted by
/// alternating least squares: the weights of each voxel given the curves (a tiny normal
/// system), then the curves given the weights (one normal system of components x bins unknowns
/// per channel, with a smoothness penalty between neighbouring knots so that hours never
/// observed follow their neighbours). Each curve is scaled to a largest value of 1 after each
/// round; the weights carry the scale.
///
/// Observations: every session of the learning range whose coverage holds the voxel while the
/// stored state is occupied with hits gives the stored mean colour at that session's hour. A
/// session that confirmed the state within the colour distance stored nothing, so its colour is
/// the last stored one: good to the map's colour distance.
///
/// Hours are of the UTC clock (as the 4D map's times; the simulator's schedule is UTC).

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "chronomap/analysis/fitted_on.h"
#include "chronomap/core/counters.h"
#include "chronomap/core/key.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/core/time.h"  // hourOfDay
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// One observed colour of one voxel (channels 0..255).
struct ColourObservation {
  uint32_t voxel = 0;  ///< index of the voxel in the caller's list
  double hour = 0.0;   ///< 0 <= hour < 24
  std::array<double, 3> rgb{};
};

/// How the colour model is fitted.
struct ColourSettings {
  int components = 2;         ///< illumination curves shared by the map (1..3)
  int bins = 24;              ///< knots per day of each curve (2..96)
  int iterations = 40;        ///< rounds of alternating least squares
  double smoothness = 0.05;   ///< weight of (L[i] - L[i+1])^2 per observation and knot
  size_t max_fit_voxels = 20000;  ///< the curves are fitted on at most this many voxels (evenly spread)
  /// @throw UsageError for values outside the ranges above.
  void validate() const;
};

/// A fitted colour model.
struct ColourModel {
  int components = 0, bins = 0;
  /// curves[(j * 3 + c) * bins + i]: component j, channel c, at knot i (hour i * 24 / bins).
  std::vector<double> curves;
  /// The modelled voxels in Morton order, and per voxel components * 3 weights
  /// (weights[(v * components + j) * 3 + c]).
  std::vector<VoxelKey> keys;
  std::vector<float> weights;
  double from_s = 0.0, to_s = 0.0;  ///< the learning range's first and last session
  size_t sessions = 0;              ///< sessions learned from
  size_t observations = 0;          ///< colour observations used
  double rms_error = 0.0;           ///< RMS of the fit over those observations, per channel, 8-bit units
  double resolution_m = 0.0;        ///< of the map it was learned from (fitColour()); 0: not from a map
  FittedOn fitted_on;               ///< the learning sessions' times and the map's fingerprint (fitColour())

  /// Curve j, channel c at `hour` (any real: taken modulo 24).
  double curve(int j, int c, double hour) const;
  /// The colour of voxel index v at `hour` (channels, not clamped).
  std::array<double, 3> predict(size_t v, double hour) const;
  /// The colour the whole map's mean weights give at `hour` (for voxels without a model).
  std::array<double, 3> predictMean(double hour) const;
  /// Index of `key` in keys, if modelled.
  std::optional<size_t> find(const VoxelKey& key) const;
  /// Stored bytes per voxel: its key (6 bytes) and its weights as 32-bit floats.
  size_t bytesPerVoxel() const { return 6 + 4 * 3 * static_cast<size_t>(components); }
  /// Stored bytes in all: the voxels and the curves.
  size_t bytes() const { return keys.size() * bytesPerVoxel() + 8 * curves.size(); }
};



/// Fits the curves and weights of `voxels` voxels to observations (any order).
/// @throw UsageError for bad settings; DataError when there is no observation, a voxel index
/// out of range, or a colour or hour that is not finite or out of range.
ColourModel fitColourObservations(std::span<const ColourObservation> observations, size_t voxels,
                                  const ColourSettings& settings);

/// The colour observations of the unit voxels of `map` by the sessions with times in
/// [from_s, to_s], with the voxels they index (Morton order). Only voxels with at least
/// `min_observations` observations.
struct ColourData {
  std::vector<VoxelKey> keys;
  std::vector<ColourObservation> observations;
  size_t sessions = 0;
  double from_s = 0.0, to_s = 0.0;
};
/// @throw UsageError when the map keeps no colour changes (created without a colour distance),
/// or when no session lies in the range; DataError when no voxel holds colour.
ColourData colourObservations(const TemporalMap& map, double from_s, double to_s, size_t min_observations = 2);

/// colourObservations() then fitColourObservations(): the model of a map's colours.
ColourModel fitColour(const TemporalMap& map, double from_s, double to_s, const ColourSettings& settings = {});

/// `map` (a session map, e.g. a snapshot or a prediction) with the colour of every voxel that
/// has hits and a model replaced by the model's colour at the hour of `time_s` (clamped to
/// 0..255); other voxels keep theirs.
/// @throw UsageError for a time that is not finite.
SessionMap recolour(const SessionMap& map, const ColourModel& model, double time_s);

/// How colours are compared between two times of a 4D map.
struct ColourDiffSettings {
  double distance = 40.0;           ///< a colour change: farther than this (8-bit RGB units)
  bool lighting_invariant = false;  ///< discount the change of light between the two hours
  /// @throw UsageError for a distance that is not finite or not positive.
  void validate() const;
};

/// One voxel occupied with hits at both times whose colour changed.
struct ColourChange {
  VoxelKey key;
  Rgb before, after;
  /// What the light alone makes of `before` at the second hour (lighting-invariant test), else
  /// `before`.
  Rgb expected;
  float distance = 0.0f;  ///< from `after` to `expected` (in the brighter hour's light)
};

/// What colourChanges() compared.
struct ColourDiff {
  size_t compared = 0;  ///< voxels occupied with hits at both times, observed anew in between
  std::vector<ColourChange> changes;
};

/// The light alone: is `after` (at hour h2) what `before` (at hour h1) becomes when the light
/// changes by `gain` (per channel, colour at h2 over colour at h1)? Compared in the brighter
/// hour's light (the darker colour scaled up), less the slack that the colours' own uncertainty
/// allows: `uncertainty` (8-bit RGB distance, e.g. rounding plus the 4D map's colour distance, by
/// which a stored colour may lag the observed one) on the brighter side, and the same scaled by
/// the largest gain on the darker side. Returns that distance (never negative) and the expected
/// colour `before` x gain.
std::pair<double, Rgb> lightingDistance(const Rgb& before, const Rgb& after, const std::array<double, 3>& gain,
                                        double uncertainty = 0.87);

/// The voxels of `map` whose colour changed from time t1 to time t2: the states valid then, each
/// seen at the hour of the last session up to that time that observed the voxel (its coverage);
/// a voxel that no session observed between the two is not compared. With
/// settings.lighting_invariant, a change the model's light explains is none: each voxel's
/// expected colour is its colour at t1 times its model's colour at the second observation's hour
/// over that at the first's (the map's mean model for voxels without one), compared by lightingDistance() with
/// the uncertainty of the map's stored colours: its colour distance plus rounding. A night's
/// colours are so dark that, scaled up to daylight, that uncertainty is large: between a night
/// and a day only large changes count.
/// @throw UsageError for times that are not finite or before the map's first session, a
/// lighting-invariant diff without a model, or bad settings.
ColourDiff colourChanges(const TemporalMap& map, double t1_s, double t2_s, const ColourModel* model,
                         const ColourDiffSettings& settings);

}  // namespace chronomap
