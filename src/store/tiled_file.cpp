#include "chronomap/store/tiled_file.h"

#include <zlib.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/temporal/window.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

uint32_t crc32Of(const std::vector<uint8_t>& bytes) {
  uLong c = crc32(0L, Z_NULL, 0);
  size_t at = 0;
  while (at < bytes.size()) {  // zlib takes 32-bit lengths
    const auto n = static_cast<uInt>(std::min<size_t>(bytes.size() - at, 1u << 30));
    c = crc32(c, bytes.data() + at, n);
    at += n;
  }
  return static_cast<uint32_t>(c);
}

}  // namespace

const TileEntry* TileIndex::find(const TileKey& key) const {
  const auto it = std::lower_bound(tiles.begin(), tiles.end(), key,
                                   [](const TileEntry& e, const TileKey& k) { return e.key < k; });
  return it != tiles.end() && it->key == key ? &*it : nullptr;
}

std::string tileFileName(const TileKey& key, uint64_t generation) {
  std::string name = "tiles/" + std::to_string(key.x) + "_" + std::to_string(key.y) + "_" + std::to_string(key.z);
  if (generation > 0) name += ".g" + std::to_string(generation);
  return name + ".cmap";
}

namespace {

/// N when `file` is `head` N ".cmap", N a generation as the writers spell it (decimal, no leading
/// zero, at most 18 digits); else nullopt.
std::optional<uint64_t> generationAfter(const std::string& head, const std::string& file) {
  const std::string tail = ".cmap";
  if (file.size() <= head.size() + tail.size() || file.compare(0, head.size(), head) != 0 ||
      file.compare(file.size() - tail.size(), tail.size(), tail) != 0) {
    return std::nullopt;
  }
  const std::string digits = file.substr(head.size(), file.size() - head.size() - tail.size());
  if (digits.size() > 18 || digits[0] == '0' ||
      !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return std::nullopt;
  }
  return std::stoull(digits);
}

}  // namespace

std::optional<uint64_t> tileGeneration(const TileKey& key, const std::string& file) {
  const std::string stem = tileFileName(key);
  if (file == stem) return 0;
  return generationAfter(stem.substr(0, stem.size() - 5) + ".g", file);
}

std::string latestFileName(const std::string& tile_file) {
  return tile_file.substr(0, tile_file.size() - 5) + ".latest.cmap";
}

std::string windowFileName(const std::string& tile_file, size_t j) {
  return tile_file.substr(0, tile_file.size() - 5) + ".w" + std::to_string(j) + ".cmap";
}

size_t openWindowFirst(const TileEntry& entry) {
  size_t first = 0;  // window j + 1 begins with window j's last session
  for (const WindowFile& w : entry.windows) first += w.sessions - 1;
  return first;
}

uint32_t firstWindowSessions(const TileKey& key, uint32_t k) {
  if (k == 0 || k > 0xffff) throw UsageError("windows of " + std::to_string(k) + " sessions: 1 to 65535");
  // splitmix64's finaliser over the packed key: neighbouring tiles get unrelated shares.
  uint64_t h = (uint64_t{key.x} << 32) | (uint64_t{key.y} << 16) | key.z;
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ULL;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebULL;
  h ^= h >> 31;
  return k + static_cast<uint32_t>(h % k);
}

namespace {

/// True when `file` is windowFileName(tileFileName(key, g), j) for some generation g.
bool isWindowFileOf(const TileKey& key, const std::string& file, size_t j) {
  const std::string tail = ".w" + std::to_string(j) + ".cmap";
  if (file.size() <= tail.size() || file.compare(file.size() - tail.size(), tail.size(), tail) != 0) return false;
  return tileGeneration(key, file.substr(0, file.size() - tail.size()) + ".cmap").has_value();
}

/// Writes the state of `tile` at its last session beside `e`'s file as its latest state.
void writeLatestState(const fs::path& folder, const TemporalMap& tile, TileEntry& e) {
  if (tile.sessionCount() == 0) return;
  const SessionMap state = tile.snapshot(tile.sessions().back().time_s);
  const std::vector<uint8_t> latest = encodeSessionMap(state, nlohmann::json::object());
  e.latest = LatestState{latestFileName(e.file), latest.size(), crc32Of(latest)};
  writeFileAtomic(folder / e.latest->file, latest);
}

}  // namespace

