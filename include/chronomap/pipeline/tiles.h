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
#include "chronomap/store/tiled_file.h"
#include "chronomap/store/tiled_map.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"
#include "chronomap/temporal/tiles.h"

namespace chronomap {

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
  /// Sessions per window file of each tile's history (store/tiled_file.h); 0: none.
  uint32_t window_sessions = kDefaultWindowSessions;
  /// Keep each tile as windows of window_sessions sessions (TileIndex::windowed).
  bool windowed_tiles = false;
};

/// What tileMap() wrote.
struct TileResult {
  int tile_level = 0;
  double tile_size_m = 0.0;
  size_t tiles = 0;
  size_t top_lists = 0;  ///< uniform cubes of tile size or larger, kept in the index
  uint64_t index_bytes = 0;
  uint64_t tile_bytes = 0;  ///< latest states and history windows included
  uint64_t map_bytes = 0;  ///< the input file
  size_t windows = 0;      ///< history windows written
};

/// Cuts a 4D map file into a tiled map folder. @throw UsageError for a bad tile size, an
/// output that names the input; what the readers throw.
TileResult tileMap(const TileSettings& settings);

/// Joins a tiled map folder back into one 4D map file (written atomically): the map that was
/// cut, compacted as every written 4D map is. @throw what the readers throw (a missing or
/// corrupt tile, an index that does not match its tiles).
/// @return the sessions of the map written.
size_t untileMap(const std::filesystem::path& folder, const std::filesystem::path& map);

/// A folder holding a tiled map (isTiledMap).
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

}  // namespace chronomap
