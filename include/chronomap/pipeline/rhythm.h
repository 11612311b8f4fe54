#pragma once
/// @file
/// Workflows of the temporal models: where a command's models come from (fitted to a range of
/// sessions, or a saved .rhythm), and a costmap written as files.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <string>

#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// Where learnRhythm() takes the models from.
struct LearnSettings {
  std::optional<std::filesystem::path> saved;  ///< read this .rhythm instead of fitting
  std::optional<std::filesystem::path> save;   ///< also write the fitted models here
  double from_s = -std::numeric_limits<double>::infinity();  ///< learning sessions' times
  double to_s = std::numeric_limits<double>::infinity();
  bool range_given = false;  ///< from_s or to_s was set by the user
  uint32_t min_changes = 1;
  /// A saved model: how the map is named in messages, whether a model fitted on another map is
  /// used anyway (checkFittedOn()), and where warnings go (none when empty).
  std::string map_name = "the map";
  bool allow_other_map = false;
  std::function<void(const std::string& warning)> warn;
};

/// The models of `map`: read from `saved` and checked against the map (checkFittedOn(): fitted
/// on another map or at another resolution is refused, unless `allow_other_map`; a warning when
/// the file cannot tell), or fitted (fitRhythm) and written to `save` if set.
/// @throw UsageError for `saved` with a learning range or `save`, or not fitted on `map`; what
/// fitRhythm and the .rhythm reader and writer throw.
RhythmModels learnRhythm(const TemporalMap& map, const LearnSettings& settings);

/// Where learnColour() takes the colour model from.
struct ColourLearnSettings {
  std::optional<std::filesystem::path> saved;  ///< read this .colour instead of fitting
  std::optional<std::filesystem::path> save;   ///< also write the fitted model here
  double from_s = -std::numeric_limits<double>::infinity();  ///< learning sessions' times
  double to_s = std::numeric_limits<double>::infinity();
  bool range_given = false;  ///< from_s or to_s was set by the user
  ColourSettings fit;        ///< how a model is fitted (not used with `saved`)
  /// As LearnSettings: a saved model's check against the map.
  std::string map_name = "the map";
  bool allow_other_map = false;
  std::function<void(const std::string& warning)> warn;
};

/// The colour model of `map`: read from `saved` and checked against the map as learnRhythm()
/// checks a saved .rhythm, or fitted (fitColour) and written to `save` if set.
/// @throw UsageError for `saved` with a learning range or `save`, or not fitted on `map`; what
/// fitColour and the .colour reader and writer throw.
ColourModel learnColour(const TemporalMap& map, const ColourLearnSettings& settings);

/// The files of a costmap: the map_server YAML and, beside it, its PGM and a PNG picture.
struct CostmapFiles {
  std::filesystem::path yaml, pgm, png;
};
/// The file names for `yaml`. @throw UsageError when it does not end in .yaml.
CostmapFiles costmapFiles(const std::filesystem::path& yaml);

/// How many cells of a costmap are unknown, free (cost 0), costly, and blocked (inscribed or lethal).
struct CostmapCounts {
  size_t unknown = 0, free = 0, costly = 0, blocked = 0;
};
/// Writes `costmap` as `files` (writeMapServer and renderCostmap), each atomically.
/// @throw DataError naming `source` when the costmap is empty (nothing known in its band).
CostmapCounts writeCostmap(const CostmapFiles& files, const Costmap& costmap, const std::string& source);

}  // namespace chronomap