uint64_t windowGeneration(const TileKey& key, const std::string& file) {
  if (const auto g = tileGeneration(key, file)) return *g;
  const size_t w = file.rfind(".w");
  if (w != std::string::npos) {
    if (const auto g = tileGeneration(key, file.substr(0, w) + ".cmap")) return *g;
  }
  throw UsageError("'" + file + "' is not a window file name of its tile");
}

namespace {

/// Writes a tile's file and its latest state under `name` in `folder`, and its windows after
/// `kept` (see writeTileFile); its row of the table.
TileEntry writeTileAndLatest(const fs::path& folder, const TileKey& key, const std::string& name,
                             const TemporalMap& tile, uint32_t window_sessions, std::vector<WindowFile> kept) {
  const std::vector<uint8_t> bytes = encodeTemporalMap(tile, nlohmann::json::object());
  TileEntry e{key, name, bytes.size(), crc32Of(bytes), std::nullopt, std::nullopt, std::move(kept)};
  writeFileAtomic(folder / e.file, bytes);
  if (window_sessions > 0 && (e.windows.size() + 1) * window_sessions <= tile.sessionCount()) {
    const TemporalMap::Parts parts = tile.parts();  // once for all the windows written
    for (size_t j = e.windows.size(); (j + 1) * window_sessions <= tile.sessionCount(); ++j) {
      const TemporalMap window =
          historyWindow(tile, parts, static_cast<uint32_t>(j * window_sessions), window_sessions);
      const std::vector<uint8_t> w =
          encodeTemporalMapAsItIs(window, {{"window", {{"first_session", j * window_sessions}}}});
      e.windows.push_back(WindowFile{windowFileName(name, j), w.size(), crc32Of(w)});
      writeFileAtomic(folder / e.windows.back().file, w);
    }
  }
  writeLatestState(folder, tile, e);
  return e;
}

/// Writes `e`'s open window `open` as it is (no compaction: a window's tree is its own), with its
/// latest state; fills in the row's file fields.
void writeWindowAndLatest(const fs::path& folder, const TemporalMap& open, TileEntry& e) {
  const std::vector<uint8_t> bytes = encodeTemporalMapAsItIs(open, nlohmann::json::object());
  e.bytes = bytes.size();
  e.crc32 = crc32Of(bytes);
  writeFileAtomic(folder / e.file, bytes);
  writeLatestState(folder, open, e);
}

/// The index's "tiles" member: version 2 only when a tile holds fewer than all `sessions`, 3
/// only when a tile has windows, so that a table without either keeps version 1's bytes (and
/// older builds read it).
nlohmann::json tableOf(const std::vector<TileEntry>& tiles, int tile_level, size_t sessions, uint32_t window_sessions,
                       bool windowed) {
  nlohmann::json list = nlohmann::json::array();
  int version = 1;
  bool windows = false;
  for (const TileEntry& t : tiles) {
    nlohmann::json row = {
        {"key", {t.key.x, t.key.y, t.key.z}}, {"file", t.file}, {"bytes", t.bytes}, {"crc32", t.crc32}};
    if (t.latest) {
      row["latest"] = {{"file", t.latest->file}, {"bytes", t.latest->bytes}, {"crc32", t.latest->crc32}};
    }
    if (t.sessions && *t.sessions < sessions) {
      row["sessions"] = *t.sessions;
      version = std::max(version, 2);
    }
    if (!t.windows.empty()) {
      nlohmann::json w = nlohmann::json::array();
      for (const WindowFile& f : t.windows) {
        w.push_back({{"file", f.file}, {"bytes", f.bytes}, {"crc32", f.crc32}});
        if (windowed) w.back()["sessions"] = f.sessions;
      }
      row["windows"] = std::move(w);
      version = 3;
      windows = true;
    }
    list.push_back(std::move(row));
  }
  if (windowed) version = 4;  // the rows' files are open windows, even where none has closed yet
  nlohmann::json table = {{"version", version}, {"level", tile_level}, {"list", std::move(list)}};
  if (windowed) table["layout"] = "windows";
  if (windows || windowed) {
    if (window_sessions == 0) throw UsageError("a tile table with windows needs their session count");
    table["window_sessions"] = window_sessions;
  }
  return {{"tiles", std::move(table)}};
}

}  // namespace

