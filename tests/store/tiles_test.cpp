// Tiled 4D maps: split and join, the index file, and queries through tiles against the whole map.

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "chronomap/analysis/segment.h"
#include "chronomap/core/error.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/pipeline/tiles.h"
#include "chronomap/temporal/tiles.h"
#include "chronomap/temporal/window.h"
#include "test_support.h"
#include "tile_table_edits.h"

namespace chronomap {
namespace {

using test::at;
using test::freeVoxel;
using test::occupiedVoxelExact;
namespace fs = std::filesystem;

constexpr int kLo = test::kTileRegionLo, kHi = test::kTileRegionHi;

double sessionTime(int i) { return 1.7e9 + 3600.0 * i; }

// A random session over a random box of the region: drifting occupied voxels, holes, free
// space with binary-fraction lengths (sums stay exact), sometimes compressed; now and then a
// large known-free cube as well, so that uniform cubes of tile size and larger occur.
SessionMap randomSession(std::mt19937_64& rng, std::vector<uint8_t>& world) {
  return test::randomTileRegionSession(rng, world, /*far_parts=*/false);
}

TemporalMap randomMap(uint64_t seed, int sessions) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> world(static_cast<size_t>((kHi - kLo) * (kHi - kLo) * (kHi - kLo)));
  for (auto& w : world) w = rng() % 8 == 0;
  TemporalMap map(0.05);
  for (int i = 0; i < sessions; ++i) map.add(sessionTime(i), randomSession(rng, world), {false, "s" + std::to_string(i)});
  map.compact();
  return map;
}

std::vector<VoxelKey> regionKeys() {
  std::vector<VoxelKey> keys;
  for (int z = kLo - 1; z <= kHi; ++z) {
    for (int y = kLo - 1; y <= kHi; ++y) {
      for (int x = kLo - 1; x <= kHi; ++x) keys.push_back(at(x, y, z));
    }
  }
  keys.push_back(at(20, 3, 5));  // inside the large free cube
  return keys;
}

bool sameHistory(const std::vector<HistoryEntry>& a, const std::vector<HistoryEntry>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].time_s != b[i].time_s || !(a[i].counters == b[i].counters) || a[i].level != b[i].level) return false;
  }
  return true;
}

std::vector<const Tile*> refsOf(const SplitMap& s) {
  std::vector<const Tile*> refs;
  for (const Tile& t : s.tiles) refs.push_back(&t);
  return refs;
}

class TilesProperty : public ::testing::TestWithParam<uint64_t> {};

TEST_P(TilesProperty, SplitAndJoinGiveTheMapBack) {
  const TemporalMap map = randomMap(GetParam(), 6);
  for (int level = 1; level <= 6; ++level) {
    const SplitMap split = splitIntoTiles(map, level);
    EXPECT_FALSE(split.tiles.empty());
    for (const Tile& t : split.tiles) {
      ASSERT_EQ(t.map.sessionCount(), map.sessionCount());
      for (size_t i = 0; i < map.sessionCount(); ++i) EXPECT_EQ(t.map.sessions()[i].time_s, map.sessions()[i].time_s);
    }
    EXPECT_TRUE(joinTiles(split.top, level, refsOf(split)) == map) << "level " << level;
    // The coverage is cut, not copied: the top holds what lies outside the tiles, each tile its
    // own part, and together they are every session's coverage.
    for (size_t i = 0; i < map.sessionCount(); ++i) {
      uint64_t voxels = split.top.sessions()[i].coverage.voxelCount();
      for (const Tile& t : split.tiles) {
        voxels += t.map.sessions()[i].coverage.voxelCount();
        const Coverage inside = clipCoverage(split.top.sessions()[i].coverage, tileCorner(t.key, level), level);
        EXPECT_EQ(inside.voxelCount(), 0u) << "session " << i << ": the top covers a tile's voxels";
      }
      EXPECT_EQ(voxels, map.sessions()[i].coverage.voxelCount()) << "session " << i << ", level " << level;
    }
    // An index written before the cut (every session's whole coverage in the top) joins back
    // to the same map.
    std::vector<SessionRecord> whole = split.top.sessions();
    for (size_t i = 0; i < whole.size(); ++i) whole[i].coverage = map.sessions()[i].coverage;
    const TemporalMap old_top =
        TemporalMap::fromParts(map.resolution_m(), map.criterion(), split.top.parts(), std::move(whole));
    EXPECT_TRUE(joinTiles(old_top, level, refsOf(split)) == map) << "level " << level;
  }
}

