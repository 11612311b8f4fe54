#pragma once
/// @file
/// The 4D map as an MCAP file that Foxglove plays as a time series (docs/foxglove.md): JSON
/// messages (message encoding "json") whose schemas are Foxglove's own JSON schemas (schema
/// encoding "jsonschema"), as @foxglove/schemas 2.1.0 publishes them.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/analysis/change_preset.h"
#include "chronomap/analysis/costmap.h"
#include "chronomap/core/counters.h"
#include "chronomap/export/mcap_writer.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// What exportFoxglove() writes and how.
struct FoxgloveSettings {
  std::string map_frame = "map";      ///< the frame every message is in
  std::string world_frame = "world";  ///< the parent of map_frame in /tf (an identity transform)
  /// The changed objects of each pair: findChanges() with these (the recommended settings, as
  /// every front door uses).
  ChangeSettings changes = recommendedChangeSettings();
  CostmapSettings costmap;  ///< the cost map of each session's state (no temporal models)
  /// Box colours by kind (the change pictures' appeared and vanished colours) and their opacity.
  Rgb appeared{20, 150, 40};
  Rgb vanished{210, 40, 30};
  Rgb moved{230, 150, 20};
  double box_alpha = 0.45;
  double label_font_size = 14.0;  ///< label text height in pixels (scale invariant)
  McapWriterSettings mcap;
};

/// The topics, in the order of their channels.
inline constexpr const char* kFoxgloveTransformTopic = "/tf";               ///< foxglove.FrameTransform
inline constexpr const char* kFoxgloveOccupiedTopic = "/map/occupied";      ///< foxglove.PointCloud
inline constexpr const char* kFoxgloveChangesTopic = "/map/changes";        ///< foxglove.SceneUpdate
inline constexpr const char* kFoxgloveCostmapTopic = "/map/costmap";        ///< foxglove.Grid

/// One topic of the file.
struct FoxgloveTopic {
  std::string topic;
  std::string schema;  ///< e.g. "foxglove.PointCloud"
  uint64_t messages = 0;
};

/// What exportFoxglove() wrote.
struct FoxgloveExport {
  std::vector<FoxgloveTopic> topics;
  size_t sessions = 0;
  uint64_t points = 0;   ///< occupied voxels, summed over the sessions
  uint64_t objects = 0;  ///< changed objects, summed over the pairs
  size_t bytes = 0;      ///< of the file
};

/// Writes `map` as an MCAP file: per session, at its time (log time and message timestamp), the
/// frame transform world -> map (/tf), the occupied voxels' centres in their observed mean colour
/// (/map/occupied: x, y, z float32 and red, green, blue, alpha uint8 per point) and the cost map
/// of its state (/map/costmap: one int8 field "cost", -1 unknown, 0 free .. 100 lethal, as
/// `chronomap costmap` writes); per pair of consecutive sessions, at the later one's time, the
/// changed objects findChanges() lists as labelled boxes (/map/changes: first a deletion of
/// the pair before's boxes, then one entity per object with its kind, voxels and, for a move, the
/// place it left and the distance in its metadata).
/// @throw UsageError for a map without sessions, a session before 1970 (MCAP times are unsigned
/// nanoseconds) or bad settings; IoError when the file cannot be written.
FoxgloveExport exportFoxglove(const std::filesystem::path& path, const TemporalMap& map,
                              const FoxgloveSettings& settings = {});

}  // namespace chronomap
