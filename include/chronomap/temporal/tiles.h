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
  /// full records (node counts), their coverage outside the tiles (each tile holds its own, so
  /// that what a query reads stays small as sessions accumulate). Where a tile hangs, its slot
  /// is empty.
  TemporalMap top;
  std::vector<Tile> tiles;  ///< in Morton order of their corners
};

/// The part of `coverage` inside the cube at `corner` of 2^level voxels per axis.
Coverage clipCoverage(const Coverage& coverage, const VoxelKey& corner, int level);

/// The part of `coverage` outside the given tiles (cubes of 2^tile_level voxels per axis).
Coverage clipCoverageOutside(const Coverage& coverage, const std::vector<TileKey>& tiles, int tile_level);

/// Every voxel any of `parts` covers (they may overlap).
Coverage unionCoverage(const std::vector<const Coverage*>& parts);

/// Cuts `map` into tiles of 2^tile_level voxels per axis. The tiles hold every session (same
/// times and names; coverage clipped to the tile; node counts zero, kept once in the top).
/// Compact the map first (TemporalMap::compact) for a join that gives back the same layout.
/// @throw UsageError for a tile level outside [kMinTileLevel, kMaxTileLevel].
SplitMap splitIntoTiles(const TemporalMap& map, int tile_level);

/// Puts the tiles back into the top: the map that was split (each session's coverage the union
/// of the top's and the tiles').
/// @throw FormatError when a tile does not fit (another resolution, other session times, a tile
/// whose place in the top is taken, or structure outside its cube).
TemporalMap joinTiles(const TemporalMap& top, int tile_level, const std::vector<const Tile*>& tiles);

/// Checks that `part` can be part of tile `key` of `top`: same resolution and criterion, every
/// history list inside the tile's cube at most `max_level` (the sessions are not checked: a
/// window of a tile holds a run of them). @throw FormatError naming `source`.
void checkFitsTileCube(const TemporalMap& top, int tile_level, const TileKey& key, const TemporalMap& part,
                       int max_level, const std::string& source);
/// Checks that `tile` can be tile `key` of `top`: same resolution, criterion and session times,
/// nothing stored outside the tile's cube. @throw FormatError naming `source`.
void checkTileFits(const TemporalMap& top, int tile_level, const TileKey& key, const TemporalMap& tile,
                   const std::string& source);

/// An aligned cube of the octree: its lowest voxel and its level (2^level voxels per axis).
struct Cube {
  VoxelKey corner;
  int level = 0;
  friend bool operator==(const Cube&, const Cube&) = default;
  /// True when `inner` lies inside this cube (or is it).
  bool contains(const Cube& inner) const {
    return inner.level <= level && (inner.corner.x >> level) == (corner.x >> level) &&
           (inner.corner.y >> level) == (corner.y >> level) && (inner.corner.z >> level) == (corner.z >> level);
  }
};

/// A map holding only what `map` holds in `cube` (the path from the root to it, then the cube's
/// list or subtree), with `sessions` as its sessions' table. Used by the streaming build to
/// take a part of a tiled map's top out, graft its tiles in (joinTiles) and add sessions to it.
TemporalMap restrictToCube(const TemporalMap& map, const Cube& cube, std::vector<SessionRecord> sessions);

/// `top` with the content of each of `parts`' cubes replaced by what `from` holds there (a map
/// with nothing outside the cube, as restrictToCube makes); inner nodes are created on the
/// way to cubes that lie where `top` holds nothing. The cubes must be disjoint and must not lie
/// inside one of `top`'s lists. The result has `sessions` as its sessions' table (the parts may
/// hold entries of sessions `top` does not have yet). @throw FormatError otherwise.
struct CubePart {
  Cube cube;
  const TemporalMap* from = nullptr;
};
TemporalMap replaceCubes(const TemporalMap& top, const std::vector<CubePart>& parts,
                         std::vector<SessionRecord> sessions);

}  // namespace chronomap
