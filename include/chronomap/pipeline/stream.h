#pragma once
/// @file
/// The streaming build of a tiled 4D map (docs/scale.md, "Streaming build"): sessions are cut
/// to the tile grid as they are integrated (their parts held under a memory budget, spilled to
/// disk beyond it), then each tile, or each group of tiles that a uniform cube above tile level
/// ties together, is read, has the sessions added in time order, and is written under new file
/// names; the tiles no new session reached keep their files (the index records how many
/// sessions each holds); the index is swapped in last. The result reads as the tiled map that
/// building the whole map then `tile` would give, byte for byte after `untile`, while memory
/// holds one session map, the budget's parts and one group of tiles per thread
/// (StreamSettings::threads).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "chronomap/octree/session_map.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// One session for streamIntoTiles.
struct StreamSession {
  double time_s = 0.0;
  std::string name;
  SessionMap map;
};

/// What streamIntoTiles does.
struct StreamSettings {
  std::filesystem::path folder;  ///< the tiled map, created when missing
  double resolution_m = 0.05;    ///< for a new map (an existing one must have it)
  ChangeCriterion criterion;     ///< for a new map
  /// Tile edge in metres for a new map (unset: 2^kDefaultTileLevel voxels); an existing map
  /// keeps its own, and a different size given is refused.
  std::optional<double> tile_size_m;
  /// Most bytes of session parts held in memory before they are spilled to files in the
  /// folder (then read back one group at a time). 0: no limit.
  size_t memory_limit_bytes = size_t{1} << 30;
  /// Added to the index's metadata (the up axis of the sessions, ChosenUp::metadata).
  nlohmann::json metadata = nlohmann::json::object();
  /// Sessions per window file of a tile's history (store/tiled_file.h): a rewritten tile gets
  /// the windows of the runs of this many sessions it holds whole. A map that records a count
  /// keeps it. 0: none written (the windows a map has are kept).
  uint32_t window_sessions = kDefaultWindowSessions;
  /// A new map keeps each tile as windows of window_sessions sessions (TileIndex::windowed), of
  /// which a night reads and writes the open one only; an existing map keeps its layout.
  bool windowed_tiles = false;
  /// Start the consensus of the map's sessions (store/tiled_file.h, StoredConsensus) when the
  /// map keeps none: the streaming build's registration does. A map that keeps one has every
  /// session added to it, whatever this says.
  bool keep_consensus = false;
  /// With keep_consensus, what the consensus starts from when the map keeps none (moved from;
  /// the streaming build's consensusOfTiles() for a folder that had none), else empty.
  std::shared_ptr<StoredConsensus> first_consensus;
  /// Groups of tiles read, added to and written at once, each on its own thread (memory then
  /// holds up to this many groups); 0: one per core. The files do not depend on it.
  int threads = 0;
  Progress progress;
};

/// The budget's own accounting and what the build did.
struct StreamStats {
  size_t groups = 0;            ///< tiles or groups of tiles processed
  size_t largest_group_tiles = 0;
  size_t tiles_read = 0;
  size_t tiles_written = 0;     ///< tiles the new sessions reached, rewritten
  size_t tiles_kept = 0;        ///< tiles no new session reached: their files kept, not read
  size_t windows_written = 0;   ///< window files written (the rewritten tiles' new whole runs of sessions)
  size_t spills = 0;               ///< times the parts were written out to make room
  uint64_t spilled_bytes = 0;
  size_t peak_parts_bytes = 0;     ///< most bytes of session parts held at once (<= the limit)
  size_t peak_group_bytes = 0;     ///< largest working map (a group's tiles and sessions)
};

/// What streamIntoTiles did.
struct StreamResult {
  bool created = false;
  int tile_level = 0;
  size_t sessions = 0;  ///< in the map now
  size_t tiles = 0;     ///< in the map now
  uint64_t index_bytes = 0;
  uint64_t tile_bytes = 0;
  std::vector<double> added_times;      ///< in time order
  std::vector<int64_t> nodes_added;     ///< per added session, as TemporalMap::add counts them
  /// streamBuild with registration: each added session's correction, in time order (else empty).
  std::vector<PoseCorrection> corrections;
  StreamStats stats;
  /// streamBuild: the limits that dropped many points, "DATASET: what" (IntegratedSession::warnings).
  std::vector<std::string> warnings;
  /// Session maps summed into the map's stored consensus now (0: the map keeps none).
  uint64_t consensus_sessions = 0;
};

/// Adds `count` sessions, made one at a time by `produce(i)`, to the tiled map in
/// `settings.folder`. Sessions must come after the map's last session (in any order among
/// themselves) at distinct times. Holds the folder's lock; a failure (or a kill) at any point
/// leaves the previous tiled map readable and unchanged.
/// @throw UsageError for clashing or earlier times, another resolution or tile size, a folder
/// that is not a tiled map; what the readers throw.
StreamResult streamIntoTiles(const StreamSettings& settings, size_t count,
                             const std::function<StreamSession(size_t)>& produce);

/// The consensus of a tiled map's stored sessions computed from their histories: the 4D map's
/// consensus over all its sessions (consensus(map, t0, t1), as `build MAP.cmap --register`
/// takes it), summed tile by tile, so that one tile's history is in memory at a time beside the
/// parts. Every tile is read once, on up to `threads` threads (0: one per core; one tile's history
/// in memory per thread). Empty for a map without sessions.
/// @throw what the tile readers throw (the first unreadable tile's error in the index's order).
SessionMap consensusOfTiles(const std::filesystem::path& folder, int threads = 0);

/// build() into a tiled map folder: each recording integrated and cut to the tiles in turn,
/// then streamIntoTiles. With registration, every recording is integrated and registered first
/// (their session maps held together, as build() holds them), as build() registers: against the
/// consensus of them all, joined by the consensus of the stored sessions when the map keeps one
/// (StoredConsensus; registerSessions' prior); a map that keeps none gets one from its histories
/// (consensusOfTiles), stored from then on. Re-alignment
/// and replacing are not supported (they need the stored map at once).
/// @throw UsageError for them; what build() throws.
/// `windowed_tiles`: a new map keeps its tiles as windows (StreamSettings::windowed_tiles).
StreamResult streamBuild(const BuildSettings& settings, std::optional<double> tile_size_m, size_t memory_limit_bytes,
                         uint32_t window_sessions = kDefaultWindowSessions, bool windowed_tiles = false);

/// addSession() into an existing tiled map folder: the session map file streamed in
/// (streamIntoTiles), at the time given or the one its file records.
/// @throw UsageError for replace, re-alignment or a write policy other than Auto, a time that is
/// neither given nor recorded; what streamIntoTiles throws.
StreamResult streamAddSession(const AddSessionSettings& settings, size_t memory_limit_bytes);

}  // namespace chronomap