TiledWriteResult writeTiledMap(const fs::path& folder, const SplitMap& split, const nlohmann::json& meta,
                               uint32_t window_sessions, const ForEachPiece& for_each, bool windowed) {
  if (windowed && window_sessions == 0) throw UsageError("the windowed layout needs windows of one session or more");
  TiledWriteResult r;
  StagedFolder staged(folder);
  fs::create_directories(staged.path() / "tiles");
  std::vector<TileEntry> entries(split.tiles.size());
  const std::function<void(size_t)> write = [&](size_t k) {
    const Tile& t = split.tiles[k];
    entries[k] = windowed ? writeTileAsWindows(staged.path(), t.key, 0, t.map, window_sessions)
                          : writeTileAndLatest(staged.path(), t.key, tileFileName(t.key), t.map, window_sessions, {});
  };
  if (for_each) {
    for_each(entries.size(), write);
  } else {
    for (size_t k = 0; k < entries.size(); ++k) write(k);
  }
  for (const TileEntry& e : entries) {
    r.tile_bytes += e.diskBytes();
    r.windows += e.windows.size();
    ++r.tiles;
  }
  const nlohmann::json extra = tableOf(entries, split.tile_level, split.top.sessionCount(), window_sessions, windowed);
  const std::vector<uint8_t> index = encodeTemporalMap(split.top, meta, MapKind::Tiled, &extra);
  writeFileAtomic(staged.path() / kTileIndexName, index);
  r.index_bytes = index.size();
  staged.commit();
  return r;
}

TileEntry writeTileFile(const fs::path& folder, const TileKey& key, uint64_t generation, const TemporalMap& tile,
                        uint32_t window_sessions, std::vector<WindowFile> kept) {
  return writeTileAndLatest(folder, key, tileFileName(key, generation), tile, window_sessions, std::move(kept));
}

TileEntry writeOpenWindow(const fs::path& folder, const TileKey& key, uint64_t generation, const TemporalMap& open,
                          std::vector<WindowFile> closed) {
  TileEntry e{key, tileFileName(key, generation), 0, 0, std::nullopt, std::nullopt, std::move(closed)};
  writeWindowAndLatest(folder, open, e);
  return e;
}

TileEntry writeTileAsWindows(const fs::path& folder, const TileKey& key, uint64_t generation, const TemporalMap& tile,
                             uint32_t window_sessions) {
  if (window_sessions == 0) throw UsageError("the windowed layout needs windows of one session or more");
  const std::vector<TemporalMap> windows = windowsOf(tile, window_sessions, firstWindowSessions(key, window_sessions));
  const std::string name = tileFileName(key, generation);
  std::vector<WindowFile> closed;
  for (size_t j = 0; j + 1 < windows.size(); ++j) {
    const std::vector<uint8_t> w = encodeTemporalMapAsItIs(windows[j], nlohmann::json::object());
    closed.push_back(WindowFile{windowFileName(name, j), w.size(), crc32Of(w), windows[j].sessionCount()});
    writeFileAtomic(folder / closed.back().file, w);
  }
  return writeOpenWindow(folder, key, generation, windows.back(), std::move(closed));
}

uint64_t writeTileIndex(const fs::path& folder, const TemporalMap& top, int tile_level,
                        const std::vector<TileEntry>& tiles, const nlohmann::json& meta, uint32_t window_sessions,
                        bool windowed) {
  const nlohmann::json extra = tableOf(tiles, tile_level, top.sessionCount(), window_sessions, windowed);
  const std::vector<uint8_t> index = encodeTemporalMap(top, meta, MapKind::Tiled, &extra);
  writeFileAtomic(folder / kTileIndexName, index);
  return index.size();
}

