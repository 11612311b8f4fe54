#include "chronomap/pipeline/stream.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <type_traits>

#include "build_steps.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/pipeline/tiles.h"
#include "chronomap/temporal/tiles.h"

namespace chronomap::pipeline {

namespace fs = std::filesystem;

namespace {

/// One leaf of a session map, as held and spilled.
struct Part {
  uint32_t session = 0;  // index given to produce()
  uint16_t x = 0, y = 0, z = 0;
  uint8_t level = 0;
  uint8_t unused = 0;
  VoxelCounters counters;
};
static_assert(std::is_trivially_copyable_v<Part>);

struct CubeLess {
  bool operator()(const Cube& a, const Cube& b) const {
    if (a.level != b.level) return a.level > b.level;
    return mortonEncode(a.corner) < mortonEncode(b.corner);
  }
};

struct NewSession {
  size_t index = 0;
  double time_s = 0.0;
  std::string name;
  Coverage coverage;
  uint64_t nodes_separate = 0;
};

std::string cubeFile(const Cube& c) {
  return std::to_string(c.level) + "_" + std::to_string(c.corner.x) + "_" + std::to_string(c.corner.y) + "_" +
         std::to_string(c.corner.z) + ".parts";
}

/// The session parts by cube, in memory under a budget, spilled to files beyond it.
class PartStore {
 public:
  PartStore(fs::path folder, size_t limit, StreamStats& stats)
      : folder_(std::move(folder)), limit_(limit), stats_(stats) {}
  ~PartStore() {
    std::error_code ec;
    if (created_) fs::remove_all(folder_, ec);
  }
  PartStore(const PartStore&) = delete;
  PartStore& operator=(const PartStore&) = delete;

  void add(const Cube& cube, const Part& p) {
    if (limit_ != 0 && bytes_ + sizeof(Part) > limit_) spill();
    held_[cube].push_back(p);
    bytes_ += sizeof(Part);
    stats_.peak_parts_bytes = std::max(stats_.peak_parts_bytes, bytes_);
    cubes_.insert(cube);
  }
  const std::set<Cube, CubeLess>& cubes() const { return cubes_; }
  /// Every part of `cube`, spilled or held; the held ones are dropped.
  std::vector<Part> take(const Cube& cube) {
    std::vector<Part> out;
    const fs::path file = folder_ / cubeFile(cube);
    if (created_ && fs::exists(file)) {
      const std::vector<uint8_t> bytes = readFileBytes(file);
      out.resize(bytes.size() / sizeof(Part));
      std::memcpy(static_cast<void*>(out.data()), bytes.data(), out.size() * sizeof(Part));
      fs::remove(file);
    }
    if (const auto it = held_.find(cube); it != held_.end()) {
      out.insert(out.end(), it->second.begin(), it->second.end());
      bytes_ -= it->second.size() * sizeof(Part);
      held_.erase(it);
    }
    return out;
  }

 private:
  void spill() {
    if (!created_) {
      fs::create_directories(folder_);
      created_ = true;
    }
    for (auto& [cube, parts] : held_) {
      std::ofstream out(folder_ / cubeFile(cube), std::ios::binary | std::ios::app);
      out.write(reinterpret_cast<const char*>(parts.data()), static_cast<std::streamsize>(parts.size() * sizeof(Part)));
      if (!out) throw IoError((folder_ / cubeFile(cube)).string() + ": cannot write (disk full?)");
      stats_.spilled_bytes += parts.size() * sizeof(Part);
    }
    held_.clear();
    bytes_ = 0;
    ++stats_.spills;
  }

