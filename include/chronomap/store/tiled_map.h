#pragma once
// A tiled 4D map opened for queries: its index in memory, its tiles read on demand and kept in
// an LRU cache under a memory limit (docs/scale.md). The format is store/tiled_file.h's.

#include <cstddef>
#include <filesystem>
#include <list>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "chronomap/analysis/diff.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/temporal/temporal_map.h"
#include "chronomap/temporal/tiles.h"

namespace chronomap {

/// How TiledMap holds tiles.
struct TileCacheSettings {
  /// Most bytes of tiles (TemporalMap::memoryBytes) held at once; the least recently used
  /// tiles are dropped whole to make room. 0: no limit. A single tile larger than the limit is
  /// still read, and held alone.
  size_t memory_limit_bytes = size_t{1} << 30;
  /// Read an older time of a tile from its history window when it has one (store/tiled_file.h);
  /// false: from the tile's file, as before windows existed (the same answer; for benchmarks).
  /// A windowed folder has no other file to read: its windows are read either way, and a tile
  /// held in the cache answers from its joined history (readTileSnapshot says what may differ).
  bool read_windows = true;
};

/// The cache's own accounting.
struct TileCacheStats {
  size_t loads = 0;      ///< tiles read from disk
  size_t latest_reads = 0;  ///< latest states read from disk (snapshots of the last session's time)
  size_t time_reads = 0;    ///< tiles read at one earlier time (snapshots), not held
  size_t window_reads = 0;  ///< of those, read from a history window
  size_t hits = 0;       ///< requests answered by a tile already held
  size_t evictions = 0;  ///< tiles dropped to stay under the limit
  size_t resident_bytes = 0;
  size_t resident_tiles = 0;
  size_t peak_resident_bytes = 0;
  size_t peak_resident_tiles = 0;
};

/// An inclusive box of voxel keys.
struct VoxelBox {
  VoxelKey min, max;
  /// True when the cube at `corner` of 2^level voxels per axis meets the box.
  bool meets(const VoxelKey& corner, int level) const;
};

/// The voxels of the box between two points in metres (map frame). @throw UsageError when a
/// corner lies outside the map or min exceeds max on an axis.
VoxelBox voxelBoxOf(const KeyGrid& grid, const Eigen::Vector3d& min_m, const Eigen::Vector3d& max_m);

/// A tiled map folder, opened for queries: the index is read at once, the tiles when a query
/// needs them, through an LRU cache under TileCacheSettings::memory_limit_bytes. Queries answer
/// exactly as the joined map would. Not thread-safe (the cache is shared state).
class TiledMap {
 public:
  /// @throw IoError, FormatError from the index.
  explicit TiledMap(const std::filesystem::path& folder, TileCacheSettings settings = {});

  const TileIndex& index() const { return index_; }
  int tileLevel() const { return index_.tile_level; }
  const KeyGrid& grid() const { return index_.top.grid(); }
  double resolution_m() const { return index_.top.resolution_m(); }
  /// The sessions' full table (as the joined map's sessions()).
  const std::vector<SessionRecord>& sessions() const { return index_.top.sessions(); }
  const TileCacheStats& cacheStats() const { return stats_; }
  /// Bytes the index (the top of the tree and the sessions' table) holds, outside the cache.
  size_t indexBytes() const { return index_.top.memoryBytes(); }

  /// Tile `key` through the cache, or null when the map holds nothing there.
  /// @throw IoError, FormatError for a missing or corrupt tile.
  std::shared_ptr<const TemporalMap> tile(const TileKey& key);
  /// The listed tiles that meet `box` (every tile without one), in key order.
  std::vector<TileKey> tilesMeeting(const std::optional<VoxelBox>& box) const;

  /// The snapshot at `time_s` (TemporalMap::snapshot) of the tiles and uniform cubes that meet
  /// `box`, or of everything. Every voxel in the box reads as in the joined map's snapshot;
  /// without a box the result is that snapshot, bit for bit. At or after the last session's
  /// time a tile not held reads its latest state instead of its history (the same voxels; not
  /// kept in the cache); before it, a tile not held is read at that time alone
  /// (readTileSnapshot: the entries valid then, not the tile's whole history; not kept either).
  SessionMap snapshot(double time_s, const std::optional<VoxelBox>& box = {});
  /// TemporalMap::history of the voxel: one tile read at most.
  std::vector<HistoryEntry> history(const VoxelKey& key);
  /// TemporalMap::valueAt of the voxel.
  std::optional<VoxelCounters> valueAt(const VoxelKey& key, double time_s);
  /// The diff between two times (diff(TemporalMap, ...)) of the cells that meet `box`, or of
  /// everything: then equal to the joined map's diff. The neighbourhood rule reads across tile
  /// borders through the cache. The dark-surface rule judges the objects the box's cells form
  /// (an object cut by the box is judged by its part inside).
  DiffMap diff(double t1_s, double t2_s, const DiffSettings& settings, const std::optional<VoxelBox>& box = {});

 private:
  struct Held {
    std::shared_ptr<const TemporalMap> map;
    size_t bytes = 0;
    std::list<TileKey>::iterator lru;  // position in lru_ (front: most recent)
  };
  void evictFor(size_t bytes);

  std::filesystem::path folder_;
  TileCacheSettings settings_;
  TileIndex index_;
  std::map<TileKey, Held> held_;
  std::list<TileKey> lru_;
  TileCacheStats stats_;
};

}  // namespace chronomap