TileIndex decodeTileIndex(const std::vector<uint8_t>& bytes, const std::string& source) {
  const CmapFile file = decodeCmap(bytes, source);
  if (file.header.kind != MapKind::Tiled) {
    throw FormatError(source + ": holds a " + std::string(kindName(file.header.kind)) + " map, not a tile index");
  }
  TileIndex index{0, 0, decodeTemporalBlocks(file, source), {}};
  const CmapBlock& meta = file.block("META", source);
  const nlohmann::json j = nlohmann::json::parse(meta.data.begin(), meta.data.end(), nullptr, false);
  try {
    const nlohmann::json& t = j.at("tiles");
    const int version = t.at("version").get<int>();
    if (version < kOldestTileTableVersion || version > kTileTableVersion) {
      throw FormatError(source + ": tile table version " + std::to_string(version) + " is not one this build reads (" +
                        std::to_string(kOldestTileTableVersion) + " to " + std::to_string(kTileTableVersion) +
                        "); a newer chronomap wrote it: read it with that version");
    }
    if (version == 4) {
      const auto layout = t.find("layout");
      if (layout == t.end() || *layout != "windows") {
        throw FormatError(source + ": a version 4 tile table names no layout this build reads");
      }
      index.windowed = true;
    }
    index.tile_level = t.at("level").get<int>();
    if (index.tile_level < kMinTileLevel || index.tile_level > kMaxTileLevel) {
      throw FormatError(source + ": invalid tile level " + std::to_string(index.tile_level));
    }
    if (index.windowed && !t.contains("window_sessions")) {
      throw FormatError(source + ": a windowed tile table without its window session count");
    }
    if (const auto k = t.find("window_sessions"); k != t.end()) {
      const uint64_t n = k->get<uint64_t>();
      if (version < 3 || n == 0 || n > 0xffffu) {
        throw FormatError(source + ": invalid window session count " + std::to_string(n) + " in a version " +
                          std::to_string(version) + " tile table");
      }
      index.window_sessions = static_cast<uint32_t>(n);
    }
    const uint32_t max_key = (uint32_t{1} << (kTreeDepth - index.tile_level)) - 1;
    for (const nlohmann::json& row : t.at("list")) {
      TileEntry e;
      const nlohmann::json& k = row.at("key");
      if (!k.is_array() || k.size() != 3) throw FormatError(source + ": a tile key is not three numbers");
      const uint32_t x = k[0].get<uint32_t>(), y = k[1].get<uint32_t>(), z = k[2].get<uint32_t>();
      if (x > max_key || y > max_key || z > max_key) throw FormatError(source + ": a tile key lies outside the map");
      e.key = TileKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)};
      e.file = row.at("file").get<std::string>();
      // The name is derived from the key: nothing else (no other folder) is ever opened.
      if (!tileGeneration(e.key, e.file)) {
        throw FormatError(source + ": tile file name '" + e.file + "' does not match its key");
      }
      e.bytes = row.at("bytes").get<uint64_t>();
      e.crc32 = row.at("crc32").get<uint32_t>();
      if (const auto latest = row.find("latest"); latest != row.end()) {
        LatestState l{latest->at("file").get<std::string>(), latest->at("bytes").get<uint64_t>(),
                      latest->at("crc32").get<uint32_t>()};
        if (l.file != latestFileName(e.file)) {
          throw FormatError(source + ": latest state file name '" + l.file + "' does not match its tile");
        }
        e.latest = std::move(l);
      }
      if (const auto held = row.find("sessions"); held != row.end()) {
        const uint64_t n = held->get<uint64_t>();
        if (version < 2 || n == 0 || n >= index.top.sessionCount()) {
          throw FormatError(source + ": tile " + e.file + " lists " + std::to_string(n) + " sessions held, which a" +
                            " version " + std::to_string(version) + " table of " +
                            std::to_string(index.top.sessionCount()) + " sessions cannot hold");
        }
        e.sessions = static_cast<size_t>(n);
      }
      if (const auto windows = row.find("windows"); windows != row.end()) {
        if (index.window_sessions == 0) throw FormatError(source + ": tile " + e.file + " lists windows without their size");
        for (const nlohmann::json& w : *windows) {
          WindowFile f{w.at("file").get<std::string>(), w.at("bytes").get<uint64_t>(), w.at("crc32").get<uint32_t>()};
          // A closed window of the windowed layout may be the tile file it was while open.
          if (!isWindowFileOf(e.key, f.file, e.windows.size()) &&
              !(index.windowed && tileGeneration(e.key, f.file) && f.file != e.file)) {
            throw FormatError(source + ": window file name '" + f.file + "' does not match its tile and place");
          }
          // A closed window was written by an earlier run than the open one (or with it, when a
          // rebuilt group cut the tile): never a name a later run could write again.
          if (index.windowed && (tileGeneration(e.key, f.file) ? windowGeneration(e.key, f.file) >= *tileGeneration(e.key, e.file)
                                                                : windowGeneration(e.key, f.file) > *tileGeneration(e.key, e.file))) {
            throw FormatError(source + ": window file name '" + f.file + "' is of a later generation than its tile's file");
          }
          if (index.windowed) {
            const uint64_t n = w.at("sessions").get<uint64_t>();
            if (n < (e.windows.empty() ? 1u : 2u) || n > index.top.sessionCount()) {
              throw FormatError(source + ": window " + f.file + " lists " + std::to_string(n) +
                                " sessions, which a closed window cannot hold");
            }
            f.sessions = static_cast<size_t>(n);
          }
          e.windows.push_back(std::move(f));
        }
      }
      if (!e.windows.empty() || index.windowed) {
        const uint64_t held = e.sessions.value_or(index.top.sessionCount());
        if (index.windowed ? openWindowFirst(e) + 1 > held
                           : e.windows.size() * uint64_t{index.window_sessions} > held) {
          throw FormatError(source + ": tile " + e.file + " lists " + std::to_string(e.windows.size()) +
                            (index.windowed ? " closed windows" : " windows of " + std::to_string(index.window_sessions) +
                                                                      " sessions") +
                            " but holds " + std::to_string(held) + " sessions");
        }
      }
      index.tiles.push_back(std::move(e));
    }
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(source + ": the tile table is malformed: " + e.what());
  }
  std::sort(index.tiles.begin(), index.tiles.end(), [](const TileEntry& a, const TileEntry& b) { return a.key < b.key; });
  for (size_t i = 1; i < index.tiles.size(); ++i) {
    if (index.tiles[i].key == index.tiles[i - 1].key) throw FormatError(source + ": a tile is listed twice");
  }
  return index;
}