  fs::path folder_;
  size_t limit_;
  StreamStats& stats_;
  bool created_ = false;
  size_t bytes_ = 0;
  std::map<Cube, std::vector<Part>, CubeLess> held_;
  std::set<Cube, CubeLess> cubes_;
};

/// The cube at `level` that holds `key`.
Cube cubeAt(const VoxelKey& key, int level) { return Cube{cellCorner(key, level), level}; }

/// The cube of the top's list that holds `c` (at c's level or above), if any; and the levels
/// of the inner nodes on the way to `c` that the top does not hold yet.
struct TopPath {
  std::optional<Cube> list;
  std::vector<int> missing_levels;  // inner nodes at these levels (between the top and c) are new
};
TopPath walkTop(const TemporalMap::Parts& top, const Cube& c) {
  TopPath out;
  uint32_t node = 0;
  for (int level = kTreeDepth; level > c.level; --level) {
    const TemporalMap::Ref r = top.inner[node][static_cast<size_t>(childSlot(c.corner, level - 1))];
    if (r != TemporalMap::kEmpty && (r & TemporalMap::kListBit)) {
      out.list = cubeAt(c.corner, level - 1);
      return out;
    }
    if (level - 1 == c.level) return out;
    if (r == TemporalMap::kEmpty) {
      for (int l = level - 1; l > c.level; --l) out.missing_levels.push_back(l);
      return out;
    }
    node = r;
  }
  return out;
}

std::vector<SessionRecord> clipped(const std::vector<SessionRecord>& all, const Cube& cube) {
  std::vector<SessionRecord> out;
  out.reserve(all.size());
  for (const SessionRecord& s : all) {
    SessionRecord r;
    r.time_s = s.time_s;
    r.name = s.name;
    r.coverage = clipCoverage(s.coverage, cube.corner, cube.level);
    out.push_back(std::move(r));
  }
  return out;
}

/// Removes what a killed earlier run left: tile files the index does not name, parts folders.
void removeLeftovers(const fs::path& folder, const TileIndex* index) {
  std::set<std::string> named;
  if (index) {
    for (const TileEntry& e : index->tiles) {
      named.insert(e.file);
      if (e.latest) named.insert(e.latest->file);
    }
  }
  std::error_code ec;
  if (fs::is_directory(folder / "tiles")) {
    for (const auto& f : fs::directory_iterator(folder / "tiles")) {
      if (!named.count("tiles/" + f.path().filename().string())) fs::remove(f.path(), ec);
    }
  }
  for (const auto& f : fs::directory_iterator(folder)) {
    if (f.path().filename().string().rfind(".parts-", 0) == 0) fs::remove_all(f.path(), ec);
  }
}

/// A folder holding only what a killed first build left (tiles without an index, parts).
bool onlyLeftovers(const fs::path& folder) {
  for (const auto& f : fs::directory_iterator(folder)) {
    const std::string name = f.path().filename().string();
    if (name != "tiles" && name.rfind(".parts-", 0) != 0) return false;
  }
  return true;
}

}  // namespace

StreamResult streamIntoTiles(const StreamSettings& s, size_t count,
                             const std::function<StreamSession(size_t)>& produce) {
  s.criterion.validate();
  if (fs::exists(s.folder) && !fs::is_directory(s.folder)) {
    throw UsageError("'" + s.folder.string() + "' exists and is not a folder (a tiled map is a folder)");
  }
  const bool existed = fs::exists(s.folder);
  if (existed && !isTiledMap(s.folder) && !onlyLeftovers(s.folder)) {
    throw UsageError("'" + s.folder.string() + "' is a folder but not a tiled 4D map (it has no " +
                     kTileIndexName + ")");
  }
  fs::create_directories(s.folder);
  struct Cleanup {  // a new map that failed leaves no folder behind
    fs::path path;
    bool armed;
    ~Cleanup() {
      std::error_code ec;
      if (!armed || fs::exists(path / kTileIndexName, ec)) return;
      fs::remove_all(path / "tiles", ec);
      if (fs::is_directory(path, ec) && fs::is_empty(path, ec)) fs::remove(path, ec);
    }
  } cleanup{s.folder, !existed || !isTiledMap(s.folder)};
  // The folder itself is locked: the index is replaced by a rename, the folder stays.
  const FileLock lock(s.folder);

  StreamResult result;
  std::optional<TileIndex> index;
  if (isTiledMap(s.folder)) index = readTileIndex(s.folder);
  result.created = !index;
  TemporalMap top = index ? index->top : TemporalMap(s.resolution_m, s.criterion);
  const int level = index ? index->tile_level
                          : (s.tile_size_m ? tileLevelFor(*s.tile_size_m, s.resolution_m) : kDefaultTileLevel);
  if (index && top.resolution_m() != s.resolution_m) {
    throw UsageError(s.folder.string() + ": the tiled map has resolution " + std::to_string(top.resolution_m()) +
                     " m but the sessions have " + std::to_string(s.resolution_m) + " m");
  }
  if (index && s.tile_size_m && tileLevelFor(*s.tile_size_m, top.resolution_m()) != level) {
    throw UsageError(s.folder.string() + " has tiles of " + std::to_string(std::ldexp(top.resolution_m(), level)) +
                     " m; it cannot take another tile size");
  }
  result.tile_level = level;
  uint64_t generation = 0;
  if (index) {
    for (const TileEntry& e : index->tiles) generation = std::max(generation, *tileGeneration(e.key, e.file));
  }
  ++generation;
  removeLeftovers(s.folder, index ? &*index : nullptr);

  // 1. Each session in turn: its record, and its leaves cut to the tiles (a leaf of tile size
  // or larger stays whole).
  PartStore parts(s.folder / (".parts-" + std::to_string(::getpid())), s.memory_limit_bytes, result.stats);
  std::vector<NewSession> added;
  std::map<Cube, std::vector<uint32_t>, CubeLess> sessions_of_cube;  // session indices with parts there
  for (size_t i = 0; i < count; ++i) {
    StreamSession session = produce(i);
    if (session.map.resolution_m() != top.resolution_m()) {
      throw UsageError(session.name + ": session resolution " + std::to_string(session.map.resolution_m()) +
                       " m differs from the tiled map's " + std::to_string(top.resolution_m()) + " m");
    }
    if (!std::isfinite(session.time_s)) throw UsageError(session.name + ": session time must be finite");
    if (top.sessionCount() && session.time_s <= top.sessions().back().time_s) {
      throw UsageError(session.name + " (" + formatTime(session.time_s) +
                       ") is not after the tiled map's last session (" +
                       formatTime(top.sessions().back().time_s) +
                       "): the streaming build only adds later sessions (join with `untile` to add earlier ones)");
    }
    added.push_back(NewSession{i, session.time_s, session.name, Coverage(session.map),
                               session.map.innerCount() + session.map.leafCount()});
    session.map.forEachLeaf([&](const LeafView& leaf) {
      const Cube cube = leaf.level < level ? cubeAt(leaf.key, level) : Cube{leaf.key, leaf.level};
      parts.add(cube, Part{static_cast<uint32_t>(i), leaf.key.x, leaf.key.y, leaf.key.z,
                           static_cast<uint8_t>(leaf.level), 0, leaf.counters});
      std::vector<uint32_t>& who = sessions_of_cube[cube];
      if (who.empty() || who.back() != i) who.push_back(static_cast<uint32_t>(i));
    });
  }
  std::stable_sort(added.begin(), added.end(),
                   [](const NewSession& a, const NewSession& b) { return a.time_s < b.time_s; });
  for (size_t k = 1; k < added.size(); ++k) {
    if (added[k].time_s == added[k - 1].time_s) {
      throw UsageError(added[k - 1].name + " and " + added[k].name + " have the same time " +
                       formatTime(added[k].time_s));
    }
  }
  const auto base_rank = static_cast<uint32_t>(top.sessionCount());
  std::vector<uint32_t> rank_of(count);
  for (size_t k = 0; k < added.size(); ++k) rank_of[added[k].index] = base_rank + static_cast<uint32_t>(k);

  // 2. Groups: a tile, or a uniform cube of the top (or a session's leaf) of tile size or more
  // with everything inside it. Groups are disjoint; largest first.
  const TemporalMap::Parts top_parts = top.parts();
  std::set<Cube, CubeLess> promoted;  // largest first
  for (const Cube& c : parts.cubes()) {
    const TopPath path = walkTop(top_parts, c);
    promoted.insert(path.list ? *path.list : c);
  }
  std::vector<Cube> groups;
  for (const Cube& g : promoted) {
    if (std::none_of(groups.begin(), groups.end(), [&](const Cube& h) { return h.contains(g); })) groups.push_back(g);
  }
  std::sort(groups.begin(), groups.end(), [](const Cube& a, const Cube& b) {
    return mortonEncode(a.corner) < mortonEncode(b.corner) ||
           (mortonEncode(a.corner) == mortonEncode(b.corner) && a.level > b.level);
  });
  // Inner nodes of the top that the sessions create on the way to a group, each counted for
  // the first session (in time order) that reaches it, as TemporalMap::add counts them.
  std::vector<int64_t> nodes_added(added.size(), 0);
  {
    std::map<Cube, uint32_t, CubeLess> new_nodes;
    for (const Cube& g : groups) {
      uint32_t first = UINT32_MAX;
      for (const auto& [c, who] : sessions_of_cube) {
        if (!g.contains(c)) continue;
        for (const uint32_t i : who) first = std::min(first, rank_of[i]);
      }
      for (const int l : walkTop(top_parts, g).missing_levels) {
        auto [it, fresh] = new_nodes.emplace(cubeAt(g.corner, l), first);
        if (!fresh) it->second = std::min(it->second, first);
      }
    }
    for (const auto& [c, r] : new_nodes) ++nodes_added[r - base_rank];
  }

  // 3. Each group: its part of the top and its tiles, the sessions added in time order,
  // compacted, cut into tiles again, written under the new generation's names.
  std::vector<SessionRecord> all = top.sessions();
  for (const NewSession& n : added) {
    SessionRecord r;
    r.time_s = n.time_s;
    r.name = n.name;
    r.coverage = n.coverage;
    r.nodes_separate = n.nodes_separate;
    all.push_back(std::move(r));
  }
  fs::create_directories(s.folder / "tiles");
  std::vector<TileEntry> entries;
  std::vector<TemporalMap> group_tops;
  std::vector<Cube> group_cubes;
  std::set<TileKey> done;
  for (const Cube& g : groups) {
    s.progress.advance("tiles", result.stats.groups, groups.size());
    std::vector<Tile> tiles;
    if (index) {
      for (const TileEntry& e : index->tiles) {
        if (g.contains(Cube{tileCorner(e.key, level), level})) {
          tiles.push_back(Tile{e.key, readTile(s.folder, *index, e)});
          ++result.stats.tiles_read;
          done.insert(e.key);
        }
      }
    }
    result.stats.largest_group_tiles = std::max(result.stats.largest_group_tiles, tiles.size());
    // The stored sessions' records in the group: the top's coverage there (outside the tiles)
    // joined with the tiles' own.
    std::vector<SessionRecord> records = clipped(top.sessions(), g);
    TemporalMap work = restrictToCube(top, g, records);
    if (!tiles.empty()) {
      std::vector<const Tile*> refs;
      for (const Tile& t : tiles) refs.push_back(&t);
      work = joinTiles(work, level, refs);
      records = work.sessions();
      tiles.clear();
    }
    std::vector<std::vector<Part>> by_session(added.size());
    for (const Cube& c : parts.cubes()) {
      if (!g.contains(c)) continue;
      for (const Part& p : parts.take(c)) by_session[rank_of[p.session] - base_rank].push_back(p);
    }
    for (size_t k = 0; k < added.size(); ++k) {
      SessionMap part(top.resolution_m());
      for (const Part& p : by_session[k]) {
        const VoxelKey key{p.x, p.y, p.z};
        if (p.level == 0) {
          part.add(key, p.counters);
        } else {
          part.addCube(key, p.level, p.counters);
        }
      }
      by_session[k].clear();
      by_session[k].shrink_to_fit();
      work.add(added[k].time_s, part, AddSettings{false, added[k].name});
      nodes_added[k] += work.sessions()[base_rank + k].nodes_added;
    }
    result.stats.peak_group_bytes = std::max(result.stats.peak_group_bytes, work.memoryBytes());
    for (SessionRecord& r : clipped(std::vector<SessionRecord>(all.begin() + base_rank, all.end()), g)) {
      records.push_back(std::move(r));
    }
    work = TemporalMap::fromParts(work.resolution_m(), work.criterion(), work.parts(), std::move(records));
    work.compact();
    SplitMap split = splitIntoTiles(work, level);
    for (const Tile& t : split.tiles) {
      entries.push_back(writeTileFile(s.folder, t.key, generation, t.map));
      result.tile_bytes += entries.back().diskBytes();
      ++result.stats.tiles_written;
    }
    group_tops.push_back(std::move(split.top));
    group_cubes.push_back(g);
    ++result.stats.groups;
  }

  // 4. The tiles no session reached: the new sessions' records (nothing observed there).
  if (index) {
    for (const TileEntry& e : index->tiles) {
      if (done.count(e.key)) continue;
      const TemporalMap old = readTile(s.folder, *index, e);
      ++result.stats.tiles_read;
      std::vector<SessionRecord> records = old.sessions();
      for (const NewSession& n : added) {
        SessionRecord r;
        r.time_s = n.time_s;
        r.name = n.name;
        r.coverage = Coverage::fromRanges({});
        records.push_back(std::move(r));
      }
      const TemporalMap tile =
          TemporalMap::fromParts(old.resolution_m(), old.criterion(), old.parts(), std::move(records));
      entries.push_back(writeTileFile(s.folder, e.key, generation, tile));
      result.tile_bytes += entries.back().diskBytes();
      ++result.stats.tiles_written;
    }
  }

  // 5. The top with the groups' parts in place, every session's record with its coverage
  // outside the tiles, compacted as a written map is; then the index, swapped in by one rename;
  // then the old files go.
  std::vector<CubePart> replaced;
  for (size_t k = 0; k < group_cubes.size(); ++k) replaced.push_back(CubePart{group_cubes[k], &group_tops[k]});
  for (size_t k = 0; k < added.size(); ++k) all[base_rank + k].nodes_added = nodes_added[k];
  std::vector<TileKey> tile_keys;
  for (const TileEntry& e : entries) tile_keys.push_back(e.key);
  for (SessionRecord& r : all) r.coverage = clipCoverageOutside(r.coverage, tile_keys, level);
  TemporalMap new_top = replaceCubes(top, replaced, std::move(all));
  group_tops.clear();
  new_top.compact();
  std::sort(entries.begin(), entries.end(),
            [](const TileEntry& a, const TileEntry& b) { return a.key < b.key; });
  const nlohmann::json meta = {{"created_by", "chronomap build --tiles"}};
  result.index_bytes = writeTileIndex(s.folder, new_top, level, entries, meta);
  cleanup.armed = false;
  TileIndex written{level, TemporalMap(new_top.resolution_m()), entries};
  removeLeftovers(s.folder, &written);

  result.sessions = new_top.sessionCount();
  result.tiles = entries.size();
  for (const NewSession& n : added) result.added_times.push_back(n.time_s);
  result.nodes_added = std::move(nodes_added);
  return result;
}

StreamResult streamBuild(const BuildSettings& b, std::optional<double> tile_size_m, size_t memory_limit_bytes) {
  if (b.registration) throw UsageError("--register cannot be used with --tiles: the streaming build adds sessions tile "
                                       "by tile and registration needs every session at once");
  if (b.realign) throw UsageError("--realign cannot be used with --tiles (it needs every session at once)");
  if (b.replace) throw UsageError("--replace cannot be used with --tiles");
  detail::checkInputs(b);
  StreamSettings s;
  s.folder = b.map;
  s.resolution_m = b.session.resolution_m;
  s.criterion = b.criterion;
  s.tile_size_m = tile_size_m;
  s.memory_limit_bytes = memory_limit_bytes;
  s.progress = b.progress;
  return streamIntoTiles(s, b.datasets.size(), [&](size_t i) {
    detail::Pending p = detail::integrateOne(b, i);
    return StreamSession{p.time_s, b.datasets[i].filename().string(), std::move(p.session.map)};
  });
}

StreamResult streamAddSession(const AddSessionSettings& a, size_t memory_limit_bytes) {
  if (a.replace) throw UsageError("--replace cannot be used on a tiled map");
  if (a.realign) throw UsageError("--realign cannot be used on a tiled map");
  if (a.write != WritePolicy::Auto) throw UsageError("--write does not apply to a tiled map");
  if (!isTiledMap(a.map)) throw UsageError("'" + a.map.string() + "' is not a tiled 4D map");
  const CmapFile file = readCmap(a.session);
  SessionMap session = sessionMapFrom(file, a.session.string());
  const double time_s = detail::sessionTime(a, file);
  StreamSettings s;
  s.folder = a.map;
  s.resolution_m = session.resolution_m();
  s.criterion = a.criterion;
  s.memory_limit_bytes = memory_limit_bytes;
  return streamIntoTiles(s, 1, [&](size_t) {
    return StreamSession{time_s, a.session.filename().string(), std::move(session)};
  });
}

}  // namespace chronomap::pipeline
