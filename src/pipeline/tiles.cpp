#include "chronomap/pipeline/tiles.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/maps.h"
#include "build_steps.h"
#include "in_order.h"

namespace chronomap {

namespace fs = std::filesystem;

int tileLevelFor(double tile_size_m, double resolution_m) {
  const double voxels = tile_size_m / resolution_m;
  const int level = std::isfinite(voxels) && voxels >= 1.0 ? static_cast<int>(std::lround(std::log2(voxels))) : -1;
  const bool power = level >= 0 && std::abs(voxels - std::ldexp(1.0, level)) <= 1e-6 * voxels;
  if (power && level >= kMinTileLevel && level <= kMaxTileLevel) return level;
  const int lo = std::clamp(level < 0 ? kMinTileLevel : static_cast<int>(std::floor(std::log2(voxels))), kMinTileLevel,
                            kMaxTileLevel);
  const int hi = std::min(lo + 1, kMaxTileLevel);
  std::ostringstream msg;
  msg << "tile size " << tile_size_m << " m is not a power-of-two number of " << resolution_m << " m voxels between "
      << (1 << kMinTileLevel) << " and " << (1 << kMaxTileLevel) << "; try " << std::ldexp(resolution_m, lo) << " m or "
      << std::ldexp(resolution_m, hi) << " m";
  throw UsageError(msg.str());
}

TileResult tileMap(const TileSettings& s) {
  if (fs::exists(s.folder) && !fs::is_directory(s.folder)) {
    throw UsageError("output '" + s.folder.string() + "' exists and is not a folder");
  }
  if (fs::exists(s.folder) && fs::exists(s.map) && fs::equivalent(s.folder, s.map)) {
    throw UsageError("output '" + s.folder.string() + "' is the input");
  }
  const CmapFile file = readCmap(s.map);
  TemporalMap map = temporalMapFrom(file, s.map.string());
  TileResult r;
  r.tile_level = s.tile_size_m ? tileLevelFor(*s.tile_size_m, map.resolution_m()) : kDefaultTileLevel;
  r.tile_size_m = std::ldexp(map.resolution_m(), r.tile_level);
  map.compact();  // as the file holds it: the join then gives back the same layout
  const SplitMap split = splitIntoTiles(map, r.tile_level);
  split.top.forEachListPlace([&](const VoxelKey&, int) { ++r.top_lists; });
  nlohmann::json meta = {{"created_by", "chronomap tile"}, {"source", s.map.string()}};
  meta.update(upKeysOf(userMetadataOf(file)));  // the map's up goes with it (docs/frames.md)
  // The tiles written on every core (their files do not depend on it).
  const TiledWriteResult w =
      writeTiledMap(
          s.folder, split, meta, s.window_sessions,
          [](size_t n, const std::function<void(size_t)>& piece) { pipeline_detail::runInOrder(n, 0, piece); },
          s.windowed_tiles);
  r.tiles = w.tiles;
  r.index_bytes = w.index_bytes;
  r.tile_bytes = w.tile_bytes;
  r.windows = w.windows;
  r.map_bytes = fs::file_size(s.map);
  return r;
}

size_t untileMap(const fs::path& folder, const fs::path& map) {
  refuseOverwritingInputs(map, {folder / kTileIndexName});
  const TileIndex index = readTileIndex(folder);
  // Read on every core; an unreadable tile gives the error reading them in order gives.
  std::vector<Tile> tiles(index.tiles.size());
  pipeline_detail::runInOrder(tiles.size(), 0, [&](size_t k) {
    tiles[k] = Tile{index.tiles[k].key, readTile(folder, index, index.tiles[k])};
  });
  std::vector<const Tile*> refs;
  for (const Tile& t : tiles) refs.push_back(&t);
  const TemporalMap joined = joinTiles(index.top, index.tile_level, refs);
  nlohmann::json meta = {{"created_by", "chronomap untile"}, {"source", folder.string()}};
  meta.update(upKeysOf(userMetadataOf(readCmap(folder / kTileIndexName))));
  writeTemporalMap(map, joined, meta);
  return joined.sessionCount();
}

bool isTiledMapFolder(const fs::path& path) { return isTiledMap(path); }

SessionMap tiledSnapshotAt(TiledMap& map, double time_s, const std::optional<VoxelBox>& box, const std::string& name) {
  const auto& sessions = map.sessions();
  if (sessions.empty() || time_s < sessions.front().time_s) {
    throw UsageError(name + " holds no session at or before " + formatTime(time_s) +
                     (sessions.empty() ? "" : " (the first is at " + formatTime(sessions.front().time_s) + ")"));
  }
  return map.snapshot(time_s, box);
}

Segmentation segmentTiledDiff(TiledMap& map, double t1_s, double t2_s, const DiffSettings& diff_settings,
                              const SegmentSettings& segment_settings, const std::optional<VoxelBox>& box,
                              DiffMap* diff_out) {
  DiffMap d = map.diff(t1_s, t2_s, diff_settings, box);
  Segmentation s = segment(d, segment_settings);
  if (diff_out) *diff_out = std::move(d);
  return s;
}

MapSnapshot snapshotOfMap(const fs::path& path, double time_s, const std::optional<BoxMetres>& box_m,
                          const TileCacheSettings& cache) {
  const std::string name = path.string();
  if (!isTiledMapFolder(path)) {
    if (box_m) throw UsageError("a box applies to a tiled map (chronomap tile); " + name + " is not one");
    return MapSnapshot{snapshotAt(readTemporalMap(path), time_s, name), std::nullopt};
  }
  TiledMap map(path, cache);
  std::optional<VoxelBox> box;
  if (box_m) box = voxelBoxOf(map.grid(), box_m->first, box_m->second);
  SessionMap snap = tiledSnapshotAt(map, time_s, box, name);
  return MapSnapshot{std::move(snap), map.cacheStats()};
}

VoxelHistory historyOfMap(const fs::path& path, const Eigen::Vector3d& point_m, const TileCacheSettings& cache) {
  auto fill = [&](const KeyGrid& grid, auto&& map) {
    VoxelHistory h;
    const auto key = grid.keyOf(point_m);
    if (!key) {
      std::ostringstream msg;
      msg << "point " << point_m.x() << "," << point_m.y() << "," << point_m.z() << " lies outside the map";
      throw UsageError(msg.str());
    }
    h.key = *key;
    h.center_m = grid.centerOf(*key);
    h.entries = map.history(*key);
    h.sessions = map.sessions().size();
    return h;
  };
  if (!isTiledMapFolder(path)) {
    const TemporalMap map = readTemporalMap(path);
    return fill(map.grid(), map);
  }
  TiledMap map(path, cache);
  VoxelHistory h = fill(map.grid(), map);
  h.tiles = map.cacheStats();
  return h;
}

}  // namespace chronomap