TEST(Tiles, CoverageCutOutsideTilesAndJoinedAgainMatchesAVoxelSet) {
  // Slow reference: the covered Morton codes as a set, on ranges inside the first 8^4 codes.
  std::mt19937 random(3);
  const int level = 2;  // tiles of 64 codes
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint64_t> ranges;
    uint64_t code = std::uniform_int_distribution<uint64_t>(0, 40)(random);
    while (code < 4000) {
      const uint64_t length = std::uniform_int_distribution<uint64_t>(1, 150)(random);
      ranges.push_back(code);
      ranges.push_back(std::min<uint64_t>(code + length, 4096));
      code = ranges.back() + std::uniform_int_distribution<uint64_t>(1, 200)(random);
    }
    const Coverage c = Coverage::fromRanges(ranges);
    std::vector<TileKey> tiles;
    std::set<uint64_t> tile_codes;
    for (uint64_t t = 0; t < 64; ++t) {
      if (std::uniform_int_distribution<int>(0, 2)(random) != 0) continue;
      const VoxelKey corner = mortonDecode(t * 64);
      tiles.push_back(tileOf(corner, level));
      tile_codes.insert(t);
    }
    std::shuffle(tiles.begin(), tiles.end(), random);
    const Coverage outside = clipCoverageOutside(c, tiles, level);
    std::set<uint64_t> expected, got;
    for (size_t i = 0; i < ranges.size(); i += 2) {
      for (uint64_t v = ranges[i]; v < ranges[i + 1]; ++v) {
        if (!tile_codes.count(v / 64)) expected.insert(v);
      }
    }
    const std::vector<uint64_t> r = outside.ranges();
    for (size_t i = 0; i < r.size(); i += 2) {
      for (uint64_t v = r[i]; v < r[i + 1]; ++v) got.insert(v);
    }
    ASSERT_EQ(got, expected) << "trial " << trial;
    // The union of the part outside, the tiles' parts and the whole is the whole again.
    std::vector<Coverage> parts = {outside, c};
    for (const TileKey& t : tiles) parts.push_back(clipCoverage(c, tileCorner(t, level), level));
    std::vector<const Coverage*> refs;
    for (const Coverage& p : parts) refs.push_back(&p);
    EXPECT_TRUE(unionCoverage(refs) == c) << "trial " << trial;
    refs.erase(refs.begin() + 1);
    EXPECT_TRUE(unionCoverage(refs) == c) << "trial " << trial;
  }
}

