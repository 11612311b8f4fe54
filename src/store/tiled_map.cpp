#include "chronomap/store/tiled_map.h"

#include <map>

#include <algorithm>

#include "chronomap/core/error.h"

namespace chronomap {

namespace fs = std::filesystem;

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

TiledMap::TiledMap(const fs::path& folder, TileCacheSettings settings)
    : folder_(folder), settings_(settings), index_(readTileIndex(folder)) {}

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
  const TileEntry* entry = index_.find(key);
  if (!entry) return nullptr;
  auto map = std::make_shared<const TemporalMap>(readTile(folder_, index_, *entry));
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
  for (const TileEntry& e : index_.tiles) {
    if (!box || box->meets(tileCorner(e.key, index_.tile_level), index_.tile_level)) keys.push_back(e.key);
  }
  return keys;
}

SessionMap TiledMap::snapshot(double time_s, const std::optional<VoxelBox>& box) {
  SessionMap out(resolution_m());
  const bool latest = !sessions().empty() && time_s >= sessions().back().time_s;
  for (const TileKey& key : tilesMeeting(box)) {
    const TileEntry* entry = index_.find(key);
    if (latest && entry && entry->latest && !held_.count(key)) {
      out.merge(readLatestState(folder_, index_, *entry));
      ++stats_.latest_reads;
    } else if (entry && !held_.count(key)) {
      // An earlier time of a tile not held: read at that time alone, not held (issue 46).
      out.merge(readTileSnapshot(folder_, index_, *entry, time_s, settings_.read_windows));
      ++stats_.time_reads;
      if (settings_.read_windows && readsWindowAt(index_, *entry, time_s)) ++stats_.window_reads;
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
  // With seen_at_both the rules read only what the session in effect observed: each part holds
  // its own share of every session's coverage.
  // (The tile is held with its coverage, so that its address names it while the map is used.)
  std::map<std::pair<const TemporalMap*, uint32_t>, std::pair<std::shared_ptr<const TemporalMap>, CoverageIndex>> seen;
  auto valueSeen = [&](const VoxelKey& k, double t) {
    std::shared_ptr<const TemporalMap> held;
    const TemporalMap* part = &index_.top;
    if (index_.top.history(k).empty()) {
      held = tile(tileOf(k, index_.tile_level));
      if (!held) return VoxelCounters{};
      part = held.get();
    }
    if (settings.seen_at_both) {
      const auto rank = part->rankAtOrBefore(t);
      if (!rank) return VoxelCounters{};
      auto it = seen.find({part, *rank});
      if (it == seen.end()) {
        it = seen.emplace(std::make_pair(part, *rank),
                          std::make_pair(held, CoverageIndex(part->sessions()[*rank].coverage))).first;
      }
      if (!it->second.second.contains(k)) return VoxelCounters{};
    }
    return part->valueAt(k, t).value_or(VoxelCounters{});
  };
  applyNeighbourhoodRule(
      cells, settings, [&](const VoxelKey& k) { return valueSeen(k, t1_s); },
      [&](const VoxelKey& k) { return valueSeen(k, t2_s); });
  return DiffMap::fromCells(resolution_m(), settings, std::move(cells));
}

}  // namespace chronomap
