#pragma once
/// @file
/// Map files as the command line names them: a session map, or a 4D map at a time
/// ("MAP.cmap@T"); snapshots and exports by file extension; the change frequency of a 4D map;
/// a diff, and its segmentation written out object by object.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "chronomap/analysis/change_frequency.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/store/cmap.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/pipeline/tiles.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// A session map file, or a 4D map file at a time.
struct MapRef {
  std::filesystem::path path;
  std::optional<double> time_s;
};

/// "FILE" or "FILE@TIME" (ISO-8601 or epoch seconds). A file whose own name holds '@' wins over
/// a time suffix. @throw UsageError for a bad time.
MapRef parseMapRef(const std::string& text);

/// The session map a reference names: the session file itself, or the 4D map's snapshot at the
/// time. @throw UsageError when a session map is given a time, a 4D map none, or the file holds
/// another kind of map.
SessionMap loadSessionMap(const MapRef& ref, const CmapFile& file);

/// What changed from `before` to `after`. Two times of one 4D map visit only what changed in
/// between; two times of one tiled map folder read its tiles through a cache under `cache`.
/// @throw UsageError when a tiled map is compared with anything but another time of itself.
DiffMap diffMaps(const MapRef& before, const MapRef& after, const DiffSettings& settings,
                 const TileCacheSettings& cache = {});

/// What changed from `before` to `after`, and which objects (analysis/changes.h): the diff of
/// diffMaps() with settings.diff, segmented and paired into moves as changesOf() does. The call
/// `chronomap diff` makes; the default is the recommended settings.
/// @throw UsageError as diffMaps() and for bad settings.
Changes changesBetween(const MapRef& before, const MapRef& after,
                       const ChangeSettings& settings = recommendedChangeSettings(),
                       const TileCacheSettings& cache = {});

/// The colour part of a diff between two times of one 4D map.
struct ColourDiffReport {
  ColourDiff diff;
  /// With settings.lighting_invariant: the light, learned from the sessions before the later
  /// time (so that a repaint at that time is not part of what it learned).
  std::optional<ColourModel> model;
};

/// The voxels occupied at both times whose colour moved by more than settings.distance (beyond
/// what the change of light explains, with settings.lighting_invariant). @throw UsageError unless
/// `before` and `after` are two times of one file, or for bad settings.
ColourDiffReport colourDiffMaps(const MapRef& before, const MapRef& after, const ColourDiffSettings& settings);

/// The 4D map's snapshot at `time_s`. @throw UsageError when no session lies at or before it.
SessionMap snapshotAt(const TemporalMap& map, double time_s, const std::string& name);

/// A map file as one state, for the exports that draw one (.ply, .ot, .png).
struct OneState {
  SessionMap map;
  std::optional<double> time_s;  ///< the 4D map's time that was taken; none for a session map
};
/// The session map file `path` as it is, or the 4D map file's snapshot at `time_s` (default:
/// its last session's time, the map as last observed).
/// @throw UsageError for a time given with a session map, a time before the 4D map's first
/// session, an empty 4D map, or another kind of file; what the readers throw.
OneState stateOfMap(const std::filesystem::path& path, std::optional<double> time_s);

/// A map file as a 4D map, for the viewer and the tour: a 4D map as it is, a session map as a
/// 4D map of that one session, at the time its file records (`recorded_at`; 1970-01-01T00:00:00Z
/// when it records none).
/// @throw UsageError for another kind of file; what the readers throw.
TemporalMap temporalMapOfFile(const std::filesystem::path& path);

/// How exportSessionMap() writes.
struct ExportSettings {
  int pixels_per_voxel = 2;  ///< .png
  nlohmann::json metadata;   ///< .cmap
};

/// Writes a session map in the format its extension names: .cmap (a session map), .ply
/// (occupied voxel centres), .ot (OctoMap ColorOcTree), .png (top view).
/// @return the elements written (leaves, points, OctoMap leaves or pixels).
/// @throw UsageError for another extension.
size_t exportSessionMap(const std::filesystem::path& path, const SessionMap& map, const ExportSettings& settings = {});

/// The voxels of `frequency` as a PLY of their centres, coloured blue (min_changes changes) to
/// red (the most). @return the points written.
size_t writeChangeFrequencyPly(const std::filesystem::path& path, const TemporalMap& map,
                               const ChangeFrequency& frequency, uint32_t min_changes);

/// A segmentation as JSON: every component's fields, the dropped count, the connectivity.
nlohmann::json segmentationJson(const Segmentation& segmentation, const SegmentSettings& settings);

/// Writes each component of `segmentation` as its own diff (.cmap) and PLY at the original
/// coordinates into `folder` (component_NNNN.*), and `summary` as components.json.
void writeComponents(const std::filesystem::path& folder, const DiffMap& diff, const Segmentation& segmentation,
                     const std::string& source, const nlohmann::json& summary);

}  // namespace chronomap