TEST_P(TilesProperty, QueriesThroughTilesAnswerAsTheWholeMap) {
  std::mt19937_64 rng(GetParam() + 100);
  const TemporalMap map = randomMap(GetParam(), 6);
  // Levels 1 and 2 write tens to hundreds of files (each flushed to disk): the split test covers them.
  const int level = 3 + static_cast<int>(rng() % 3);
  test::TempDir dir;
  writeTiledMap(dir / "tiled", splitIntoTiles(map, level), nlohmann::json::object());
  TiledMap tiled(dir / "tiled", {0});
  ASSERT_EQ(tiled.sessions().size(), map.sessionCount());

  std::vector<double> times{sessionTime(0) - 1.0};
  for (int i = 0; i < 6; ++i) times.push_back(sessionTime(i) + (i % 2 ? 0.0 : 10.0));
  for (const double t : times) EXPECT_TRUE(tiled.snapshot(t) == map.snapshot(t)) << "level " << level << " t " << t;

  // A region: every voxel in the box reads as in the whole snapshot.
  const VoxelBox box{at(kLo + static_cast<int>(rng() % 8), kLo + static_cast<int>(rng() % 8), kLo),
                     at(kLo + 8 + static_cast<int>(rng() % 8), kHi - 1, kLo + 4 + static_cast<int>(rng() % 8))};
  const VoxelBox& region = box;
  const double t = times[1 + rng() % 6];
  const SessionMap whole = map.snapshot(t);
  const SessionMap part = tiled.snapshot(t, region);
  for (uint16_t z = box.min.z; z <= box.max.z; ++z) {
    for (uint16_t y = box.min.y; y <= box.max.y; ++y) {
      for (uint16_t x = box.min.x; x <= box.max.x; ++x) {
        const VoxelKey k{x, y, z};
        ASSERT_EQ(part.find(k), whole.find(k)) << "level " << level;
      }
    }
  }

  for (const VoxelKey& k : regionKeys()) {
    ASSERT_TRUE(sameHistory(tiled.history(k), map.history(k))) << "level " << level;
  }

  for (DiffMode mode : {DiffMode::Hard, DiffMode::Threshold, DiffMode::Continuous}) {
    DiffSettings s;
    s.mode = mode;
    s.neighbourhood_voxels = mode == DiffMode::Threshold ? 1 : 0;
    s.kept_surface_radius_voxels = mode == DiffMode::Hard ? 2 : 0;  // reaches across tile borders too
    const double t1 = times[rng() % times.size()], t2 = times[rng() % times.size()];
    EXPECT_TRUE(tiled.diff(t1, t2, s) == diff(map, t1, t2, s)) << toString(mode) << " level " << level;
    // A region's diff is the whole diff's cells that meet the box.
    const DiffMap d = diff(map, t1, t2, s);
    std::vector<ChangeCell> in;
    for (const ChangeCell& c : d.cells()) {
      if (region.meets(c.key, c.level)) in.push_back(c);
    }
    EXPECT_TRUE(tiled.diff(t1, t2, s, region) == DiffMap::fromCells(0.05, s, in));
  }
}

TEST_P(TilesProperty, AFolderJoinsBackToTheSameFile) {
  const TemporalMap map = randomMap(GetParam(), 4);
  test::TempDir dir;
  writeTemporalMap(dir / "map.cmap", map, {{"k", 1}});
  TileSettings s;
  s.map = dir / "map.cmap";
  s.folder = dir / "tiled";
  s.tile_size_m = 0.05 * (8 << (GetParam() % 3));
  const TileResult r = tileMap(s);
  EXPECT_GT(r.tiles, 0u);
  // tileMap writes its tiles on every core: the files are those of writing them one by one.
  TemporalMap compacted = readTemporalMap(s.map);
  compacted.compact();
  writeTiledMap(dir / "serial", splitIntoTiles(compacted, r.tile_level),
                {{"created_by", "chronomap tile"}, {"source", s.map.string()}});
  size_t files = 0;
  for (const auto& f : fs::recursive_directory_iterator(dir / "serial")) {
    if (!f.is_regular_file()) continue;
    ++files;
    const fs::path rel = fs::relative(f.path(), dir / "serial");
    EXPECT_TRUE(test::bytesOf(f.path()) == test::bytesOf(dir / "tiled" / rel)) << rel;
  }
  EXPECT_EQ(files, 2 * r.tiles + r.windows + 1);
  EXPECT_EQ(untileMap(dir / "tiled", dir / "back.cmap"), map.sessionCount());
  EXPECT_TRUE(readTemporalMap(dir / "back.cmap") == map);
  writeTemporalMap(dir / "again.cmap", readTemporalMap(dir / "back.cmap"), {{"k", 1}});
  writeTemporalMap(dir / "orig.cmap", map, {{"k", 1}});
  EXPECT_EQ(test::bytesOf(dir / "again.cmap"), test::bytesOf(dir / "orig.cmap"));
}

