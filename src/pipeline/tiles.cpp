#include "chronomap/pipeline/tiles.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/io/file.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/pipeline/maps.h"

namespace chronomap::pipeline {

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
  TemporalMap map = io::readTemporalMap(s.map);
  TileResult r;
  r.tile_level = s.tile_size_m ? tileLevelFor(*s.tile_size_m, map.resolution_m()) : kDefaultTileLevel;
  r.tile_size_m = std::ldexp(map.resolution_m(), r.tile_level);
  map.compact();  // as the file holds it: the join then gives back the same layout
  const SplitMap split = splitIntoTiles(map, r.tile_level);
  split.top.forEachList([&](const VoxelKey&, int, std::span<const TemporalMap::Entry>) { ++r.top_lists; });
  const nlohmann::json meta = {{"created_by", "chronomap tile"}, {"source", s.map.string()}};
  const io::TiledWriteResult w = io::writeTiledMap(s.folder, split, meta);
  r.tiles = w.tiles;
  r.index_bytes = w.index_bytes;
  r.tile_bytes = w.tile_bytes;
  r.map_bytes = fs::file_size(s.map);
  return r;
}

size_t untileMap(const fs::path& folder, const fs::path& map) {
  io::refuseOverwritingInputs(map, {folder / io::kTileIndexName});
  const io::TileIndex index = io::readTileIndex(folder);
  std::vector<Tile> tiles;
  tiles.reserve(index.tiles.size());
  for (const io::TileEntry& e : index.tiles) tiles.push_back(Tile{e.key, io::readTile(folder, index, e)});
  std::vector<const Tile*> refs;
  for (const Tile& t : tiles) refs.push_back(&t);
  const TemporalMap joined = joinTiles(index.top, index.tile_level, refs);
  io::writeTemporalMap(map, joined, {{"created_by", "chronomap untile"}, {"source", folder.string()}});
  return joined.sessionCount();
}

bool VoxelBox::meets(const VoxelKey& corner, int level) const {
  const int64_t edge = int64_t{1} << level;
  auto axis = [edge](int64_t c, int64_t lo, int64_t hi) { return c <= hi && c + edge - 1 >= lo; };
  return axis(corner.x, min.x, max.x) && axis(corner.y, min.y, max.y) && axis(corner.z, min.z, max.z);
}

VoxelBox voxelBoxOf(const KeyGrid& grid, const Eigen::Vector3d& min_m, const Eigen::Vector3d& max_m) {
  if ((min_m.array() > max_m.array()).any()) throw UsageError("box: the lower corner lies above the upper one");
  const auto lo = grid.keyOf(min_m), hi = grid.keyOf(max_m);
  if (!lo || !hi) throw UsageError("box: a corner lies outside the map");
  return VoxelBox{*lo, *hi};
}

bool isTiledMapFolder(const fs::path& path) { return io::isTiledMap(path); }

TiledMap::TiledMap(const fs::path& folder, TileCacheSettings settings)
    : folder_(folder), settings_(settings), index_(io::readTileIndex(folder)) {}

void TiledMap::evictFor(size_t bytes) {
  if (settings_.memory_limit_bytes == 0) return;
  while (!lru_.empty() && stats_.resident_bytes + bytes > settings_.memory_limit_bytes) {
    const auto it = held_.find(lru_.back());
    stats_.resident_bytes -= it->second.bytes;
    --stats_.resident_tiles;
    ++stats_.evictions;
    held_.erase(it);
    lru_.pop_back();
  }
}

std::shared_ptr<const TemporalMap> TiledMap::tile(const TileKey& key) {
  if (const auto it = held_.find(key); it != held_.end()) {
    ++stats_.hits;
    lru_.splice(lru_.begin(), lru_, it->second.lru);
    return it->second.map;
  }
  const io::TileEntry* entry = index_.find(key);
  if (!entry) return nullptr;
  auto map = std::make_shared<const TemporalMap>(io::readTile(folder_, index_, *entry));
  const size_t bytes = map->memoryBytes();
  evictFor(bytes);
  lru_.push_front(key);
  held_.emplace(key, Held{map, bytes, lru_.begin()});
  ++stats_.loads;
  stats_.resident_bytes += bytes;
  ++stats_.resident_tiles;
  stats_.peak_resident_bytes = std::max(stats_.peak_resident_bytes, stats_.resident_bytes);
  stats_.peak_resident_tiles = std::max(stats_.peak_resident_tiles, stats_.resident_tiles);
  return map;
}