TileIndex readTileIndex(const fs::path& folder) {
  const fs::path path = folder / kTileIndexName;
  if (!fs::exists(path)) throw IoError(folder.string() + " is not a tiled 4D map (it has no " + kTileIndexName + ")");
  return readNamingMemory(path, [&] { return decodeTileIndex(readFileBytes(path), path.string()); });
}

namespace {

/// @throw IoError when `path`, a `what` file ("tile", "window", "latest state") the index lists,
/// is missing.
void requireListed(const fs::path& path, const char* what) {
  if (!fs::exists(path)) throw IoError(path.string() + ": " + what + " file missing (listed in the index)");
}

/// The `what` file at `path`, decoded, once its size and checksum match the index's row.
CmapFile listedFile(const fs::path& path, uint64_t bytes_listed, uint32_t crc32_listed, const char* what) {
  const std::string source = path.string();
  const std::vector<uint8_t> bytes = readFileBytes(path);
  if (bytes.size() != bytes_listed || crc32Of(bytes) != crc32_listed) {
    throw FormatError(source + ": " + what + " file does not match the index (size or checksum differ)");
  }
  return decodeCmap(bytes, source);
}

/// True when every leaf of `map` lies inside the tile `key`.
bool insideTile(const SessionMap& map, const TileIndex& index, const TileKey& key) {
  bool inside = true;
  map.forEachLeaf([&](const LeafView& leaf) {
    inside = inside && leaf.level <= index.tile_level && tileOf(leaf.key, index.tile_level) == key;
  });
  return inside;
}

/// The tile of `file` with the index's later sessions appended, checked against the index.
TemporalMap tileOfFile(const CmapFile& file, const std::string& source, const TileIndex& index,
                       const TileEntry& entry) {
  TemporalMap tile = temporalMapFrom(file, source);
  const std::vector<SessionRecord>& all = index.top.sessions();
  const size_t held = entry.sessions.value_or(all.size());
  if (held < all.size()) {  // (a tile that should hold all: checkTileFits names both counts)
    if (tile.sessionCount() != held) {
      throw FormatError(source + ": holds " + std::to_string(tile.sessionCount()) +
                        " sessions but the index lists it with " + std::to_string(held));
    }
    try {
      const auto first = all.begin() + static_cast<std::ptrdiff_t>(held);
      tile.appendUnobservedSessions(std::vector<SessionRecord>(first, all.end()));
    } catch (const UsageError& e) {
      throw FormatError(source + ": its sessions do not come before the index's later ones: " + e.what());
    }
  }
  checkTileFits(index.top, index.tile_level, entry.key, tile, source);
  return tile;
}

}  // namespace