TEST_P(TilesProperty, ASmallBudgetIsRespectedAndAnswersStayTheSame) {
  const TemporalMap map = randomMap(GetParam(), 5);
  test::TempDir dir;
  writeTiledMap(dir / "tiled", splitIntoTiles(map, 3), nlohmann::json::object());
  size_t largest = 0;
  {
    TiledMap all(dir / "tiled", {0});
    for (const TileKey& k : all.tilesMeeting(std::nullopt)) largest = std::max(largest, all.tile(k)->memoryBytes());
    EXPECT_EQ(all.cacheStats().evictions, 0u);
  }
  const size_t limit = 3 * largest;
  TiledMap tiled(dir / "tiled", {limit});
  const double t = sessionTime(3);
  EXPECT_TRUE(tiled.snapshot(t) == map.snapshot(t));
  DiffSettings s;
  s.neighbourhood_voxels = 1;
  EXPECT_TRUE(tiled.diff(sessionTime(1), t, s) == diff(map, sessionTime(1), t, s));
  for (const VoxelKey& k : regionKeys()) ASSERT_TRUE(sameHistory(tiled.history(k), map.history(k)));
  const TileCacheStats& c = tiled.cacheStats();
  EXPECT_LE(c.peak_resident_bytes, limit);
  EXPECT_LE(c.resident_bytes, limit);
  EXPECT_GT(c.evictions, 0u);
  EXPECT_GT(c.loads, tiled.index().tiles.size());  // tiles were read again after being dropped
}

INSTANTIATE_TEST_SUITE_P(Seeds, TilesProperty, ::testing::Range<uint64_t>(0, 6));

TEST(Tiles, AnObjectAcrossATileBorderIsOneObject) {
  // Free space, then a 4 x 4 x 4 box that straddles the borders of tiles of 4 voxels on all axes.
  TemporalMap map(0.05);
  SessionMap before(0.05), after(0.05);
  for (int z = -6; z < 6; ++z) {
    for (int y = -6; y < 6; ++y) {
      for (int x = -6; x < 6; ++x) {
        before.add(at(x, y, z), freeVoxel(0.125f));
        const bool box = x >= -2 && x < 2 && y >= -2 && y < 2 && z >= -2 && z < 2;
        after.add(at(x, y, z), box ? occupiedVoxelExact(2, 200) : freeVoxel(0.125f));
      }
    }
  }
  map.add(sessionTime(0), before);
  map.add(sessionTime(1), after);
  test::TempDir dir;
  writeTiledMap(dir / "tiled", splitIntoTiles(map, 2), nlohmann::json::object());
  TiledMap tiled(dir / "tiled", {0});
  DiffMap d;
  const Segmentation seg = segmentTiledDiff(tiled, sessionTime(0), sessionTime(1), {}, {}, std::nullopt, &d);
  std::vector<TileKey> touched;
  for (const ChangeCell& c : d.cells()) touched.push_back(tileOf(c.key, 2));
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  EXPECT_EQ(touched.size(), 8u);  // the object lies in 8 tiles
  ASSERT_EQ(seg.components.size(), 1u);
  EXPECT_EQ(seg.components[0].voxels, 64u);
  EXPECT_EQ(seg.components[0].kind, ChangeKind::Appeared);
  const Segmentation whole = segment(diff(map, sessionTime(0), sessionTime(1)));
  ASSERT_EQ(whole.components.size(), 1u);
  EXPECT_EQ(whole.components[0].voxels, seg.components[0].voxels);
  EXPECT_EQ(whole.components[0].centroid_m, seg.components[0].centroid_m);
}

TEST(Tiles, ARegionTouchesOnlyTheTilesItNeeds) {
  const TemporalMap map = randomMap(3, 4);
  test::TempDir dir;
  writeTiledMap(dir / "tiled", splitIntoTiles(map, 3), nlohmann::json::object());
  TiledMap tiled(dir / "tiled", {0});
  const VoxelBox box{at(0, 0, 0), at(7, 7, 7)};  // exactly one tile
  tiled.snapshot(sessionTime(3), box);  // the last session: the tile's latest state alone
  EXPECT_EQ(tiled.cacheStats().latest_reads, 1u);
  EXPECT_EQ(tiled.cacheStats().loads, 0u);
  tiled.snapshot(sessionTime(2), box);  // an earlier time: the tile read at that time alone
  EXPECT_EQ(tiled.cacheStats().time_reads, 1u);
  EXPECT_EQ(tiled.cacheStats().loads, 0u);
  tiled.history(at(0, 0, 0));  // its history: the tile read whole, and held
  EXPECT_EQ(tiled.cacheStats().loads, 1u);
  tiled.snapshot(sessionTime(3), box);  // the tile is held now: no file read
  tiled.snapshot(sessionTime(2), box);
  EXPECT_EQ(tiled.cacheStats().latest_reads, 1u);
  EXPECT_EQ(tiled.cacheStats().time_reads, 1u);
  EXPECT_EQ(tiled.cacheStats().loads, 1u);
  const TileKey first = tileOf(at(0, 0, 0), 3);
  const auto other = std::find_if(tiled.index().tiles.begin(), tiled.index().tiles.end(),
                                  [&](const TileEntry& e) { return !(e.key == first); });
  ASSERT_NE(other, tiled.index().tiles.end());
  tiled.history(tileCorner(other->key, 3));  // a voxel of another tile: that tile alone
  EXPECT_EQ(tiled.cacheStats().loads, 2u);
  EXPECT_GT(tiled.index().tiles.size(), 8u);
}

