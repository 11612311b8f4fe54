#pragma once
/// @file
/// Tiled 4D maps (docs/scale.md): cutting a 4D map file into a folder of tiles and joining it
/// back, and asking a tiled map (snapshot of a region or of everything, history, diff, the
/// segmentation of a diff) through a cache that reads tiles lazily under a memory budget.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <list>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/io/tiled_file.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"
#include "chronomap/temporal/tiles.h"

namespace chronomap::pipeline {

/// The tile edge tileMap() uses unless told: 128 voxels (6.4 m at 5 cm), about a room.
inline constexpr int kDefaultTileLevel = 7;

/// The tile level whose edge is `tile_size_m` at `resolution_m`.
/// @throw UsageError unless the edge is a power-of-two number of voxels in
/// [2^kMinTileLevel, 2^kMaxTileLevel] (the message names the nearest valid sizes).
int tileLevelFor(double tile_size_m, double resolution_m);

/// What tileMap() does.
struct TileSettings {
  std::filesystem::path map;     ///< the 4D map (.cmap) to cut
  std::filesystem::path folder;  ///< the tiled map to write (replaced as a whole)
  /// Tile edge in metres; unset: 2^kDefaultTileLevel voxels.
  std::optional<double> tile_size_m;
};

/// What tileMap() wrote.
struct TileResult {
  int tile_level = 0;
  double tile_size_m = 0.0;
  size_t tiles = 0;
  size_t top_lists = 0;  ///< uniform cubes of tile size or larger, kept in the index
  uint64_t index_bytes = 0;
  uint64_t tile_bytes = 0;
  uint64_t map_bytes = 0;  ///< the input file
};

/// Cuts a 4D map file into a tiled map folder. @throw UsageError for a bad tile size, an
/// output that names the input; what the readers throw.
TileResult tileMap(const TileSettings& settings);

/// Joins a tiled map folder back into one 4D map file (written atomically): the map that was
/// cut, compacted as every written 4D map is. @throw what the readers throw (a missing or
/// corrupt tile, an index that does not match its tiles).
/// @return the sessions of the map written.
size_t untileMap(const std::filesystem::path& folder, const std::filesystem::path& map);

/// How TiledMap holds tiles.
struct TileCacheSettings {
  /// Most bytes of tiles (TemporalMap::memoryBytes) held at once; the least recently used
  /// tiles are dropped whole to make room. 0: no limit. A single tile larger than the limit is
  /// still read, and held alone.
  size_t memory_limit_bytes = size_t{1} << 30;
};

/// The cache's own accounting.
struct TileCacheStats {
  size_t loads = 0;      ///< tiles read from disk
  size_t latest_reads = 0;  ///< latest states read from disk (snapshots of the last session's time)
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

  const io::TileIndex& index() const { return index_; }
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
  /// kept in the cache).
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
  io::TileIndex index_;
  std::map<TileKey, Held> held_;
  std::list<TileKey> lru_;
  TileCacheStats stats_;
};

/// A folder holding a tiled map (io::isTiledMap).
bool isTiledMapFolder(const std::filesystem::path& path);

/// TiledMap::snapshot with snapshotAt's check. @throw UsageError when no session lies at or
/// before the time.
SessionMap tiledSnapshotAt(TiledMap& map, double time_s, const std::optional<VoxelBox>& box, const std::string& name);

/// The objects that changed between two times of a tiled map: the diff's cells gathered from
/// every tile the box meets, then segmented as one diff, so that an object across a tile
/// border is one component.
Segmentation segmentTiledDiff(TiledMap& map, double t1_s, double t2_s, const DiffSettings& diff_settings,
                              const SegmentSettings& segment_settings, const std::optional<VoxelBox>& box = {},
                              DiffMap* diff_out = nullptr);

/// A box in metres (map frame): lower and upper corner.
using BoxMetres = std::pair<Eigen::Vector3d, Eigen::Vector3d>;

/// A snapshot read from a 4D map file or a tiled map folder.
struct MapSnapshot {
  SessionMap map;
  std::optional<TileCacheStats> tiles;  ///< for a tiled map: what its cache did
};
/// The snapshot at `time_s` of the 4D map file or tiled map folder `path`; with `box_m` (tiled
/// maps only) the tiles that meet the box. @throw UsageError when no session lies at or before
/// the time, or for a box on an untiled map; what the readers throw.
MapSnapshot snapshotOfMap(const std::filesystem::path& path, double time_s, const std::optional<BoxMetres>& box_m,
                          const TileCacheSettings& cache = {});

/// The history of the voxel that holds a point, from a 4D map file or a tiled map folder.
struct VoxelHistory {
  VoxelKey key;
  Eigen::Vector3d center_m = Eigen::Vector3d::Zero();
  std::vector<HistoryEntry> entries;
  size_t sessions = 0;  ///< in the map
  std::optional<TileCacheStats> tiles;
};
/// @throw UsageError when the point lies outside the map; what the readers throw.
VoxelHistory historyOfMap(const std::filesystem::path& path, const Eigen::Vector3d& point_m,
                          const TileCacheSettings& cache = {});

}  // namespace chronomap::pipeline