std::vector<TileKey> TiledMap::tilesMeeting(const std::optional<VoxelBox>& box) const {
  std::vector<TileKey> keys;
  for (const io::TileEntry& e : index_.tiles) {
    if (!box || box->meets(tileCorner(e.key, index_.tile_level), index_.tile_level)) keys.push_back(e.key);
  }
  return keys;
}

SessionMap TiledMap::snapshot(double time_s, const std::optional<VoxelBox>& box) {
  SessionMap out(resolution_m());
  const bool latest = !sessions().empty() && time_s >= sessions().back().time_s;
  for (const TileKey& key : tilesMeeting(box)) {
    const io::TileEntry* entry = index_.find(key);
    if (latest && entry && entry->latest && !held_.count(key)) {
      out.merge(io::readLatestState(folder_, index_, *entry));
      ++stats_.latest_reads;
    } else {
      out.merge(tile(key)->snapshot(time_s));
    }
  }
  if (const auto rank = index_.top.rankAtOrBefore(time_s)) {
    index_.top.forEachList([&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> entries) {
      if (box && !box->meets(corner, level)) return;
      const TemporalMap::Entry* valid = nullptr;
      for (const TemporalMap::Entry& e : entries) {
        if (e.session > *rank) break;
        valid = &e;
      }
      if (valid) out.addCube(corner, level, valid->value);
    });
  }
  // Tiles are compressed inside; the cubes of several tiles that read free merge here, summed
  // in the same order as the whole map's snapshot sums them.
  out.compressFree();
  return out;
}

std::vector<HistoryEntry> TiledMap::history(const VoxelKey& key) {
  std::vector<HistoryEntry> h = index_.top.history(key);
  if (!h.empty()) return h;  // a uniform cube of tile size or larger
  const auto t = tile(tileOf(key, index_.tile_level));
  return t ? t->history(key) : h;
}

std::optional<VoxelCounters> TiledMap::valueAt(const VoxelKey& key, double time_s) {
  if (!index_.top.history(key).empty()) return index_.top.valueAt(key, time_s);
  const auto t = tile(tileOf(key, index_.tile_level));
  return t ? t->valueAt(key, time_s) : std::nullopt;
}

DiffMap TiledMap::diff(double t1_s, double t2_s, const DiffSettings& settings, const std::optional<VoxelBox>& box) {
  settings.validate();
  // Each part's cells by the voxel rule alone; the neighbourhood rule needs the voxels around
  // each cell, which may lie in another tile: applied once all cells are gathered.
  DiffSettings voxel_rule = settings;
  voxel_rule.neighbourhood_voxels = 0;
  voxel_rule.kept_surface_radius_voxels = 0;
  voxel_rule.dark_surface_radius_voxels = 0;
  std::vector<ChangeCell> cells;
  auto gather = [&](const TemporalMap& part) {
    const DiffMap d = chronomap::diff(part, t1_s, t2_s, voxel_rule);
    for (const ChangeCell& c : d.cells()) {
      if (!box || box->meets(c.key, c.level)) cells.push_back(c);
    }
  };
  gather(index_.top);
  for (const TileKey& key : tilesMeeting(box)) gather(*tile(key));
  applyNeighbourhoodRule(
      cells, settings, [&](const VoxelKey& k) { return valueAt(k, t1_s).value_or(VoxelCounters{}); },
      [&](const VoxelKey& k) { return valueAt(k, t2_s).value_or(VoxelCounters{}); });
  return DiffMap::fromCells(resolution_m(), settings, std::move(cells));
}

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
    return MapSnapshot{snapshotAt(io::readTemporalMap(path), time_s, name), std::nullopt};
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
    const TemporalMap map = io::readTemporalMap(path);
    return fill(map.grid(), map);
  }
  TiledMap map(path, cache);
  VoxelHistory h = fill(map.grid(), map);
  h.tiles = map.cacheStats();
  return h;
}

}  // namespace chronomap::pipeline