// A tile read at one time (issue 46) gives the snapshot of the tile read whole, node for node
// (the same pools in the same order, so the same bytes), at every session's time, between
// them, before the first and after the last, with coarse free cubes among its nodes: from its
// file, and from its windows where it has them (runs of 2 sessions: all 6; of 4: the first 4).
TEST_P(TilesProperty, ATileReadAtOneTimeIsItsSnapshotNodeForNode) {
  const TemporalMap map = randomMap(GetParam(), 6);
  for (const uint32_t window_sessions : {0u, 2u, 4u}) {
    test::TempDir dir;
    writeTiledMap(dir / "tiled", splitIntoTiles(map, 3), nlohmann::json::object(), window_sessions);
    const TileIndex index = readTileIndex(dir / "tiled");
    EXPECT_EQ(index.window_sessions, window_sessions);
    std::vector<double> times{sessionTime(0) - 1.0};
    for (int i = 0; i < 6; ++i) times.insert(times.end(), {sessionTime(i), sessionTime(i) + 1800.0});
    size_t coarse = 0, leaves = 0;
    for (const TileEntry& e : index.tiles) {
      EXPECT_EQ(e.windows.size(), window_sessions ? 6 / window_sessions : 0) << e.file;
      const TemporalMap tile = readTile(dir / "tiled", index, e);
      // Each window is written as it is, not compacted: compaction would merge sibling lists
      // that agree inside the window only, and their sums would then differ from the tile's.
      for (size_t j = 0; j < e.windows.size(); ++j) {
        const TemporalMap::Parts want = historyWindow(tile, static_cast<uint32_t>(j * window_sessions), window_sessions).parts();
        const TemporalMap::Parts got = readTemporalMap(dir / "tiled" / e.windows[j].file).parts();
        EXPECT_TRUE(got.inner == want.inner && got.list_sizes == want.list_sizes && got.entries == want.entries)
            << e.windows[j].file;
      }
      for (const double t : times) {
        TemporalMap::SnapshotVisits visits;
        const SessionMap whole = tile.snapshot(t, &visits);
        const SessionMap read = readTileSnapshot(dir / "tiled", index, e, t);
        coarse += visits.coarse;
        leaves += whole.leafCount();
        ASSERT_EQ(read.innerPool(), whole.innerPool()) << e.file << " at " << t << ", windows of " << window_sessions;
        ASSERT_TRUE(test::samePools(read, whole));
        EXPECT_EQ(encodeSessionMap(read, nlohmann::json::object()), encodeSessionMap(whole, nlohmann::json::object()));
      }
    }
    EXPECT_GT(coarse, 0u);
    EXPECT_GT(leaves, 0u);
    TiledMap tiled(dir / "tiled", {0});
    EXPECT_TRUE(tiled.snapshot(sessionTime(2)) == map.snapshot(sessionTime(2)));
    EXPECT_EQ(tiled.cacheStats().time_reads, index.tiles.size());
    EXPECT_EQ(tiled.cacheStats().window_reads, window_sessions ? index.tiles.size() : 0u);
    EXPECT_EQ(tiled.cacheStats().loads, 0u);
    TiledMap without(dir / "tiled", {0, false});  // the tiles' files: the same answer
    EXPECT_TRUE(without.snapshot(sessionTime(2)) == map.snapshot(sessionTime(2)));
    EXPECT_EQ(without.cacheStats().window_reads, 0u);
    // The windows change nothing else: the map untiled is the map.
    untileMap(dir / "tiled", dir / "whole.cmap");
    EXPECT_TRUE(readTemporalMap(dir / "whole.cmap") == map);
  }
}

