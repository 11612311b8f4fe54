#pragma once
/// @file
/// What a saved model was fitted on, so that it is used only with that map: the learning
/// sessions' times and a fingerprint of the map over them (docs/rhythm.md, "A model belongs to
/// its map"). The rhythm (`.rhythm`) and colour (`.colour`) models both record it.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

struct RhythmModels;
struct ColourModel;

/// The map a model was fitted on, beyond its resolution and learning range.
struct FittedOn {
  /// The learning sessions' times, increasing (empty when not recorded).
  std::vector<double> times_s;
  /// mapFingerprint() over those sessions; 0 when not recorded (a model saved before chronomap
  /// recorded it, .rhythm before version 4 and .colour before version 2, or fitted without a map).
  uint64_t fingerprint = 0;
  bool recorded() const { return fingerprint != 0; }
};

/// A fingerprint of `map` over its sessions at `times_s`: FNV-1a (64 bits, never 0) over the
/// resolution and, per session, its time and the voxels it observed (its Coverage, as runs of
/// Morton codes). The voxels a session observed are stored exactly in every file version, so the
/// fingerprint survives saving, reading, compaction, tiling and sessions added later; it changes
/// when a session is replaced by one that observed other voxels, or the map was built at another
/// place or origin. std::nullopt when a time is not one of the map's sessions.
std::optional<uint64_t> mapFingerprint(const TemporalMap& map, std::span<const double> times_s);

/// What a model fitted on the sessions of `map` with times in [from_s, to_s] records.
FittedOn fittedOn(const TemporalMap& map, double from_s, double to_s);

/// True when two resolutions are the same for keys: within a relative 1e-9 (a key 65 535 voxels
/// from the origin moves by less than 1e-4 voxel).
bool sameResolution(double a_m, double b_m);

/// How checkFittedOn names things and what it allows.
struct FittedOnCheck {
  std::string model_name;  ///< the model (its file), for messages
  std::string map_name;    ///< the map (its file), for messages
  /// What a person can do instead, ending every refusal ("leave out --rhythm to fit ...").
  std::string refit;
  /// The flag that sets allow_other_map, offered when another map is refused ("" none).
  std::string allow_flag;
  /// A model of other sessions or another fingerprint is used with a warning instead of refused
  /// (a map rebuilt from the same recordings, say). Another resolution is always refused.
  bool allow_other_map = false;
};

/// Checks that a saved model belongs to `map`: the same resolution, every learning session a
/// session of the map, and the same fingerprint over them. A model that records no fingerprint
/// (older files) is checked by its resolution and its first and last learning sessions' times.
/// @return a warning for people ("" when none): the model could not be checked in full, or it
/// was fitted on another map and `allow_other_map` lets it through.
/// @throw UsageError naming both the model's and the map's facts and the way out.
std::string checkFittedOn(const RhythmModels& models, const TemporalMap& map, const FittedOnCheck& check);
std::string checkFittedOn(const ColourModel& model, const TemporalMap& map, const FittedOnCheck& check);

}  // namespace chronomap