namespace {

/// A window of a windowed tile (`what`: "window" or "tile" for the open one) as its file holds
/// it, checked to hold `count` sessions, those of the index from rank `first` on.
TemporalMap windowOfFile(const fs::path& path, uint64_t bytes, uint32_t crc32, const TileIndex& index,
                         const TileKey& key, size_t first, size_t count, const char* what) {
  const std::string source = path.string();
  requireListed(path, what);
  return readNamingMemory(path, [&] {
    TemporalMap window = temporalMapFrom(listedFile(path, bytes, crc32, what), source);
    const std::vector<SessionRecord>& all = index.top.sessions();
    bool same = window.sessionCount() == count && first + count <= all.size();
    for (size_t i = 0; same && i < count; ++i) same = window.sessions()[i].time_s == all[first + i].time_s;
    if (!same) {
      throw FormatError(source + ": its " + std::to_string(window.sessionCount()) +
                        " sessions are not the index's " + std::to_string(count) + " from session " +
                        std::to_string(first + 1));
    }
    // As a tile, but that a window may be one uniform cube of tile size (compacted on its own;
    // the joined tile is checked whole).
    checkFitsTileCube(index.top, index.tile_level, key, window, index.tile_level, source);
    return window;
  });
}

}  // namespace

TemporalMap readOpenWindow(const fs::path& folder, const TileIndex& index, const TileEntry& entry) {
  if (!index.windowed) throw UsageError("tile " + entry.file + " is not kept as windows");
  const size_t first = openWindowFirst(entry);
  const size_t held = entry.sessions.value_or(index.top.sessionCount());
  return windowOfFile(folder / entry.file, entry.bytes, entry.crc32, index, entry.key, first, held - first, "tile");
}

std::vector<TemporalMap> readClosedWindows(const fs::path& folder, const TileIndex& index, const TileKey& key,
                                           const std::vector<WindowFile>& closed) {
  std::vector<TemporalMap> windows;
  size_t first = 0;  // window j + 1 begins with window j's last session
  for (const WindowFile& w : closed) {
    windows.push_back(windowOfFile(folder / w.file, w.bytes, w.crc32, index, key, first, w.sessions, "window"));
    first += w.sessions - 1;
  }
  return windows;
}

TemporalMap readTile(const fs::path& folder, const TileIndex& index, const TileEntry& entry) {
  const fs::path path = folder / entry.file;
  const std::string source = path.string();
  if (index.windowed) {
    std::vector<TemporalMap> windows = readClosedWindows(folder, index, entry.key, entry.windows);
    windows.push_back(readOpenWindow(folder, index, entry));
    const std::vector<SessionRecord>& all = index.top.sessions();
    const size_t held = entry.sessions.value_or(all.size());
    windows.back().appendUnobservedSessions(std::vector<SessionRecord>(all.begin() + static_cast<std::ptrdiff_t>(held), all.end()));
    TemporalMap tile(index.top.resolution_m());
    try {
      tile = joinWindows(windows);
    } catch (const Error& e) {
      throw FormatError(source + ": its windows do not join into one history: " + e.what());
    }
    windows.clear();
    checkTileFits(index.top, index.tile_level, entry.key, tile, source);
    return tile;
  }
  requireListed(path, "tile");
  return readNamingMemory(path, [&] {
    return tileOfFile(listedFile(path, entry.bytes, entry.crc32, "tile"), source, index, entry);
  });
}