// A window of a map's history (temporal/window.h) answers every time inside it as the map
// does, node for node, for every run of sessions; it holds fewer entries than the map.
TEST_P(TilesProperty, AHistoryWindowAnswersItsTimesAsTheMap) {
  const TemporalMap map = randomMap(GetParam() + 100, 7);
  for (uint32_t first = 0; first < 7; ++first) {
    for (uint32_t count = 1; first + count <= 7; ++count) {
      const TemporalMap window = historyWindow(map, first, count);
      ASSERT_GE(window.sessionCount(), count);
      EXPECT_EQ(window.sessions()[0].time_s, map.sessions()[first].time_s);
      EXPECT_LE(window.counts().entries, map.counts().entries);
      for (uint32_t r = first; r < first + count; ++r) {
        for (const double t : {sessionTime(static_cast<int>(r)), sessionTime(static_cast<int>(r)) + 1800.0}) {
          const SessionMap a = window.snapshot(t), b = map.snapshot(t);
          ASSERT_EQ(a.innerPool(), b.innerPool()) << first << "+" << count << " at session " << r;
          ASSERT_TRUE(a == b) << first << "+" << count << " at session " << r;
        }
      }
    }
  }
  EXPECT_LT(historyWindow(map, 5, 2).counts().entries, map.counts().entries);
  EXPECT_THROW(historyWindow(map, 0, 0), UsageError);
  EXPECT_THROW(historyWindow(map, 6, 2), UsageError);
  EXPECT_THROW(historyWindow(map, 7, 1), UsageError);
}

// A window file changed, missing or misnamed: the time it holds fails naming it; the tile read
// whole and the latest time do not need it. An index whose windows do not fit is refused.
TEST(Tiles, ABadWindowGivesOneClearError) {
  const TemporalMap map = randomMap(8, 5);
  test::TempDir dir;
  writeTiledMap(dir / "tiled", splitIntoTiles(map, 3), nlohmann::json::object(), 2);
  const TileIndex index = readTileIndex(dir / "tiled");
  const TileEntry& e = index.tiles[0];
  ASSERT_EQ(e.windows.size(), 2u);
  EXPECT_EQ(e.windows[1].file, windowFileName(e.file, 1));
  std::vector<uint8_t> bytes = test::bytesOf(dir / "tiled" / e.windows[1].file);
  bytes[bytes.size() / 2] ^= 0x08;
  test::writeBytes(dir / "tiled" / e.windows[1].file, bytes);
  try {
    readTileSnapshot(dir / "tiled", index, e, sessionTime(3));
    FAIL() << "no error";
  } catch (const FormatError& x) {
    EXPECT_NE(std::string(x.what()).find(e.windows[1].file), std::string::npos) << x.what();
  }
  EXPECT_NO_THROW(readTileSnapshot(dir / "tiled", index, e, sessionTime(1)));  // window 0
  EXPECT_NO_THROW(readTileSnapshot(dir / "tiled", index, e, sessionTime(4)));  // no window: the file
  EXPECT_NO_THROW(readTile(dir / "tiled", index, e));
  fs::remove(dir / "tiled" / e.windows[1].file);
  EXPECT_THROW(readTileSnapshot(dir / "tiled", index, e, sessionTime(2)), IoError);
  // Another tile's window in its place: its size and checksum differ from the row's.
  fs::copy_file(dir / "tiled" / index.tiles[1].windows[1].file, dir / "tiled" / e.windows[1].file);
  EXPECT_THROW(readTileSnapshot(dir / "tiled", index, e, sessionTime(2)), FormatError);

  // The index: a window named for another tile or place, more windows than sessions, windows
  // in a table of version 2 or without their size.
  const test::TileTableEdits edits(dir / "tiled");
  EXPECT_EQ(decodeTileIndex(edits.with([](nlohmann::json&) {}), "index").tiles[0].windows.size(), 2u);
  edits.expectRefused([](nlohmann::json& t) { t["list"][0]["windows"][1]["file"] = t["list"][1]["windows"][1]["file"]; },
          "window file name");
  edits.expectRefused([](nlohmann::json& t) { t["list"][0]["windows"][0]["file"] = t["list"][0]["windows"][1]["file"]; },
          "window file name");
  edits.expectRefused([](nlohmann::json& t) {
    nlohmann::json extra = t["list"][0]["windows"][1];
    extra["file"] = windowFileName(t["list"][0]["file"].get<std::string>(), 2);
    t["list"][0]["windows"].push_back(extra);
  }, "windows of 2 sessions");
  edits.expectRefused([](nlohmann::json& t) { t["version"] = 2; }, "window session count");
  edits.expectRefused([](nlohmann::json& t) { t["window_sessions"] = 0; }, "window session count");
  edits.expectRefused([](nlohmann::json& t) { t.erase("window_sessions"); }, "without their size");
}

