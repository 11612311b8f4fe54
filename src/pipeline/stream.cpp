#include "chronomap/pipeline/stream.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <span>

#include "build_steps.h"
#include "in_order.h"
#include "chronomap/align/consensus.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/part_store.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/pipeline/tiles.h"
#include "chronomap/temporal/tiles.h"
#include "chronomap/temporal/window.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

struct NewSession {
  size_t index = 0;
  double time_s = 0.0;
  std::string name;
  Coverage coverage;
  uint64_t nodes_separate = 0;
};

/// Refuses session `name` at `time_s`, not after the tiled map's last session at `last_s`.
[[noreturn]] void refuseEarlier(const std::string& name, double time_s, double last_s) {
  throw UsageError(name + " (" + formatTime(time_s) + ") is not after the tiled map's last session (" +
                   formatTime(last_s) + "): the streaming build only adds later sessions (join with `untile` to add "
                   "earlier ones)");
}

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
/// `also`: a file the index's metadata names (the consensus), or empty.
void removeLeftovers(const fs::path& folder, const TileIndex* index, const std::string& also = {}) {
  std::set<std::string> named;
  if (!also.empty()) named.insert(also);
  if (index) {
    for (const TileEntry& e : index->tiles) {
      named.insert(e.file);
      if (e.latest) named.insert(e.latest->file);
      for (const WindowFile& w : e.windows) named.insert(w.file);
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

/// Checks that `folder` can take a tiled map; returns whether it existed.
bool checkFolder(const fs::path& folder) {
  if (fs::exists(folder) && !fs::is_directory(folder)) {
    throw UsageError("'" + folder.string() + "' exists and is not a folder (a tiled map is a folder)");
  }
  const bool existed = fs::exists(folder);
  if (existed && !isTiledMap(folder) && !onlyLeftovers(folder)) {
    throw UsageError("'" + folder.string() + "' is a folder but not a tiled 4D map (it has no " +
                     kTileIndexName + ")");
  }
  return existed;
}

/// A new map that failed leaves no folder behind.
struct FolderCleanup {
  fs::path path;
  bool armed;
  ~FolderCleanup() {
    std::error_code ec;
    if (!armed || fs::exists(path / kTileIndexName, ec)) return;
    fs::remove_all(path / "tiles", ec);
    if (fs::is_directory(path, ec) && fs::is_empty(path, ec)) fs::remove(path, ec);
  }
};

/// The tile level: the stored map's, else the one asked for; checks that the sessions fit.
int tileLevelOf(const StreamSettings& s, const std::optional<TileIndex>& index, const TemporalMap& top) {
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
  return level;
}

/// The generation this build writes its tiles under: one past the stored map's newest (its
/// tiles' and its consensus file's).
uint64_t nextGeneration(const std::optional<TileIndex>& index, const std::optional<StoredConsensus>& consensus) {
  uint64_t generation = 0;
  if (index) {
    for (const TileEntry& e : index->tiles) {
      generation = std::max(generation, *tileGeneration(e.key, e.file));
      for (const WindowFile& w : e.windows) generation = std::max(generation, windowGeneration(e.key, w.file));
    }
  }
  if (consensus) generation = std::max(generation, *consensusGeneration(consensus->file));
  return generation + 1;
}

/// The steps of streamIntoTiles() after the folder is set up, with what they hand each other.
class TileStream {
 public:
  TileStream(const StreamSettings& s, const std::optional<TileIndex>& index, const TemporalMap& top, int level,
             uint64_t generation, uint32_t window_sessions, bool windowed, StreamResult& result)
      : s_(s), index_(index), top_(top), level_(level), generation_(generation), window_sessions_(window_sessions),
        windowed_(windowed), result_(result),
        parts_(s.folder / (".parts-" + std::to_string(::getpid())), s.memory_limit_bytes) {}

  void addSessions(size_t count, const std::function<StreamSession(size_t)>& produce);
  void formGroups();
  void writeGroups();
  void keepUnreached();
  /// The top with the groups' parts in place, every session's record with its coverage
  /// outside the tiles, compacted as a written map is; sorts the entries.
  TemporalMap newTop();

  std::vector<TileEntry>& entries() { return entries_; }
  const std::vector<NewSession>& added() const { return added_; }
  std::vector<int64_t>& nodesAdded() { return nodes_added_; }
  const PartStoreStats& partStats() const { return parts_.stats(); }

 private:
  /// What one group's work gives: kept apart while groups run at once, joined in group order.
  struct GroupOut {
    std::vector<TileEntry> entries;
    std::optional<TemporalMap> top;  // writeSplit()'s part of the top
    StreamStats stats;               // tiles read and written, windows, the group's size
    uint64_t tile_bytes = 0;
    std::vector<int64_t> nodes_added;  // per added session
    std::vector<TileKey> done;         // stored tiles read
    /// A tile written, `kept_windows` of its windows kept from before.
    void wrote(TileEntry e, size_t kept_windows) {
      stats.windows_written += e.windows.size() - kept_windows;
      tile_bytes += e.diskBytes();
      ++stats.tiles_written;
      entries.push_back(std::move(e));
    }
  };
  void addSession(size_t i, StreamSession& session);
  const TileEntry* storedTileOf(const Cube& g) const;
  void writeGroup(const Cube& g, GroupOut& out);
  void rewriteStoredTile(const Cube& g, const TileEntry& e, GroupOut& out);
  void rewriteOpenWindow(const Cube& g, const TileEntry& e, GroupOut& out);
  void countStoredTile(const TileEntry& e, GroupOut& out);
  void addToStoredTile(const Cube& g, TemporalMap& work, GroupOut& out, size_t first);
  void writeSplit(const TemporalMap& work, GroupOut& out);
  TemporalMap groupBase(const Cube& g, std::vector<SessionRecord>& records, GroupOut& out);
  void addGroupSessions(const Cube& g, TemporalMap& work, GroupOut& out, size_t first = 0);
  void joinGroup(const Cube& g, GroupOut& out);

  const StreamSettings& s_;
  const std::optional<TileIndex>& index_;
  const TemporalMap& top_;
  const int level_;
  const uint64_t generation_;
  const uint32_t window_sessions_;
  const bool windowed_;
  StreamResult& result_;
  PartStore parts_;
  std::mutex parts_mutex_;     // parts_.take() from groups running at once
  std::mutex progress_mutex_;  // s_.progress from them
  std::vector<NewSession> added_;
  std::map<Cube, std::vector<uint32_t>, CubeLess> sessions_of_cube_;  // session indices with parts there
  uint32_t base_rank_ = 0;
  std::vector<uint32_t> rank_of_;
  std::vector<Cube> groups_;
  std::vector<int64_t> nodes_added_;
  std::vector<SessionRecord> all_;
  std::vector<TileEntry> entries_;
  std::vector<TemporalMap> group_tops_;
  std::vector<Cube> group_cubes_;
  std::set<TileKey> done_;
};

// 1. Each session in turn: its record, and its leaves cut to the tiles (a leaf of tile size or
// larger stays whole).
void TileStream::addSessions(size_t count, const std::function<StreamSession(size_t)>& produce) {
  for (size_t i = 0; i < count; ++i) {
    StreamSession session = produce(i);
    addSession(i, session);
  }
  std::stable_sort(added_.begin(), added_.end(),
                   [](const NewSession& a, const NewSession& b) { return a.time_s < b.time_s; });
  for (size_t k = 1; k < added_.size(); ++k) {
    if (added_[k].time_s == added_[k - 1].time_s) {
      throw UsageError(added_[k - 1].name + " and " + added_[k].name + " have the same time " +
                       formatTime(added_[k].time_s));
    }
  }
  base_rank_ = static_cast<uint32_t>(top_.sessionCount());
  rank_of_.resize(count);
  for (size_t k = 0; k < added_.size(); ++k) rank_of_[added_[k].index] = base_rank_ + static_cast<uint32_t>(k);
}

void TileStream::addSession(size_t i, StreamSession& session) {
  const TemporalMap& top = top_;
  if (session.map.resolution_m() != top.resolution_m()) {
    throw UsageError(session.name + ": session resolution " + std::to_string(session.map.resolution_m()) +
                     " m differs from the tiled map's " + std::to_string(top.resolution_m()) + " m");
  }
  if (!std::isfinite(session.time_s)) throw UsageError(session.name + ": session time must be finite");
  if (top.sessionCount() && session.time_s <= top.sessions().back().time_s) {
    refuseEarlier(session.name, session.time_s, top.sessions().back().time_s);
  }
  added_.push_back(NewSession{i, session.time_s, session.name, Coverage(session.map),
                              session.map.innerCount() + session.map.leafCount()});
  session.map.forEachLeaf([&](const LeafView& leaf) {
    const Cube cube = leaf.level < level_ ? cubeAt(leaf.key, level_) : Cube{leaf.key, leaf.level};
    parts_.add(cube, SessionPart{static_cast<uint32_t>(i), leaf.key.x, leaf.key.y, leaf.key.z,
                          static_cast<uint8_t>(leaf.level), 0, leaf.counters});
    std::vector<uint32_t>& who = sessions_of_cube_[cube];
    if (who.empty() || who.back() != i) who.push_back(static_cast<uint32_t>(i));
  });
}

// 2. Groups: a tile, or a uniform cube of the top (or a session's leaf) of tile size or more
// with everything inside it. Groups are disjoint; largest first.
void TileStream::formGroups() {
  const TemporalMap::Parts top_parts = top_.parts();
  std::set<Cube, CubeLess> promoted;  // largest first
  for (const Cube& c : parts_.cubes()) {
    const TopPath path = walkTop(top_parts, c);
    promoted.insert(path.list ? *path.list : c);
  }
  std::vector<Cube>& groups = groups_;
  for (const Cube& g : promoted) {
    if (std::none_of(groups.begin(), groups.end(), [&](const Cube& h) { return h.contains(g); })) groups.push_back(g);
  }
  std::sort(groups.begin(), groups.end(), [](const Cube& a, const Cube& b) {
    return mortonEncode(a.corner) < mortonEncode(b.corner) ||
           (mortonEncode(a.corner) == mortonEncode(b.corner) && a.level > b.level);
  });
  // Inner nodes of the top that the sessions create on the way to a group, each counted for
  // the first session (in time order) that reaches it, as TemporalMap::add counts them.
  nodes_added_.assign(added_.size(), 0);
  std::map<Cube, uint32_t, CubeLess> new_nodes;
  for (const Cube& g : groups) {
    uint32_t first = UINT32_MAX;
    for (const auto& [c, who] : sessions_of_cube_) {
      if (!g.contains(c)) continue;
      for (const uint32_t i : who) first = std::min(first, rank_of_[i]);
    }
    for (const int l : walkTop(top_parts, g).missing_levels) {
      auto [it, fresh] = new_nodes.emplace(cubeAt(g.corner, l), first);
      if (!fresh) it->second = std::min(it->second, first);
    }
  }
  for (const auto& [c, r] : new_nodes) ++nodes_added_[r - base_rank_];
}

// 3. Each group: its part of the top and its tiles, the sessions added in time order,
// compacted, cut into tiles again, written under the new generation's names. Groups are
// disjoint, so up to s_.threads of them run at once, each on its own thread; what each gives is
// joined in group order, so the files, the top and the figures are the same for every thread
// count. A failed group stops the groups after it from starting, and the error given is the
// first group's in order, as one thread gives it.
void TileStream::writeGroups() {
  all_ = top_.sessions();
  for (const NewSession& n : added_) {
    SessionRecord r;
    r.time_s = n.time_s;
    r.name = n.name;
    r.coverage = n.coverage;
    r.nodes_separate = n.nodes_separate;
    all_.push_back(std::move(r));
  }
  fs::create_directories(s_.folder / "tiles");
  const size_t n = groups_.size();
  std::vector<GroupOut> outs(n);
  std::atomic<size_t> finished{0};
  pipeline_detail::runInOrder(n, s_.threads, [&](size_t k) {
    {
      const std::lock_guard<std::mutex> lock(progress_mutex_);
      s_.progress.advance("tiles", finished.load(), n);
    }
    writeGroup(groups_[k], outs[k]);
    ++finished;
  });
  for (size_t k = 0; k < n; ++k) joinGroup(groups_[k], outs[k]);
}

// One group, read, added to and written; what it gives goes to `out`.
void TileStream::writeGroup(const Cube& g, GroupOut& out) {
  out.nodes_added.assign(added_.size(), 0);
  if (const TileEntry* e = storedTileOf(g)) {
    rewriteStoredTile(g, *e, out);
    return;
  }
  std::vector<SessionRecord> records;
  TemporalMap work = groupBase(g, records, out);
  addGroupSessions(g, work, out);
  out.stats.peak_group_bytes = std::max(out.stats.peak_group_bytes, work.memoryBytes());
  for (SessionRecord& r : clipped(std::vector<SessionRecord>(all_.begin() + base_rank_, all_.end()), g)) {
    records.push_back(std::move(r));
  }
  work = TemporalMap::fromParts(work.resolution_m(), work.criterion(), work.parts(), std::move(records));
  work.compact(TemporalMap::Relayout::kWhenMerged);  // written, then dropped
  writeSplit(work, out);
}

// A group's output joined to the build's, in group order.
void TileStream::joinGroup(const Cube& g, GroupOut& out) {
  for (TileEntry& e : out.entries) entries_.push_back(std::move(e));
  if (out.top) {
    group_tops_.push_back(std::move(*out.top));
    group_cubes_.push_back(g);
  }
  StreamStats& st = result_.stats;
  st.tiles_read += out.stats.tiles_read;
  st.tiles_written += out.stats.tiles_written;
  st.windows_written += out.stats.windows_written;
  st.largest_group_tiles = std::max(st.largest_group_tiles, out.stats.largest_group_tiles);
  st.peak_group_bytes = std::max(st.peak_group_bytes, out.stats.peak_group_bytes);
  result_.tile_bytes += out.tile_bytes;
  for (size_t k = 0; k < out.nodes_added.size(); ++k) nodes_added_[k] += out.nodes_added[k];
  done_.insert(out.done.begin(), out.done.end());
  ++st.groups;
  out = GroupOut{};
}

// The stored tile whose cube the group is, if any. Such a group holds nothing but that tile: the
// top has no node inside a stored tile's cube, and a uniform cube of the top around it would have
// been the group.
const TileEntry* TileStream::storedTileOf(const Cube& g) const {
  if (!index_ || g.level != level_) return nullptr;
  const TileEntry* e = index_->find(tileOf(g.corner, level_));
  return e && tileCorner(e->key, level_) == g.corner ? e : nullptr;
}

// A stored tile read for a group that is that tile alone.
void TileStream::countStoredTile(const TileEntry& e, GroupOut& out) {
  ++out.stats.tiles_read;
  out.done.push_back(e.key);
  out.stats.largest_group_tiles = std::max<size_t>(out.stats.largest_group_tiles, 1);
}

// The new sessions added to a stored tile's history, or to its open window (whose session 0 is
// the index's session `first`), with their records clipped to the tile; compacted.
void TileStream::addToStoredTile(const Cube& g, TemporalMap& work, GroupOut& out, size_t first) {
  std::vector<SessionRecord> records = work.sessions();
  addGroupSessions(g, work, out, first);
  out.stats.peak_group_bytes = std::max(out.stats.peak_group_bytes, work.memoryBytes());
  for (SessionRecord& r : clipped(std::vector<SessionRecord>(all_.begin() + base_rank_, all_.end()), g)) {
    records.push_back(std::move(r));
  }
  work.replaceSessionRecords(std::move(records));
  work.compact(TemporalMap::Relayout::kWhenMerged);  // written, then dropped
}

// A group that is one stored tile: the tile read, the sessions added, written again. The same
// bytes as the general path (the top cut to the cube, the tile joined in, the group split
// again), without its three copies of the tile; the top keeps its nodes around the tile.
void TileStream::rewriteStoredTile(const Cube& g, const TileEntry& e, GroupOut& out) {
  if (windowed_) {
    rewriteOpenWindow(g, e, out);
    return;
  }
  TemporalMap work = readTile(s_.folder, *index_, e);
  countStoredTile(e, out);
  addToStoredTile(g, work, out, 0);
  const std::vector<HistoryEntry> corner = work.history(g.corner);
  if (!corner.empty() && corner.front().level >= level_) {
    // Compaction made the whole tile one uniform cube (not seen with later sessions only): it
    // belongs in the top, as the general path's split puts it.
    writeSplit(work, out);
    return;
  }
  // The windows written before hold earlier sessions only, which these did not change.
  out.wrote(writeTileFile(s_.folder, e.key, generation_, work, window_sessions_, e.windows), e.windows.size());
}

// The same for a tile kept as windows (TileIndex::windowed): the open window alone is read,
// added to, compacted and written. It is closed first when it holds a whole window of sessions
// of its own (the first window: firstWindowSessions, staggered over the tiles): its file stays
// as it is, as the last closed window, and the new open window continues it (continuedWindow),
// the sessions that did not reach the tile since appended unobserved. Where compaction leaves
// the open window one uniform cube, the whole history is joined to tell whether the tile itself
// is (it then goes to the top, as rewriteStoredTile's).
void TileStream::rewriteOpenWindow(const Cube& g, const TileEntry& e, GroupOut& out) {
  TemporalMap work = readOpenWindow(s_.folder, *index_, e);
  countStoredTile(e, out);
  std::vector<WindowFile> closed = e.windows;
  size_t first = openWindowFirst(e);
  const size_t own = work.sessionCount() - (closed.empty() ? 0 : 1);
  if (own >= (closed.empty() ? firstWindowSessions(e.key, window_sessions_) : window_sessions_)) {
    closed.push_back(WindowFile{e.file, e.bytes, e.crc32, work.sessionCount()});
    first += work.sessionCount() - 1;
    work = continuedWindow(work);
  }
  const std::vector<SessionRecord>& stored = top_.sessions();
  work.appendUnobservedSessions(
      std::vector<SessionRecord>(stored.begin() + static_cast<std::ptrdiff_t>(first + work.sessionCount()), stored.end()));
  addToStoredTile(g, work, out, first);
  const std::vector<HistoryEntry> corner = work.history(g.corner);
  if (!corner.empty() && corner.front().level >= level_) {
    std::vector<TemporalMap> windows = readClosedWindows(s_.folder, *index_, e.key, closed);
    windows.push_back(std::move(work));
    const TemporalMap whole = joinWindows(windows);
    const std::vector<HistoryEntry> whole_corner = whole.history(g.corner);
    if (!whole_corner.empty() && whole_corner.front().level >= level_) {
      writeSplit(whole, out);
      return;
    }
    work = std::move(windows.back());
  }
  const size_t kept = closed.size();  // (a window closed here keeps its file: none written)
  out.wrote(writeOpenWindow(s_.folder, e.key, generation_, work, std::move(closed)), kept);
}

// A group's compacted map cut into tiles (written under the new generation's names) and its part
// of the top (kept for newTop()).
void TileStream::writeSplit(const TemporalMap& work, GroupOut& out) {
  SplitMap split = splitIntoTiles(work, level_);
  for (const Tile& t : split.tiles) {
    out.wrote(windowed_ ? writeTileAsWindows(s_.folder, t.key, generation_, t.map, window_sessions_)
                        : writeTileFile(s_.folder, t.key, generation_, t.map, window_sessions_),
              0);
  }
  out.top = std::move(split.top);
}

// The group's part of the stored map: the top's part with the group's tiles joined in; `records`
// gets the stored sessions' records there (the top's coverage outside the tiles joined with the
// tiles' own).
TemporalMap TileStream::groupBase(const Cube& g, std::vector<SessionRecord>& records, GroupOut& out) {
  std::vector<Tile> tiles;
  if (index_) {
    for (const TileEntry& e : index_->tiles) {
      if (g.contains(Cube{tileCorner(e.key, level_), level_})) {
        tiles.push_back(Tile{e.key, readTile(s_.folder, *index_, e)});
        ++out.stats.tiles_read;
        out.done.push_back(e.key);
      }
    }
  }
  out.stats.largest_group_tiles = std::max(out.stats.largest_group_tiles, tiles.size());
  records = clipped(top_.sessions(), g);
  TemporalMap work = restrictToCube(top_, g, records);
  if (!tiles.empty()) {
    std::vector<const Tile*> refs;
    for (const Tile& t : tiles) refs.push_back(&t);
    work = joinTiles(work, level_, refs);
    records = work.sessions();
    tiles.clear();
  }
  return work;
}

// The new sessions' parts inside the group, added to `work` in time order.
void TileStream::addGroupSessions(const Cube& g, TemporalMap& work, GroupOut& out, size_t first) {
  std::vector<std::vector<SessionPart>> by_session(added_.size());
  for (const Cube& c : parts_.cubes()) {  // the set does not change while groups run
    if (!g.contains(c)) continue;
    std::vector<SessionPart> parts;
    {
      const std::lock_guard<std::mutex> lock(parts_mutex_);
      parts = parts_.take(c);
    }
    for (const SessionPart& p : parts) by_session[rank_of_[p.session] - base_rank_].push_back(p);
  }
  for (size_t k = 0; k < added_.size(); ++k) {
    SessionMap part(top_.resolution_m());
    for (const SessionPart& p : by_session[k]) {
      const VoxelKey key{p.x, p.y, p.z};
      if (p.level == 0) {
        part.add(key, p.counters);
      } else {
        part.addCube(key, p.level, p.counters);
      }
    }
    by_session[k].clear();
    by_session[k].shrink_to_fit();
    work.add(added_[k].time_s, part, AddSettings{false, added_[k].name});
    out.nodes_added[k] += work.sessions()[base_rank_ - first + k].nodes_added;
  }
}

// 4. The tiles no session reached keep their files, neither read nor written: their rows say
// how many of the sessions they hold, and readTile adds the later ones as unobserved (nothing
// observed there, no entry), which is what rewriting them with the new records would store.
void TileStream::keepUnreached() {
  if (!index_) return;
  for (const TileEntry& e : index_->tiles) {
    if (done_.count(e.key)) continue;
    TileEntry kept = e;
    kept.sessions = e.sessions.value_or(top_.sessionCount());
    entries_.push_back(std::move(kept));
    result_.tile_bytes += e.diskBytes();
    ++result_.stats.tiles_kept;
  }
}

TemporalMap TileStream::newTop() {
  std::vector<CubePart> replaced;
  for (size_t k = 0; k < group_cubes_.size(); ++k) replaced.push_back(CubePart{group_cubes_[k], &group_tops_[k]});
  for (size_t k = 0; k < added_.size(); ++k) all_[base_rank_ + k].nodes_added = nodes_added_[k];
  std::vector<TileKey> tile_keys;
  for (const TileEntry& e : entries_) tile_keys.push_back(e.key);
  for (SessionRecord& r : all_) r.coverage = clipCoverageOutside(r.coverage, tile_keys, level_);
  TemporalMap new_top = replaceCubes(top_, replaced, std::move(all_));
  group_tops_.clear();
  new_top.compact();
  std::sort(entries_.begin(), entries_.end(),
            [](const TileEntry& a, const TileEntry& b) { return a.key < b.key; });
  return new_top;
}

}  // namespace

StreamResult streamIntoTiles(const StreamSettings& s, size_t count,
                             const std::function<StreamSession(size_t)>& produce) {
  s.criterion.validate();
  const bool existed = checkFolder(s.folder);
  fs::create_directories(s.folder);
  FolderCleanup cleanup{s.folder, !existed || !isTiledMap(s.folder)};
  // The folder itself is locked: the index is replaced by a rename, the folder stays.
  const FileLock lock(s.folder);

  StreamResult result;
  std::optional<TileIndex> index;
  std::optional<StoredConsensus> consensus_before;
  if (isTiledMap(s.folder)) {
    index = readTileIndex(s.folder);
    consensus_before = readStoredConsensus(s.folder, userMetadataOf(readCmap(s.folder / kTileIndexName)),
                                           index->top.resolution_m());
  }
  result.created = !index;
  const TemporalMap top = index ? index->top : TemporalMap(s.resolution_m, s.criterion);
  const int level = tileLevelOf(s, index, top);
  result.tile_level = level;
  const uint64_t generation = nextGeneration(index, consensus_before);
  removeLeftovers(s.folder, index ? &*index : nullptr, consensus_before ? consensus_before->file : std::string());

  // The consensus of every session, each added to it as it arrives (one session map at a time).
  std::optional<StoredConsensus> consensus = std::move(consensus_before);
  if (!consensus && s.keep_consensus) {
    consensus = s.first_consensus ? std::move(*s.first_consensus)
                                  : StoredConsensus{SessionMap(top.resolution_m()), 0, ""};
  }
  const std::function<StreamSession(size_t)> summed = [&](size_t i) {
    StreamSession session = produce(i);
    if (consensus) {
      const SessionMap* both[] = {&consensus->map, &session.map};
      consensus->map = chronomap::consensus(std::span<const SessionMap* const>(both));
      ++consensus->sessions;
    }
    return session;
  };

  const uint32_t window_sessions = index && index->window_sessions > 0 ? index->window_sessions : s.window_sessions;
  const bool windowed = index ? index->windowed : s.windowed_tiles;
  if (index && s.windowed_tiles && !index->windowed) {
    result.warnings.push_back(s.folder.string() + " keeps its whole-history tiles: --windowed-tiles applies to a new "
                              "tiled map (cut this one again with `untile` and `tile --windowed-tiles`)");
  }
  if (windowed && window_sessions == 0) throw UsageError("tiles kept as windows need windows of one session or more");
  TileStream stream(s, index, top, level, generation, window_sessions, windowed, result);
  stream.addSessions(count, summed);
  stream.formGroups();
  stream.writeGroups();
  stream.keepUnreached();
  // 5. The top, then the index, swapped in by one rename; then the old files go.
  const TemporalMap new_top = stream.newTop();
  const std::vector<TileEntry>& entries = stream.entries();
  nlohmann::json meta = {{"created_by", "chronomap build --tiles"}};
  if (s.metadata.is_object()) meta.update(s.metadata);
  std::string consensus_file;
  if (consensus) {
    meta[kConsensusKey] = writeStoredConsensus(s.folder, generation, consensus->map, consensus->sessions);
    consensus_file = meta[kConsensusKey]["file"].get<std::string>();
    result.consensus_sessions = consensus->sessions;
  }
  result.index_bytes = writeTileIndex(s.folder, new_top, level, entries, meta, window_sessions, windowed);
  cleanup.armed = false;
  TileIndex written{level, window_sessions, TemporalMap(new_top.resolution_m()), entries, windowed};
  removeLeftovers(s.folder, &written, consensus_file);

  result.stats.spills = stream.partStats().spills;
  result.stats.spilled_bytes = stream.partStats().spilled_bytes;
  result.stats.peak_parts_bytes = stream.partStats().peak_bytes;
  result.sessions = new_top.sessionCount();
  result.tiles = entries.size();
  for (const NewSession& n : stream.added()) result.added_times.push_back(n.time_s);
  result.nodes_added = std::move(stream.nodesAdded());
  return result;
}

SessionMap consensusOfTiles(const fs::path& folder, int threads) {
  const TileIndex index = readTileIndex(folder);
  const std::vector<SessionRecord>& sessions = index.top.sessions();
  if (sessions.empty()) return SessionMap(index.top.resolution_m());
  const double t0 = sessions.front().time_s, t1 = sessions.back().time_s;
  // The parts are disjoint (the top's slot is empty where a tile hangs): summed once at the end.
  // Tiles are read on every core, one tile's history in memory per thread.
  std::vector<SessionMap> parts(index.tiles.size() + 1, SessionMap(index.top.resolution_m()));
  parts[0] = consensus(index.top, t0, t1);
  pipeline_detail::runInOrder(index.tiles.size(), threads, [&](size_t k) {
    parts[k + 1] = consensus(readTile(folder, index, index.tiles[k]), t0, t1);
  });
  return consensus(std::span<const SessionMap>(parts));
}

StreamResult streamBuild(const BuildSettings& b, std::optional<double> tile_size_m, size_t memory_limit_bytes,
                         uint32_t window_sessions, bool windowed_tiles) {
  if (b.realign) throw UsageError("--realign cannot be used with --tiles (it needs every session at once)");
  if (b.replace) throw UsageError("--replace cannot be used with --tiles");
  pipeline_detail::checkInputs(b);
  // One up for every session, the tiled map's own when it records one (as build() chooses it).
  const bool created = !isTiledMap(b.map);
  const nlohmann::json stored =
      created ? nlohmann::json::object() : userMetadataOf(readCmap(b.map / kTileIndexName));
  const ChosenUp up = chooseBuildUp(b, created, stored);
  const BuildSettings with_up = pipeline_detail::withUp(b, up);
  StreamSettings s;
  s.metadata = pipeline_detail::mapMetadata(stored, up);
  s.folder = b.map;
  s.resolution_m = b.session.resolution_m;
  s.criterion = b.criterion;
  s.tile_size_m = tile_size_m;
  s.memory_limit_bytes = memory_limit_bytes;
  s.window_sessions = window_sessions;
  s.windowed_tiles = windowed_tiles;
  s.threads = b.session.integrator.threads;  // --threads: the tiles' groups too
  s.progress = b.progress;
  std::vector<std::string> warnings;
  auto sessionOf = [&](pipeline_detail::Pending& p) {
    for (const std::string& w : p.session.warnings) warnings.push_back(b.datasets[p.index].string() + ": " + w);
    return StreamSession{p.time_s, b.datasets[p.index].filename().string(), std::move(p.session.map)};
  };
  if (!b.registration) {
    StreamResult result = streamIntoTiles(s, b.datasets.size(), [&](size_t i) {
      pipeline_detail::Pending p = pipeline_detail::integrateOne(with_up, i);
      return sessionOf(p);
    });
    result.warnings.insert(result.warnings.begin(), warnings.begin(), warnings.end());
    return result;
  }
  // Registration: the recordings integrated, sorted and registered as build() does, then streamed;
  // a time the tiled map cannot take is refused before the registration's long work. The stored
  // sessions take part through their consensus, when the map keeps one.
  const BuildSettings r = pipeline_detail::withRegistrationCache(with_up);
  std::vector<pipeline_detail::Pending> pending;
  for (size_t i = 0; i < b.datasets.size(); ++i) pending.push_back(pipeline_detail::integrateOne(r, i));
  pipeline_detail::sortByTime(r, pending);
  std::optional<StoredConsensus> prior;
  if (!created) {
    const TileIndex index = readTileIndex(b.map);
    const std::vector<SessionRecord>& stored_sessions = index.top.sessions();
    if (!stored_sessions.empty() && pending.front().time_s <= stored_sessions.back().time_s) {
      refuseEarlier(b.datasets[pending.front().index].string(), pending.front().time_s, stored_sessions.back().time_s);
    }
    prior = readStoredConsensus(b.map, stored, index.top.resolution_m());
    if (!prior && !stored_sessions.empty()) {
      const std::string n = std::to_string(stored_sessions.size());
      b.progress.say("computing the consensus of the " + n + " stored session(s) from their histories");
      prior = StoredConsensus{consensusOfTiles(b.map, b.session.integrator.threads), stored_sessions.size(), ""};
      warnings.push_back(b.map.string() + ": kept no consensus of its " + n +
                         " stored session(s) (built without --register, or cut by `tile`): computed once from "
                         "their histories, every tile read, and kept from now on");
    }
  }
  std::vector<PoseCorrection> corrections =
      pipeline_detail::registerPending(r, pending, prior ? &prior->map : nullptr);
  // A computed consensus goes on to be stored; a stored one streamIntoTiles reads again, under
  // the folder's lock.
  if (prior && prior->file.empty()) s.first_consensus = std::make_shared<StoredConsensus>(std::move(*prior));
  prior.reset();
  s.keep_consensus = true;
  StreamResult result = streamIntoTiles(s, pending.size(), [&](size_t k) { return sessionOf(pending[k]); });
  result.warnings.insert(result.warnings.begin(), warnings.begin(), warnings.end());
  result.corrections = std::move(corrections);
  return result;
}

StreamResult streamAddSession(const AddSessionSettings& a, size_t memory_limit_bytes) {
  if (a.replace) throw UsageError("--replace cannot be used on a tiled map");
  if (a.realign) throw UsageError("--realign cannot be used on a tiled map");
  if (a.write != WritePolicy::Auto) throw UsageError("--write does not apply to a tiled map");
  if (!isTiledMap(a.map)) throw UsageError("'" + a.map.string() + "' is not a tiled 4D map");
  const CmapFile file = readCmap(a.session);
  SessionMap session = sessionMapFrom(file, a.session.string());
  const double time_s = pipeline_detail::sessionTime(a, file);
  StreamSettings s;
  // The map keeps its up axis; a session of another is refused (as addSession refuses it).
  const nlohmann::json stored = userMetadataOf(readCmap(a.map / kTileIndexName));
  const ChosenUp map_up = storedUp(stored, a.map.string());
  pipeline_detail::refuseOtherUp(a.session, storedUp(metadataOf(file), a.session.string()), a.map, map_up);
  s.metadata = upKeysOf(stored);
  s.folder = a.map;
  s.resolution_m = session.resolution_m();
  s.criterion = a.criterion;
  s.memory_limit_bytes = memory_limit_bytes;
  s.threads = a.threads;
  return streamIntoTiles(s, 1, [&](size_t) {
    return StreamSession{time_s, a.session.filename().string(), std::move(session)};
  });
}

}  // namespace chronomap
