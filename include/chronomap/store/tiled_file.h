#pragma once
/// @file
/// A tiled 4D map on disk (docs/file-format.md, "Tiled 4D maps"): a folder holding `index.cmap`
/// (a .cmap of kind "tiled": the top of the octree, the sessions' table once, and the table of
/// tiles) and `tiles/X_Y_Z.cmap`, one 4D map per tile.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "chronomap/temporal/tiles.h"

namespace chronomap {

/// The index's file name inside a tiled map's folder.
inline constexpr const char* kTileIndexName = "index.cmap";
/// Version of the tile table inside the index's metadata (the .cmap container has its own):
/// the newest this build reads and writes. Version 2 adds a row's `sessions`: a tile that the
/// last runs of the streaming build did not reach keeps its file, which holds the first
/// `sessions` sessions of the index's table only (the later ones observed nothing there). A
/// table whose every tile holds every session is written as version 1, as before. Version 3
/// adds window files (a row's `windows`, the table's `window_sessions`); a table without them
/// keeps version 1's or 2's bytes. Version 4 is the windowed layout (TileIndex::windowed): a
/// row's `file` is the tile's open window and its `windows` the closed ones, each with the
/// number of sessions its file holds.
inline constexpr int kTileTableVersion = 4;
/// Sessions per window file (docs/file-format.md, "A tile's history windows"), as the writers
/// choose it when a folder does not record one: a snapshot of an older time reads one window,
/// whose entries grow with these sessions, not with the tile's whole history. 16: on a year of
/// one floor of the `site`, a room's snapshot at the middle of the year takes 1.4-1.7x the latest
/// one (6.8x without windows); the windows take 1.4x the histories' bytes (docs/scale.md).
inline constexpr uint32_t kDefaultWindowSessions = 16;
/// The oldest tile table version this build reads.
inline constexpr int kOldestTileTableVersion = 1;

/// A tile's state at the map's last session, kept beside its history (a session map file), so
/// that a snapshot of the latest time reads what it shows, not every session's entries.
struct LatestState {
  std::string file;     ///< latestFileName(the tile's file)
  uint64_t bytes = 0;   ///< size of the file
  uint32_t crc32 = 0;   ///< CRC-32 of the file
};

/// A window of a tile's history (temporal/window.h): historyWindow(tile, j * K, K) for the j-th
/// window of a table with K window sessions, written once, when the tile first held those sessions.
/// In the windowed layout (TileIndex::windowed) a closed window instead: one of the runs of
/// sessions the tile's history is kept as (temporal/window.h, joinWindows), named as a window or
/// as the tile file it was while it was open.
struct WindowFile {
  std::string file;     ///< windowFileName(a tile file name, j), or (windowed) a tile file name
  uint64_t bytes = 0;   ///< size of the file
  uint32_t crc32 = 0;   ///< CRC-32 of the file
  size_t sessions = 0;  ///< windowed layout: the sessions its file holds (0 otherwise)
};

/// One row of the tile table.
struct TileEntry {
  TileKey key;
  std::string file;     ///< relative to the folder: tiles/X_Y_Z.cmap (windowed: the open window)
  uint64_t bytes = 0;   ///< size of the tile's file
  uint32_t crc32 = 0;   ///< CRC-32 of the tile's file
  std::optional<LatestState> latest;  ///< absent in folders written before it existed
  /// Sessions the tile holds (its file; windowed: its windows, the open one up to this rank): the
  /// first ones of the index's table (the later ones did not reach the tile; readTile adds them
  /// as unobserved). At least 1. Absent: every session.
  std::optional<size_t> sessions;
  /// Its history's windows in time order: the j-th holds the sessions of rank [j * K, (j + 1) * K)
  /// for the table's K (TileIndex::window_sessions). Windows exist for whole runs of K sessions
  /// the tile holds, from the first on. Windowed layout: the closed windows (TileIndex::windowed).
  std::vector<WindowFile> windows;
  /// Bytes the tile takes on disk: its file, its latest state's and its windows'.
  uint64_t diskBytes() const {
    uint64_t n = bytes + (latest ? latest->bytes : 0);
    for (const WindowFile& w : windows) n += w.bytes;
    return n;
  }
};

/// A decoded tile index.
struct TileIndex {
  int tile_level = 0;
  /// Sessions per window file; 0 when the table records none (no tile has windows).
  uint32_t window_sessions = 0;
  TemporalMap top;               ///< see SplitMap::top
  std::vector<TileEntry> tiles;  ///< sorted by key
  /// The windowed layout (tile table version 4, docs/scale.md, "A tile as its windows"): each
  /// row's `file` is the tile's open window, holding the sessions from the last closed window's
  /// last one on (that one carried as its session 0; from the first session when there is no
  /// closed window), and its `windows` are the closed windows in time order, window j + 1's
  /// session 0 being window j's last session. A window closes once it holds window_sessions
  /// sessions of its own (the tile's first window: firstWindowSessions), at the start of the
  /// next run that reaches the tile. A night reads and writes the open window only; the whole
  /// history is joinWindows of them all.
  bool windowed = false;
  /// The row of tile `key`, or null when the map holds nothing there.
  const TileEntry* find(const TileKey& key) const;
};

/// Windowed layout: the rank, in the index's sessions, of the first session (the carried one when
/// it has closed windows) of `entry`'s open window.
size_t openWindowFirst(const TileEntry& entry);

/// Windowed layout: the sessions tile `key`'s first window holds before it closes, k plus a
/// share of k in [0, k) fixed by a hash of the key; later windows hold k of their own. The
/// tiles of a site, reached on the same nights, would otherwise all close their windows on the
/// same night and swing together, every night's work growing for k nights and then falling
/// back; staggered, the open windows a night reads hold about k / 2 sessions of their own on
/// average on every night after the first 2k. (Files of either rule read alike: the tile table
/// lists each closed window's sessions.)
/// @throw UsageError when k is 0 or above 65535 (the tile table's limit).
uint32_t firstWindowSessions(const TileKey& key, uint32_t k);

/// The file name a tile gets: tiles/X_Y_Z.cmap (tile coordinates, decimal), or, for a tile
/// written by the streaming build's generation `generation` > 0, tiles/X_Y_Z.gN.cmap (so that
/// new tiles never overwrite the files the current index names).
std::string tileFileName(const TileKey& key, uint64_t generation = 0);
/// The generation in a tile's file name when it is tileFileName(key, generation) for some
/// generation; nothing otherwise.
std::optional<uint64_t> tileGeneration(const TileKey& key, const std::string& file);
/// The generation of a tile's window file name (a tile file name, or one with `.wJ` before
/// `.cmap`). @throw UsageError for another name.
uint64_t windowGeneration(const TileKey& key, const std::string& file);
/// The file name of a tile's latest state: its file's name with `.latest` before `.cmap`.
std::string latestFileName(const std::string& tile_file);
/// The file name of a tile's j-th window: the name of the tile's file when the window was
/// written, with `.wJ` before `.cmap` (a window keeps its name when later generations rewrite
/// the tile).
std::string windowFileName(const std::string& tile_file, size_t j);

/// What writeTiledMap wrote.
struct TiledWriteResult {
  uint64_t index_bytes = 0;
  uint64_t tile_bytes = 0;  ///< all tiles together, their latest states and windows included
  size_t tiles = 0;
  size_t windows = 0;       ///< history windows written
};

/// Runs piece(k) for every k in [0, n), in any order or at once, each piece touching only its
/// own output; rethrows what a piece throws (the pipeline's runInOrder runs them on every core).
using ForEachPiece = std::function<void(size_t n, const std::function<void(size_t)>& piece)>;

/// Writes `split` into the folder `folder` as a whole (staged, then moved into place: an
/// error leaves the folder as it was). `meta` (a JSON object) is stored in the index.
/// Every tile gets its windows of `window_sessions` sessions (0: none); `windowed` writes the
/// windowed layout instead (each tile as writeTileAsWindows; window_sessions > 0). The tiles are
/// written through `for_each` (empty: one after another); the files do not depend on it.
TiledWriteResult writeTiledMap(const std::filesystem::path& folder, const SplitMap& split, const nlohmann::json& meta,
                               uint32_t window_sessions = kDefaultWindowSessions,
                               const ForEachPiece& for_each = {}, bool windowed = false);

/// Writes one tile's file (atomically) into the folder as tileFileName(key, generation), and
/// its latest state beside it. With `window_sessions` K > 0 the tile keeps the windows `kept`
/// (written before, for its first sessions) and gets those of the whole runs of K sessions
/// after them that it holds, written under this generation's names. @return its row of the
/// tile table.
TileEntry writeTileFile(const std::filesystem::path& folder, const TileKey& key, uint64_t generation,
                        const TemporalMap& tile, uint32_t window_sessions = 0, std::vector<WindowFile> kept = {});
/// The windowed layout's writers (TileIndex::windowed). writeOpenWindow writes `open` (a window
/// whose session 0 is `closed`'s last window's last session, or the first session when `closed`
/// is empty) as the tile's file tileFileName(key, generation), written as it is, and its latest
/// state beside it; the row keeps `closed`. writeTileAsWindows writes a whole history as windows
/// of `window_sessions` (windowsOf; the first of firstWindowSessions): all but the last closed,
/// under windowFileName(the tile's file, j), and the last as the open one.
TileEntry writeOpenWindow(const std::filesystem::path& folder, const TileKey& key, uint64_t generation,
                          const TemporalMap& open, std::vector<WindowFile> closed);
TileEntry writeTileAsWindows(const std::filesystem::path& folder, const TileKey& key, uint64_t generation,
                             const TemporalMap& tile, uint32_t window_sessions);
/// Windowed layout: `entry`'s open window as its file holds it (its sessions checked against the
/// index's, nothing appended). @throw IoError, FormatError as readTile.
TemporalMap readOpenWindow(const std::filesystem::path& folder, const TileIndex& index, const TileEntry& entry);
/// Windowed layout: tile `key`'s closed windows `closed` (from the first, in order) as their files
/// hold them, each checked likewise against the index's sessions from where it begins.
std::vector<TemporalMap> readClosedWindows(const std::filesystem::path& folder, const TileIndex& index,
                                           const TileKey& key, const std::vector<WindowFile>& closed);

/// Writes the index of a tiled map (atomically: the previous index stays until the rename).
/// A row whose `sessions` is below top.sessionCount() is written with it (table version 2);
/// rows with windows make it version 3, with `window_sessions` (which must then be > 0);
/// without either the table is version 1; `windowed` writes version 4 (TileIndex::windowed).
/// @return the bytes written.
uint64_t writeTileIndex(const std::filesystem::path& folder, const TemporalMap& top, int tile_level,
                        const std::vector<TileEntry>& tiles, const nlohmann::json& meta,
                        uint32_t window_sessions = 0, bool windowed = false);

/// Decodes an index file image. @throw FormatError naming `source`.
TileIndex decodeTileIndex(const std::vector<uint8_t>& bytes, const std::string& source);
/// Reads `folder`/index.cmap. @throw IoError, FormatError.
TileIndex readTileIndex(const std::filesystem::path& folder);
/// Reads one tile, checking its size and checksum against the index and that it fits it
/// (resolution, criterion, the sessions' times, nothing outside its cube). A tile whose file
/// holds only the first entry.sessions sessions gets the index's later ones appended as
/// unobserved (TemporalMap::appendUnobservedSessions): the map that rewriting it would store.
/// In the windowed layout the tile's windows are read, each checked so, and joined (joinWindows).
/// @throw IoError (missing file), FormatError naming the tile's file.
TemporalMap readTile(const std::filesystem::path& folder, const TileIndex& index, const TileEntry& entry);

/// readTile(...).snapshot(time_s), without building the tile: from the window holding that time
/// when the tile has one, else from its file; either is checked against the index as readTile
/// checks the tile (size, checksum, resolution, criterion, the sessions' times, nothing outside
/// its cube), then read at that one time (snapshotOfColumns: the entries valid then, not the
/// whole history). Files it does not cover (format version 1, appended sessions, a time before
/// the first session) are read by readTile.
/// @throw IoError (missing file), FormatError naming the tile's file.
/// `read_windows` false reads the tile's file even where a window holds the time.
/// Windowed layout (TileIndex::windowed): the time is read from the one window holding it (the
/// first closed one that does, else the open one), whatever `read_windows` says; where that
/// window merged carried free cubes, its free space without hits has other cubes and lengths
/// than readTile(...).snapshot(time_s) (the same states, hits, colours and positions).
SessionMap readTileSnapshot(const std::filesystem::path& folder, const TileIndex& index, const TileEntry& entry,
                            double time_s, bool read_windows = true);
/// True when readTileSnapshot reads `time_s` of the tile from one of its windows.
bool readsWindowAt(const TileIndex& index, const TileEntry& entry, double time_s);

/// Reads a tile's latest state (entry.latest must be set), checking its size and checksum
/// against the index and that it lies inside the tile's cube at the index's resolution.
/// @throw IoError (missing file), FormatError naming the file.
SessionMap readLatestState(const std::filesystem::path& folder, const TileIndex& index, const TileEntry& entry);

/// True when `path` is a folder holding an index.cmap.
bool isTiledMap(const std::filesystem::path& path);

/// The consensus of a tiled map's sessions, the streaming build's registration prior
/// (docs/scale.md, "Registration"): the sum (consensus()) of every session map streamed in since
/// it was started, one session after another in the order they were added. One session map file
/// in tiles/, in format version 1 (the counters exact), named by the index metadata's
/// kConsensusKey entry: {"file", "bytes", "crc32", "sessions"}.
struct StoredConsensus {
  SessionMap map;
  uint64_t sessions = 0;  ///< session maps summed into it
  std::string file;       ///< relative to the folder
};
inline constexpr const char* kConsensusKey = "consensus";
/// The file generation `generation`'s consensus is written to: tiles/consensus.gN.cmap.
std::string consensusFileName(uint64_t generation);
/// The generation of a consensus file name; nullopt for any other name.
std::optional<uint64_t> consensusGeneration(const std::string& file);
/// The consensus the index metadata `meta` names; nullopt when it names none.
/// @throw FormatError naming the file for a bad entry, one of another size, CRC-32 or resolution,
/// or what the session map reader finds; IoError for a missing file.
std::optional<StoredConsensus> readStoredConsensus(const std::filesystem::path& folder, const nlohmann::json& meta,
                                                   double resolution_m);
/// Writes `map` as generation `generation`'s consensus of `sessions` session maps; returns the
/// metadata entry naming it (kConsensusKey's value).
nlohmann::json writeStoredConsensus(const std::filesystem::path& folder, uint64_t generation, const SessionMap& map,
                                    uint64_t sessions);

}  // namespace chronomap
