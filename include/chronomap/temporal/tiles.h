#pragma once
/// @file
/// A 4D map cut into tiles: a fixed grid of aligned cubes of 2^tile_level voxels per axis, each
/// an independent TemporalMap holding the part of the octree inside it, and a "top" map holding
/// the rest: the inner nodes above tile level and the uniform known-free cubes of tile size or
/// larger (which a tile cannot hold without splitting their history). Splitting and joining are
/// exact: join(split(m)) == m for a compacted m (docs/scale.md).

#include <cstdint>
#include <vector>

#include "chronomap/core/key.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// The smallest and largest tile level (2^level voxels per tile edge).
inline constexpr int kMinTileLevel = 1;
inline constexpr int kMaxTileLevel = kTreeDepth - 1;

/// Position of a tile in the tile grid: a voxel key shifted right by the tile level.
struct TileKey {
  uint16_t x = 0, y = 0, z = 0;
  friend bool operator==(const TileKey&, const TileKey&) = default;
  friend auto operator<=>(const TileKey&, const TileKey&) = default;
};

/// The tile that holds the voxel `key`.
constexpr TileKey tileOf(const VoxelKey& key, int tile_level) {
  return TileKey{static_cast<uint16_t>(key.x >> tile_level), static_cast<uint16_t>(key.y >> tile_level),
                 static_cast<uint16_t>(key.z >> tile_level)};
}
/// The lowest voxel of tile `t`.
constexpr VoxelKey tileCorner(const TileKey& t, int tile_level) {
  return VoxelKey{static_cast<uint16_t>(t.x << tile_level), static_cast<uint16_t>(t.y << tile_level),
                  static_cast<uint16_t>(t.z << tile_level)};
}

/// One tile of a split map.
struct Tile {
  TileKey key;
  TemporalMap map;  ///< the tile's subtree under the path from the root; sessions clipped to it
};

/// A 4D map cut into tiles.
struct SplitMap {
  int tile_level = 0;
  /// Inner nodes above tile level and the slot lists at tile level or above; the sessions'
  /// full records (coverage, node counts). Where a tile hangs, its slot is empty.
  TemporalMap top;
  std::vector<Tile> tiles;  ///< in Morton order of their corners
};

/// The part of `coverage` inside the cube at `corner` of 2^level voxels per axis.
Coverage clipCoverage(const Coverage& coverage, const VoxelKey& corner, int level);

/// Cuts `map` into tiles of 2^tile_level voxels per axis. The tiles hold every session (same
/// times and names; coverage clipped to the tile; node counts zero, kept once in the top).
/// Compact the map first (TemporalMap::compact) for a join that gives back the same layout.
/// @throw UsageError for a tile level outside [kMinTileLevel, kMaxTileLevel].
SplitMap splitIntoTiles(const TemporalMap& map, int tile_level);

/// Puts the tiles back into the top: the map that was split.
/// @throw FormatError when a tile does not fit (another resolution, other session times, a tile
/// whose place in the top is taken, or structure outside its cube).
TemporalMap joinTiles(const TemporalMap& top, int tile_level, const std::vector<const Tile*>& tiles);

/// Checks that `tile` can be tile `key` of `top`: same resolution, criterion and session times,
/// nothing stored outside the tile's cube. @throw FormatError naming `source`.
void checkTileFits(const TemporalMap& top, int tile_level, const TileKey& key, const TemporalMap& tile,
                   const std::string& source);

}  // namespace chronomap