// The windowed layout's first windows (firstWindowSessions): k plus a share of k fixed by the
// tile, so that the tiles of a floor, reached on the same nights, close their windows on
// different nights. Over a block of 8 x 8 x 4 tiles every share is taken, none by more than
// twice its fair part.
TEST(Tiles, FirstWindowsAreStaggeredOverTheTiles) {
  for (const uint32_t k : {1u, 2u, 16u}) {
    std::vector<size_t> taken(k, 0);
    for (uint16_t x = 100; x < 108; ++x) {
      for (uint16_t y = 7; y < 15; ++y) {
        for (uint16_t z = 0; z < 4; ++z) {
          const uint32_t f = firstWindowSessions(TileKey{x, y, z}, k);
          ASSERT_GE(f, k);
          ASSERT_LT(f, 2 * k);
          ++taken[f - k];
        }
      }
    }
    for (uint32_t share = 0; share < k; ++share) {
      EXPECT_GT(taken[share], 0u) << "k " << k << ", share " << share;
      EXPECT_LE(taken[share], 2 * 256 / k) << "k " << k << ", share " << share;
    }
  }
  // The rule docs/file-format.md states, pinned: a folder written today closes its windows where
  // one written later will.
  EXPECT_EQ(firstWindowSessions(TileKey{0, 0, 0}, 16), 16u);
  EXPECT_EQ(firstWindowSessions(TileKey{1, 2, 3}, 16), 29u);
  EXPECT_EQ(firstWindowSessions(TileKey{4096, 4096, 4096}, 2), 3u);
  EXPECT_EQ(firstWindowSessions(TileKey{4097, 4096, 4096}, 2), 2u);
  EXPECT_THROW(firstWindowSessions(TileKey{1, 2, 3}, 0), UsageError);
  EXPECT_THROW(firstWindowSessions(TileKey{1, 2, 3}, 65536), UsageError);
}

TEST(Tiles, TileSizesArePowersOfTwoVoxels) {
  EXPECT_EQ(tileLevelFor(6.4, 0.05), 7);
  EXPECT_EQ(tileLevelFor(0.1, 0.05), 1);
  EXPECT_THROW(tileLevelFor(5.0, 0.05), UsageError);
  EXPECT_THROW(tileLevelFor(0.05, 0.05), UsageError);  // one voxel
  EXPECT_THROW(tileLevelFor(-1.0, 0.05), UsageError);
  EXPECT_THROW(splitIntoTiles(TemporalMap(0.05), 0), UsageError);
}