namespace {

/// The snapshot read from a tile's file, or from a window (`window_first`: the rank of its first
/// session in the index), checked against the index as readTile checks the tile: resolution,
/// criterion, the sessions' times, every leaf inside the tile.
SessionMap checkedSnapshot(StoredSnapshot stored, const CmapFile& file, const std::string& source,
                           const TileIndex& index, const TileEntry& entry, std::optional<size_t> window_first) {
  if (file.header.resolution_m != index.top.resolution_m()) {
    throw FormatError(source + ": resolution " + std::to_string(file.header.resolution_m) +
                      " m differs from the index's " + std::to_string(index.top.resolution_m()) + " m");
  }
  if (!(stored.criterion == index.top.criterion())) {
    throw FormatError(source + ": its change criterion differs from the index's");
  }
  const std::vector<SessionRecord>& all = index.top.sessions();
  const size_t held = entry.sessions.value_or(all.size());
  const size_t first = window_first.value_or(0);
  if (!window_first && held < all.size() && stored.sessions.size() != held) {
    throw FormatError(source + ": holds " + std::to_string(stored.sessions.size()) +
                      " sessions but the index lists it with " + std::to_string(held));
  }
  // A tile's file holds every session it holds; a window a run of them.
  bool same = !window_first ? stored.sessions.size() == held : first + stored.sessions.size() <= held;
  for (size_t i = 0; same && i < stored.sessions.size(); ++i) same = stored.sessions[i].time_s == all[first + i].time_s;
  if (!same) {
    if (window_first) {
      throw FormatError(source + ": its sessions do not match the index's sessions table from session " +
                        std::to_string(first + 1));
    }
    const size_t count = held < all.size() ? all.size() : stored.sessions.size();
    throw FormatError(source + ": its sessions (" + std::to_string(count) +
                      ") do not match the index's sessions table (" + std::to_string(all.size()) + ")");
  }
  if (!insideTile(stored.map, index, entry.key)) throw FormatError(source + " holds nodes outside its tile");
  return std::move(stored.map);
}

/// The snapshot at session `rank` from the tile's window that holds it.
SessionMap windowSnapshot(const fs::path& folder, const TileIndex& index, const TileEntry& entry, uint32_t rank) {
  const size_t j = rank / index.window_sessions;
  const WindowFile& w = entry.windows[j];
  const fs::path path = folder / w.file;
  const std::string source = path.string();
  requireListed(path, "window");
  return readNamingMemory(path, [&] {
    const CmapFile file = listedFile(path, w.bytes, w.crc32, "window");
    if (file.header.version < 2 || !file.appended.empty()) {
      throw FormatError(source + ": a window file is a 4D map of format version 2 or later without appended sessions");
    }
    const size_t first = j * index.window_sessions;
    StoredSnapshot stored = snapshotOfColumns(file, source, static_cast<uint32_t>(rank - first));
    if (stored.sessions.size() < index.window_sessions) {
      throw FormatError(source + ": a window holds " + std::to_string(stored.sessions.size()) + " sessions, not " +
                        std::to_string(index.window_sessions));
    }
    return checkedSnapshot(std::move(stored), file, source, index, entry, first);
  });
}

}  // namespace

namespace {

/// Windowed layout: the snapshot at session `rank` (before the tile's held sessions end) from
/// the window holding it: the first closed one that does, else the open one.
SessionMap windowedSnapshot(const fs::path& folder, const TileIndex& index, const TileEntry& entry, size_t rank) {
  size_t first = 0;
  const WindowFile* window = nullptr;
  for (const WindowFile& w : entry.windows) {
    if (rank < first + w.sessions) {
      window = &w;
      break;
    }
    first += w.sessions - 1;
  }
  const fs::path path = folder / (window ? window->file : entry.file);
  const std::string source = path.string();
  const char* what = window ? "window" : "tile";
  requireListed(path, what);
  return readNamingMemory(path, [&] {
    const CmapFile file =
        listedFile(path, window ? window->bytes : entry.bytes, window ? window->crc32 : entry.crc32, what);
    const size_t count = window ? window->sessions : entry.sessions.value_or(index.top.sessionCount()) - first;
    if (file.header.kind != MapKind::Temporal || file.header.version < 2 || !file.appended.empty()) {
      throw FormatError(source + ": a window is a 4D map of format version 2 or later without appended sessions");
    }
    StoredSnapshot stored = snapshotOfColumns(file, source, static_cast<uint32_t>(rank - first));
    if (stored.sessions.size() != count) {
      throw FormatError(source + ": holds " + std::to_string(stored.sessions.size()) +
                        " sessions but the index lists it with " + std::to_string(count));
    }
    return checkedSnapshot(std::move(stored), file, source, index, entry, first);
  });
}

}  // namespace

bool readsWindowAt(const TileIndex& index, const TileEntry& entry, double time_s) {
  const auto rank = index.top.rankAtOrBefore(time_s);
  if (index.windowed) {
    const size_t held = entry.sessions.value_or(index.top.sessionCount());
    // (The last closed window's last session is also the open window's first: read from the closed one.)
    return rank && !entry.windows.empty() && std::min<size_t>(*rank, held - 1) <= openWindowFirst(entry);
  }
  return rank && index.window_sessions > 0 && *rank / index.window_sessions < entry.windows.size();
}