TEST(Tiles, BadInputGivesOneClearError) {
  const TemporalMap map = randomMap(5, 3);
  test::TempDir dir;
  const SplitMap split = splitIntoTiles(map, 3);
  writeTiledMap(dir / "tiled", split, nlohmann::json::object());
  const TileIndex index = readTileIndex(dir / "tiled");
  ASSERT_GE(index.tiles.size(), 2u);

  // A missing tile: the index opens, the query that needs the tile fails naming it.
  fs::remove(dir / "tiled" / index.tiles[0].file);
  TiledMap tiled(dir / "tiled", {0});
  try {
    tiled.snapshot(sessionTime(1));
    FAIL() << "no error";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(index.tiles[0].file), std::string::npos) << e.what();
  }
  // Its latest state, corrupt or missing: the last session's snapshot fails naming it.
  std::vector<uint8_t> latest = test::bytesOf(dir / "tiled" / index.tiles[0].latest->file);
  latest[latest.size() / 2] ^= 0x10;
  test::writeBytes(dir / "tiled" / index.tiles[0].latest->file, latest);
  try {
    tiled.snapshot(sessionTime(2));
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find(index.tiles[0].latest->file), std::string::npos) << e.what();
  }
  fs::remove(dir / "tiled" / index.tiles[0].latest->file);
  EXPECT_THROW(tiled.snapshot(sessionTime(2)), IoError);
  EXPECT_THROW(untileMap(dir / "tiled", dir / "x.cmap"), IoError);

  // A tile changed after the index was written.
  std::vector<uint8_t> bytes = test::bytesOf(dir / "tiled" / index.tiles[1].file);
  bytes[bytes.size() / 2] ^= 0x40;
  test::writeBytes(dir / "tiled" / index.tiles[1].file, bytes);
  EXPECT_THROW(readTile(dir / "tiled", index, index.tiles[1]), FormatError);
  EXPECT_THROW(readTileSnapshot(dir / "tiled", index, index.tiles[1], sessionTime(1)), FormatError);

  // A corrupt index.
  std::vector<uint8_t> idx = test::bytesOf(dir / "tiled" / kTileIndexName);
  for (size_t at_byte : {size_t{5}, size_t{14}, idx.size() / 2, idx.size() - 3}) {
    std::vector<uint8_t> bad = idx;
    bad[at_byte] ^= 0x21;
    EXPECT_THROW(decodeTileIndex(bad, "index"), FormatError) << at_byte;
  }
  idx.resize(idx.size() - 7);
  EXPECT_THROW(decodeTileIndex(idx, "index"), FormatError);
  // A 4D map is not an index, nor is a folder without one.
  writeTemporalMap(dir / "map.cmap", map, {});
  EXPECT_THROW(decodeTileIndex(test::bytesOf(dir / "map.cmap"), "map"), FormatError);
  EXPECT_THROW(readTileIndex(dir.path()), IoError);

  // A tile whose sessions' table disagrees with the index's: one session fewer.
  TemporalMap shorter = map;
  shorter.remove(sessionTime(2));
  shorter.compact();
  const SplitMap other = splitIntoTiles(shorter, 3);
  SplitMap mixed{3, split.top, {}};
  mixed.tiles.push_back(other.tiles[0]);
  writeTiledMap(dir / "mixed", mixed, nlohmann::json::object());
  const TileIndex mixed_index = readTileIndex(dir / "mixed");
  try {
    readTile(dir / "mixed", mixed_index, mixed_index.tiles[0]);
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("sessions"), std::string::npos) << e.what();
  }
  try {
    readTileSnapshot(dir / "mixed", mixed_index, mixed_index.tiles[0], sessionTime(1));
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("sessions"), std::string::npos) << e.what();
  }

  // A tile filed under another tile's key.
  SplitMap moved{3, split.top, {}};
  moved.tiles.push_back(Tile{split.tiles[1].key, split.tiles[0].map});
  writeTiledMap(dir / "moved", moved, nlohmann::json::object());
  const TileIndex moved_index = readTileIndex(dir / "moved");
  try {
    readTile(dir / "moved", moved_index, moved_index.tiles[0]);
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("outside its tile"), std::string::npos) << e.what();
  }
  try {
    readTileSnapshot(dir / "moved", moved_index, moved_index.tiles[0], sessionTime(1));
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("outside its tile"), std::string::npos) << e.what();
  }
  try {
    readLatestState(dir / "moved", moved_index, moved_index.tiles[0]);
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("outside its tile"), std::string::npos) << e.what();
  }
  EXPECT_THROW(joinTiles(split.top, 3, {&moved.tiles[0]}), FormatError);
}

}  // namespace
}  // namespace chronomap