SessionMap readTileSnapshot(const fs::path& folder, const TileIndex& index, const TileEntry& entry, double time_s,
                            bool read_windows) {
  const auto rank = index.top.rankAtOrBefore(time_s);
  if (index.windowed) {
    // The sessions after the tile's held ones observed nothing there: the state stays.
    if (!rank) return readTile(folder, index, entry).snapshot(time_s);
    return windowedSnapshot(folder, index, entry, std::min<size_t>(*rank, entry.sessions.value_or(*rank + 1) - 1));
  }
  if (read_windows && readsWindowAt(index, entry, time_s)) return windowSnapshot(folder, index, entry, *rank);
  const fs::path path = folder / entry.file;
  const std::string source = path.string();
  requireListed(path, "tile");
  return readNamingMemory(path, [&] {
    const CmapFile file = listedFile(path, entry.bytes, entry.crc32, "tile");
    if (!rank || file.header.kind != MapKind::Temporal || file.header.version < 2 || !file.appended.empty()) {
      return tileOfFile(file, source, index, entry).snapshot(time_s);  // (what the fast read does not cover)
    }
    return checkedSnapshot(snapshotOfColumns(file, source, *rank), file, source, index, entry, std::nullopt);
  });
}

SessionMap readLatestState(const fs::path& folder, const TileIndex& index, const TileEntry& entry) {
  if (!entry.latest) throw UsageError("tile " + entry.file + " has no latest state");
  const fs::path path = folder / entry.latest->file;
  const std::string source = path.string();
  requireListed(path, "latest state");
  return readNamingMemory(path, [&] {
    SessionMap state = sessionMapFrom(listedFile(path, entry.latest->bytes, entry.latest->crc32, "latest state"), source);
    if (state.resolution_m() != index.top.resolution_m()) {
      throw FormatError(source + ": resolution differs from the index's");
    }
    if (!insideTile(state, index, entry.key)) throw FormatError(source + " holds voxels outside its tile");
    return state;
  });
}

bool isTiledMap(const fs::path& path) { return fs::is_directory(path) && fs::exists(path / kTileIndexName); }

std::string consensusFileName(uint64_t generation) { return "tiles/consensus.g" + std::to_string(generation) + ".cmap"; }

std::optional<uint64_t> consensusGeneration(const std::string& file) {
  return generationAfter("tiles/consensus.g", file);
}

std::optional<StoredConsensus> readStoredConsensus(const fs::path& folder, const nlohmann::json& meta,
                                                   double resolution_m) {
  if (!meta.is_object() || !meta.contains(kConsensusKey)) return std::nullopt;
  const std::string index_source = (folder / kTileIndexName).string();
  const nlohmann::json& row = meta.at(kConsensusKey);
  StoredConsensus out{SessionMap(resolution_m), 0, ""};
  uint64_t bytes_listed = 0;
  uint32_t crc32_listed = 0;
  try {
    out.file = row.at("file").get<std::string>();
    bytes_listed = row.at("bytes").get<uint64_t>();
    crc32_listed = row.at("crc32").get<uint32_t>();
    out.sessions = row.at("sessions").get<uint64_t>();
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(index_source + ": the consensus entry is unreadable (" + e.what() + ")");
  }
  if (!consensusGeneration(out.file)) {
    throw FormatError(index_source + ": the consensus file name '" + out.file + "' is not one the build writes");
  }
  const fs::path path = folder / out.file;
  const std::string source = path.string();
  requireListed(path, "consensus");
  out.map = readNamingMemory(path, [&] {
    SessionMap map = sessionMapFrom(listedFile(path, bytes_listed, crc32_listed, "consensus"), source);
    if (map.resolution_m() != resolution_m) throw FormatError(source + ": resolution differs from the index's");
    return map;
  });
  return out;
}

nlohmann::json writeStoredConsensus(const fs::path& folder, uint64_t generation, const SessionMap& map,
                                    uint64_t sessions) {
  const std::string file = consensusFileName(generation);
  const nlohmann::json meta = {{"created_by", "chronomap build --tiles"},
                               {"content", "the consensus of the tiled map's sessions"},
                               {"sessions", sessions}};
  // Version 1: lengths and offsets as the sums hold them (versions 2 and 3 quantise them).
  const std::vector<uint8_t> bytes = encodeSessionMap(map, meta, /*zstd_level=*/3, /*version=*/1);
  fs::create_directories(folder / "tiles");
  writeFileAtomic(folder / file, bytes);
  return {{"file", file}, {"bytes", bytes.size()}, {"crc32", crc32Of(bytes)}, {"sessions", sessions}};
}

}  // namespace chronomap
