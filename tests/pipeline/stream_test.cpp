// The streaming build of tiled 4D maps: sessions added tile by tile give the tiled map that
// building the whole map and cutting it gives, under a memory budget, and a failure leaves the
// previous tiled map as it was.

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <span>

#include "chronomap/align/consensus.h"
#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/pipeline/stream.h"
#include "chronomap/pipeline/tiles.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/core/time.h"
#include "chronomap/store/tiled_map.h"
#include "chronomap/temporal/tiles.h"
#include "chronomap/temporal/window.h"
#include "test_support.h"
#include "tile_table_edits.h"
#include "window_compare.h"
#include "pipeline/in_order.h"

namespace chronomap::stream_test {

using test::at;
using test::freeVoxel;
using test::occupiedVoxelExact;
namespace fs = std::filesystem;

constexpr int kLo = test::kTileRegionLo, kHi = test::kTileRegionHi;

double timeOf(int i) { return 1.8e9 + 3600.0 * i; }

SessionMap randomSession(std::mt19937_64& rng, std::vector<uint8_t>& world) {
  return test::randomTileRegionSession(rng, world, /*far_parts=*/true);
}

std::vector<SessionMap> randomSessions(uint64_t seed, int n) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> world(static_cast<size_t>((kHi - kLo) * (kHi - kLo) * (kHi - kLo)));
  for (auto& w : world) w = rng() % 8 == 0;
  std::vector<SessionMap> out;
  for (int i = 0; i < n; ++i) out.push_back(randomSession(rng, world));
  return out;
}

std::string nameOf(int i) { return "s" + std::to_string(i); }

// What `chronomap build` of each batch into one .cmap does: the sessions added in time order,
// then the map written (compacted) and read back for the next batch.
TemporalMap wholeBuild(const std::vector<SessionMap>& sessions, const std::vector<std::vector<int>>& batches) {
  TemporalMap map(0.05);
  for (const auto& batch : batches) {
    std::vector<int> sorted = batch;
    std::sort(sorted.begin(), sorted.end());
    for (const int i : sorted) map.add(timeOf(i), sessions[static_cast<size_t>(i)], {false, nameOf(i)});
    const std::vector<uint8_t> bytes = encodeTemporalMap(map, nlohmann::json::object());
    map = temporalMapFrom(decodeCmap(bytes, "whole"), "whole");
  }
  return map;
}

StreamResult stream(const fs::path& folder, const std::vector<SessionMap>& sessions,
                              const std::vector<int>& batch, int tile_level, size_t limit,
                              uint32_t window_sessions = kDefaultWindowSessions, int threads = 0,
                              bool windowed = false) {
  StreamSettings s;
  s.threads = threads;
  s.windowed_tiles = windowed;
  s.window_sessions = window_sessions;
  s.folder = folder;
  s.tile_size_m = std::ldexp(0.05, tile_level);
  s.memory_limit_bytes = limit;
  return streamIntoTiles(s, batch.size(), [&](size_t k) {
    const int i = batch[k];
    return StreamSession{timeOf(i), nameOf(i), sessions[static_cast<size_t>(i)]};
  });
}

TemporalMap joined(const fs::path& folder) {
  const TileIndex index = readTileIndex(folder);
  std::vector<Tile> tiles;
  for (const TileEntry& e : index.tiles) tiles.push_back(Tile{e.key, readTile(folder, index, e)});
  std::vector<const Tile*> refs;
  for (const Tile& t : tiles) refs.push_back(&t);
  return joinTiles(index.top, index.tile_level, refs);
}

std::map<std::string, std::vector<uint8_t>> filesOf(const fs::path& folder) {
  std::map<std::string, std::vector<uint8_t>> out;
  for (const auto& f : fs::recursive_directory_iterator(folder)) {
    if (f.is_regular_file()) out[fs::relative(f.path(), folder).string()] = readFileBytes(f.path());
  }
  return out;
}

class StreamProperty : public ::testing::TestWithParam<uint64_t> {};

// Random sessions streamed in random batches (each batch in shuffled order) at a random tile
// size and budget: the joined tiles are the whole map built batch by batch, to the byte, and
// the tiles are those `tile` cuts from it.
TEST_P(StreamProperty, StreamingGivesTheWholeBuildCut) {
  std::mt19937_64 rng(GetParam());
  const int n = 7;
  const std::vector<SessionMap> sessions = randomSessions(GetParam() * 7919, n);
  std::vector<std::vector<int>> batches(1);
  for (int i = 0; i < n; ++i) {
    if (i > 0 && rng() % 3 == 0) batches.emplace_back();
    batches.back().push_back(i);
  }
  for (auto& b : batches) std::shuffle(b.begin(), b.end(), rng);
  const int level = 3 + static_cast<int>(rng() % 3);  // level 2 writes hundreds of files, each flushed
  const size_t limit = rng() % 2 ? 0 : 800 + rng() % 4000;
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  for (const auto& b : batches) {
    const StreamResult r = stream(folder, sessions, b, level, limit);
    if (limit) {
      EXPECT_LE(r.stats.peak_parts_bytes, limit);
    }
  }
  TemporalMap whole = wholeBuild(sessions, batches);
  const TemporalMap streamed = joined(folder);
  ASSERT_TRUE(streamed == whole) << "level " << level << ", " << batches.size() << " batches";
  EXPECT_EQ(encodeTemporalMap(streamed, nlohmann::json::object()),
            encodeTemporalMap(whole, nlohmann::json::object()));
  whole.compact();
  const SplitMap cut = splitIntoTiles(whole, level);
  const TileIndex index = readTileIndex(folder);
  ASSERT_EQ(index.tiles.size(), cut.tiles.size());
  for (const Tile& t : cut.tiles) {
    const TileEntry* e = index.find(t.key);
    ASSERT_NE(e, nullptr);
    EXPECT_TRUE(readTile(folder, index, *e) == t.map);
    ASSERT_TRUE(e->latest.has_value());
    EXPECT_TRUE(readLatestState(folder, index, *e) == asStored(t.map.snapshot(t.map.sessions().back().time_s)));
  }
  EXPECT_TRUE(index.top == cut.top);
  // Only the files the index names remain (older generations and parts are gone): each tile's
  // history and latest state, and the index.
  EXPECT_EQ(filesOf(folder).size(), 2 * index.tiles.size() + 1);
}

INSTANTIATE_TEST_SUITE_P(Seeds, StreamProperty, ::testing::Values(1, 2, 3, 4, 5, 6, 7, 8));

// The hard case: a free cube larger than a tile (held in the index's top), then a session that
// sees an occupied voxel inside it: the cube is refined below tile level, and the new tile
// takes the cube's history over.
TEST(Stream, AUniformCubeAboveTileLevelRefinedByALaterSession) {
  std::vector<SessionMap> sessions(3, SessionMap(0.05));
  sessions[0].addCube(at(32, 0, 0), 5, freeVoxel(0.5f));
  sessions[1].addCube(at(32, 0, 0), 5, freeVoxel(0.25f));
  sessions[2].add(at(37, 3, 5), occupiedVoxelExact(2, 9));
  sessions[2].add(at(36, 3, 5), freeVoxel(0.125f));
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  stream(folder, sessions, {0, 1}, 3, 0);
  const TileIndex before = readTileIndex(folder);
  EXPECT_TRUE(before.tiles.empty());  // the whole cube is one list of the top
  const StreamResult r = stream(folder, sessions, {2}, 3, 0);
  EXPECT_EQ(r.tiles, 1u);
  const TemporalMap whole = wholeBuild(sessions, {{0, 1}, {2}});
  const TemporalMap streamed = joined(folder);
  EXPECT_TRUE(streamed == whole);
  const std::vector<HistoryEntry> h = streamed.history(at(37, 3, 5));
  ASSERT_EQ(h.size(), 2u);  // the cube's state (free twice: no change), then the voxel's own
  EXPECT_EQ(h[0].time_s, timeOf(0));
  EXPECT_EQ(h[1].time_s, timeOf(2));
  EXPECT_EQ(h[1].counters, occupiedVoxelExact(2, 9));
  const std::vector<HistoryEntry> far = streamed.history(at(50, 20, 20));  // elsewhere the cube stays whole
  ASSERT_EQ(far.size(), 1u);
  EXPECT_GE(far[0].level, 3);
}

TEST(Stream, ABudgetBoundsThePartsHeldAndSpillsTheRest) {
  const std::vector<SessionMap> sessions = randomSessions(77, 4);
  test::TempDir dir;
  const StreamResult small = stream(dir / "small", sessions, {0, 1, 2, 3}, 3, 4096);
  EXPECT_LE(small.stats.peak_parts_bytes, 4096u);
  EXPECT_GT(small.stats.spills, 0u);
  EXPECT_GT(small.stats.spilled_bytes, 0u);
  const StreamResult large = stream(dir / "large", sessions, {0, 1, 2, 3}, 3, 0);
  EXPECT_EQ(large.stats.spills, 0u);
  EXPECT_GT(large.stats.peak_parts_bytes, 4096u);
  EXPECT_TRUE(joined(dir / "small") == joined(dir / "large"));
  EXPECT_EQ(small.nodes_added, large.nodes_added);
  EXPECT_FALSE(fs::exists(dir / "small" / ".parts-0"));
}

// runInOrder (the streaming build's groups, the tiles `untile` and the consensus read): on random
// sets of failing pieces and thread counts, every piece before the first failing one runs once,
// and the error is that piece's, as one thread gives it.
TEST(InOrder, TheFirstFailingPieceInOrderIsTheError) {
  std::mt19937 rng(17);
  for (int round = 0; round < 60; ++round) {
    const size_t n = 1 + rng() % 40;
    std::vector<bool> fails(n);
    for (size_t k = 0; k < n; ++k) fails[k] = rng() % 6 == 0;
    const int threads = static_cast<int>(rng() % 5);  // 0: one per core
    std::vector<std::atomic<int>> ran(n);
    size_t first = n;
    for (size_t k = 0; k < n && first == n; ++k) {
      if (fails[k]) first = k;
    }
    try {
      pipeline_detail::runInOrder(n, threads, [&](size_t k) {
        ++ran[k];
        if (fails[k]) throw DataError("piece " + std::to_string(k));
      });
      EXPECT_EQ(first, n) << "round " << round;
    } catch (const DataError& e) {
      EXPECT_EQ(std::string(e.what()), "piece " + std::to_string(first)) << "round " << round;
    }
    for (size_t k = 0; k < n; ++k) {
      if (k <= first) {
        EXPECT_EQ(ran[k].load(), 1) << "piece " << k << ", round " << round;
      } else {
        EXPECT_LE(ran[k].load(), 1) << "piece " << k << ", round " << round;
      }
    }
  }
}

// Groups of tiles run at once on several threads: every file (tiles, latest states, windows,
// the index) and every figure are one thread's; a failure in two groups gives the first group's
// error in group order whatever the threads, and leaves the index and the files it names.
TEST(Stream, ThreadsWriteTheSameFilesAndGiveTheFirstError) {
  for (const uint64_t seed : {3u, 4u, 5u}) {
    std::mt19937_64 rng(seed);
    const int n = 9;
    const std::vector<SessionMap> sessions = randomSessions(seed * 104729, n);
    std::vector<std::vector<int>> batches(1);
    for (int i = 0; i < n; ++i) {
      if (i > 0 && rng() % 3 == 0) batches.emplace_back();
      batches.back().push_back(i);
    }
    const size_t limit = rng() % 2 ? 0 : 800 + rng() % 4000;
    test::TempDir dir;
    for (const auto& b : batches) {
      const StreamResult one = stream(dir / "one", sessions, b, 3, limit, 2, 1);
      const StreamResult four = stream(dir / "four", sessions, b, 3, limit, 2, 4);
      EXPECT_EQ(one.nodes_added, four.nodes_added) << "seed " << seed;
      EXPECT_EQ(one.tile_bytes, four.tile_bytes);
      EXPECT_EQ(one.stats.groups, four.stats.groups);
      EXPECT_EQ(one.stats.tiles_read, four.stats.tiles_read);
      EXPECT_EQ(one.stats.tiles_written, four.stats.tiles_written);
      EXPECT_EQ(one.stats.windows_written, four.stats.windows_written);
      EXPECT_EQ(one.stats.peak_group_bytes, four.stats.peak_group_bytes);
      EXPECT_GT(one.stats.groups, 4u);
      ASSERT_TRUE(filesOf(dir / "one") == filesOf(dir / "four")) << "seed " << seed;
    }
    // Two stored tiles damaged: the error names the first one a run reaches in group order.
    const TileIndex index = readTileIndex(dir / "one");
    ASSERT_GE(index.tiles.size(), 4u);
    std::vector<std::string> messages;
    for (const int threads : {1, 4}) {
      const fs::path folder = dir / "damaged";  // the same path: the messages name it
      fs::remove_all(folder);
      fs::copy(dir / "one", folder, fs::copy_options::recursive);
      for (const size_t t : {index.tiles.size() / 2, index.tiles.size() - 1}) {
        std::vector<uint8_t> bytes = readFileBytes(folder / index.tiles[t].file);
        bytes[bytes.size() / 2] ^= 0x5A;
        writeFileAtomic(folder / index.tiles[t].file, bytes);
      }
      const auto before = filesOf(folder);
      // Every session again, later: every tile is reached.
      StreamSettings s;
      s.folder = folder;
      s.threads = threads;
      try {
        streamIntoTiles(s, 1, [&](size_t) {
          // What every session observed: it reaches every tile.
          return StreamSession{timeOf(n + 5), "again", consensus(std::span<const SessionMap>(sessions))};
        });
        ADD_FAILURE() << "a damaged tile was read";
      } catch (const Error& e) {
        messages.push_back(e.what());
      }
      // The index and every file it names as they were (the new generation's files a failed run
      // wrote are the next run's to remove).
      const auto after = filesOf(folder);
      for (const auto& [name, bytes] : before) {
        const auto it = after.find(name);
        EXPECT_TRUE(it != after.end() && it->second == bytes) << name << ", " << threads << " thread(s)";
      }
    }
    ASSERT_EQ(messages.size(), 2u);
    EXPECT_EQ(messages[0], messages[1]);
    EXPECT_TRUE(messages[0].find(index.tiles[index.tiles.size() / 2].file) != std::string::npos ||
                messages[0].find(index.tiles.back().file) != std::string::npos)
        << messages[0];
  }
}

TEST(Stream, AFailedAddLeavesThePreviousTiledMap) {
  const std::vector<SessionMap> sessions = randomSessions(5, 5);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  stream(folder, sessions, {0, 1}, 3, 0);
  const auto before = filesOf(folder);
  StreamSettings s;
  s.folder = folder;
  s.memory_limit_bytes = 2000;  // parts spilled into the folder before the failure
  EXPECT_THROW(streamIntoTiles(s, 3,
                                         [&](size_t k) -> StreamSession {
                                           if (k == 2) throw IoError("recording 4 cannot be read");
                                           return {timeOf(2 + static_cast<int>(k)), nameOf(2), sessions[2 + k]};
                                         }),
               IoError);
  EXPECT_EQ(filesOf(folder), before);
  // A failure while the tiles are being written: new tiles exist, the index is the old one.
  writeFileAtomic(folder / "tiles" / "0_0_0.g7.cmap", {1, 2, 3});  // what a killed run leaves
  fs::create_directories(folder / ".parts-99999");
  EXPECT_TRUE(joined(folder) == wholeBuild(sessions, {{0, 1}}));  // still readable
  stream(folder, sessions, {2, 3, 4}, 3, 0);
  EXPECT_TRUE(joined(folder) == wholeBuild(sessions, {{0, 1}, {2, 3, 4}}));
  EXPECT_FALSE(fs::exists(folder / "tiles" / "0_0_0.g7.cmap"));
  EXPECT_FALSE(fs::exists(folder / ".parts-99999"));
  // A first build that fails leaves no folder.
  EXPECT_THROW(streamIntoTiles(
                   [&] {
                     StreamSettings n;
                     n.folder = dir / "new";
                     return n;
                   }(),
                   1, [&](size_t) -> StreamSession { throw IoError("unreadable"); }),
               IoError);
  EXPECT_FALSE(fs::exists(dir / "new"));
}

// The consensus a tiled map keeps for the streaming build's registration: started when asked,
// then every session summed into it one at a time in the order given, whoever streams; its file
// swaps with the index (the old one goes, a failed run keeps it), and a damaged one is refused
// naming it, the folder unchanged.
TEST(Stream, TheStoredConsensusSumsEverySessionAndSwapsWithTheIndex) {
  const std::vector<SessionMap> sessions = randomSessions(11, 5);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  const auto metaOf = [&] { return userMetadataOf(readCmap(folder / kTileIndexName)); };
  const auto summed = [&](const std::vector<int>& order) {
    SessionMap sum(0.05);
    for (const int i : order) {
      const SessionMap* both[] = {&sum, &sessions[static_cast<size_t>(i)]};
      sum = consensus(std::span<const SessionMap* const>(both));
    }
    return sum;
  };
  // Without it asked for, none is kept.
  stream(dir / "plain", sessions, {0, 1}, 3, 0);
  EXPECT_FALSE(userMetadataOf(readCmap(dir / "plain" / kTileIndexName)).contains(kConsensusKey));
  EXPECT_FALSE(readStoredConsensus(dir / "plain", userMetadataOf(readCmap(dir / "plain" / kTileIndexName)), 0.05));
  StreamSettings s;
  s.folder = folder;
  s.tile_size_m = std::ldexp(0.05, 3);
  s.keep_consensus = true;
  const StreamResult first = streamIntoTiles(s, 2, [&](size_t k) {
    const int i = k == 0 ? 1 : 0;  // given out of time order: summed as given
    return StreamSession{timeOf(i), nameOf(i), sessions[static_cast<size_t>(i)]};
  });
  EXPECT_EQ(first.consensus_sessions, 2u);
  std::optional<StoredConsensus> stored = readStoredConsensus(folder, metaOf(), 0.05);
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->sessions, 2u);
  EXPECT_TRUE(stored->map == summed({1, 0}));
  const std::string first_file = stored->file;
  EXPECT_EQ(consensusGeneration(first_file), 1u);
  // A later run that does not ask still sums its sessions; the old file goes.
  const StreamResult second = stream(folder, sessions, {2}, 3, 0);
  EXPECT_EQ(second.consensus_sessions, 3u);
  stored = readStoredConsensus(folder, metaOf(), 0.05);
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->sessions, 3u);
  EXPECT_TRUE(stored->map == summed({1, 0, 2}));
  EXPECT_NE(stored->file, first_file);
  EXPECT_FALSE(fs::exists(folder / first_file));
  EXPECT_TRUE(joined(folder) == wholeBuild(sessions, {{0, 1}, {2}}));  // the tiles as without it
  // A failed run keeps the index and the consensus as they were.
  const auto before = filesOf(folder);
  EXPECT_THROW(streamIntoTiles(s, 2,
                               [&](size_t k) -> StreamSession {
                                 if (k == 1) throw IoError("recording cannot be read");
                                 return {timeOf(3), nameOf(3), sessions[3]};
                               }),
               IoError);
  EXPECT_EQ(filesOf(folder), before);
  // A damaged consensus is refused naming it; nothing changes.
  std::vector<uint8_t> bytes = readFileBytes(folder / stored->file);
  bytes[bytes.size() / 2] ^= 0x20;
  writeFileAtomic(folder / stored->file, bytes);
  const auto damaged = filesOf(folder);
  try {
    stream(folder, sessions, {3}, 3, 0);
    ADD_FAILURE() << "a damaged consensus was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(stored->file), std::string::npos) << e.what();
  }
  EXPECT_EQ(filesOf(folder), damaged);
  // Truncated and empty files, and entries that are not what the build writes, read directly.
  const auto refused = [&](const nlohmann::json& meta, const std::string& expected) {
    try {
      readStoredConsensus(folder, meta, 0.05);
      ADD_FAILURE() << "read: " << meta.dump();
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  bytes.resize(bytes.size() / 2);
  writeFileAtomic(folder / stored->file, bytes);
  refused(metaOf(), stored->file);
  writeFileAtomic(folder / stored->file, {});
  refused(metaOf(), stored->file);
  nlohmann::json entry = metaOf();
  entry[kConsensusKey]["file"] = "tiles/../index.cmap";
  refused(entry, "is not one the build writes");
  for (const char* member : {"file", "bytes", "crc32", "sessions"}) {
    entry = metaOf();
    entry[kConsensusKey].erase(member);
    refused(entry, "the consensus entry is unreadable");
  }
  entry = metaOf();
  entry[kConsensusKey]["sessions"] = "three";
  refused(entry, "the consensus entry is unreadable");
  refused({{kConsensusKey, nullptr}}, "the consensus entry is unreadable");
  fs::remove(folder / stored->file);
  EXPECT_THROW(stream(folder, sessions, {3}, 3, 0), IoError);
  EXPECT_EQ(consensusGeneration("tiles/consensus.g0.cmap"), std::nullopt);
  EXPECT_EQ(consensusGeneration("tiles/consensus.g12.cmap"), 12u);
  EXPECT_EQ(consensusGeneration("tiles/0_0_0.g12.cmap"), std::nullopt);
}

// A folder that keeps no consensus: the stored sessions' consensus computed tile by tile from
// their histories is the joined 4D map's consensus over all its sessions, voxel for voxel.
TEST(Stream, TheConsensusOfTilesIsTheJoinedMapsConsensus) {
  const std::vector<SessionMap> sessions = randomSessions(12, 4);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  stream(folder, sessions, {0, 1}, 3, 0);
  stream(folder, sessions, {2, 3}, 3, 0);
  const TemporalMap whole = joined(folder);
  const SessionMap expected = consensus(whole, timeOf(0), timeOf(3));
  const SessionMap got = consensusOfTiles(folder);
  size_t leaves = 0;
  expected.forEachLeaf([&](const LeafView& l) {
    ++leaves;
    for (const VoxelKey& k : {l.key, VoxelKey{static_cast<uint16_t>(l.key.x + (1 << l.level) - 1), l.key.y, l.key.z}}) {
      const auto a = expected.find(k), b = got.find(k);
      ASSERT_EQ(a.has_value(), b.has_value());
      if (a) {
        EXPECT_TRUE(test::nearlyEqual(*a, *b)) << k.x << " " << k.y << " " << k.z;
      }
    }
  });
  EXPECT_GT(leaves, 100u);
  size_t got_leaves = 0;
  got.forEachLeaf([&](const LeafView& l) {
    ++got_leaves;
    EXPECT_TRUE(expected.find(l.key).has_value()) << l.key.x << " " << l.key.y << " " << l.key.z;
  });
  EXPECT_GT(got_leaves, 100u);
}

// A room of 12 x 6 x 6 voxels from x = x0 (tiles of 8 voxels: 2 tiles, none uniform):
// occupied where `world` says (drifting by a few flips a night), free with binary-fraction
// lengths elsewhere, one voxel in ten unobserved.
SessionMap roomSession(std::mt19937_64& rng, std::vector<uint8_t>& world, int x0) {
  for (int i = 0; i < 30; ++i) world[rng() % world.size()] ^= 1;
  SessionMap m(0.05);
  for (int z = 0; z < 6; ++z) {
    for (int y = 0; y < 6; ++y) {
      for (int x = 0; x < 12; ++x) {
        if (rng() % 10 == 0) continue;
        const bool occ = world[static_cast<size_t>((z * 6 + y) * 12 + x)] != 0;
        m.add(at(x0 + x, y, z), occ ? occupiedVoxelExact(1 + static_cast<uint32_t>(rng() % 3))
                                    : freeVoxel(0.125f * static_cast<float>(1 + rng() % 4)));
      }
    }
  }
  return m;
}

// The index's files (each tile's history and latest state) of the tiles whose x lies in
// [x_lo, x_hi), with a hash of their bytes.
std::map<std::string, size_t> roomFiles(const fs::path& folder, int x_lo, int x_hi) {
  const TileIndex index = readTileIndex(folder);
  std::map<std::string, size_t> out;
  auto hashOf = [](const std::vector<uint8_t>& b) { return std::hash<std::string>{}(std::string(b.begin(), b.end())); };
  for (const TileEntry& e : index.tiles) {
    const int x = static_cast<int>(e.key.x) - static_cast<int>(tileOf(at(0, 0, 0), 3).x);
    if (x < x_lo || x >= x_hi) continue;
    out[e.file] = hashOf(readFileBytes(folder / e.file));
    if (e.latest) out[e.latest->file] = hashOf(readFileBytes(folder / e.latest->file));
  }
  return out;
}

constexpr int kRoomB = 40;  // room A: tiles x 0..1, room B: tiles x 5..6

// One session a night, of the rooms each string names ('A', 'B'), over two random worlds.
std::vector<SessionMap> twoRoomNights(uint64_t seed, const std::vector<std::string>& seen) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> world_a(12 * 6 * 6), world_b(12 * 6 * 6);
  for (auto& w : world_a) w = rng() % 6 == 0;
  for (auto& w : world_b) w = rng() % 6 == 0;
  std::vector<SessionMap> sessions;
  for (const std::string& rooms : seen) {
    SessionMap night(0.05);
    for (const char room : rooms) {
      night.merge(room == 'A' ? roomSession(rng, world_a, 0) : roomSession(rng, world_b, kRoomB));
    }
    sessions.push_back(std::move(night));
  }
  return sessions;
}

// Issue 46: a night that observes one room rewrites that room's tiles only; the other room's
// files keep their names and bytes, and every query at every session answers as the whole map.
TEST(Stream, ANightObservingOneRoomRewritesOnlyThatRoomsTiles) {
  // Night 0 sees both rooms, then A, B, A alone (one batch a night).
  const std::vector<std::string> seen = {"AB", "A", "B", "A"};
  const std::vector<SessionMap> sessions = twoRoomNights(46, seen);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  std::vector<std::vector<int>> batches;
  for (int n = 0; n < static_cast<int>(seen.size()); ++n) {
    std::map<std::string, size_t> before_a, before_b;
    if (n >= 1) before_a = roomFiles(folder, 0, 2), before_b = roomFiles(folder, 5, 7);
    const StreamResult r = stream(folder, sessions, {n}, 3, 0);
    batches.push_back({n});
    if (n < 1) continue;
    const bool a = seen[static_cast<size_t>(n)][0] == 'A';
    const auto& untouched_before = a ? before_b : before_a;
    const auto& touched_before = a ? before_a : before_b;
    const auto untouched_after = a ? roomFiles(folder, 5, 7) : roomFiles(folder, 0, 2);
    const auto touched_after = a ? roomFiles(folder, 0, 2) : roomFiles(folder, 5, 7);
    EXPECT_EQ(r.tiles, 4u);
    EXPECT_EQ(r.stats.tiles_written, 2u) << "night " << n;
    EXPECT_EQ(r.stats.tiles_kept, 2u) << "night " << n;
    EXPECT_EQ(r.stats.tiles_read, 2u) << "night " << n;  // the kept tiles are not even read
    EXPECT_EQ(untouched_after.size(), 4u);  // 2 tiles, each with its latest state
    EXPECT_EQ(untouched_after, untouched_before) << "night " << n << ": the room not seen was rewritten";
    for (const auto& [file, bytes] : touched_before) EXPECT_FALSE(touched_after.count(file)) << file;
  }
  // The answers: joined, the whole map built night by night, to the byte; through TiledMap,
  // every session's snapshot, the diffs between sessions (with the coverage rule, which reads
  // each tile's own coverage) and every voxel's history.
  const TemporalMap whole = wholeBuild(sessions, batches);
  const TemporalMap streamed = joined(folder);
  ASSERT_TRUE(streamed == whole);
  EXPECT_EQ(encodeTemporalMap(streamed, nlohmann::json::object()), encodeTemporalMap(whole, nlohmann::json::object()));
  TiledMap tiled(folder, {0});
  const std::vector<double> times = whole.times();
  for (const double t : times) EXPECT_TRUE(tiled.snapshot(t) == whole.snapshot(t)) << formatTime(t);
  DiffSettings d;
  d.seen_at_both = true;
  d.neighbourhood_voxels = 1;
  for (size_t i = 0; i < times.size(); ++i) {
    for (size_t j = i + 1; j < times.size(); ++j) {
      EXPECT_TRUE(tiled.diff(times[i], times[j], d) == diff(whole, times[i], times[j], d)) << i << " " << j;
    }
  }
  for (const int x0 : {0, kRoomB}) {
    for (int z = 0; z < 6; ++z) {
      for (int y = 0; y < 6; ++y) {
        for (int x = 0; x < 12; ++x) {
          const std::vector<HistoryEntry> got = tiled.history(at(x0 + x, y, z)), want = whole.history(at(x0 + x, y, z));
          ASSERT_EQ(got.size(), want.size());
          for (size_t k = 0; k < got.size(); ++k) {
            EXPECT_EQ(got[k].time_s, want[k].time_s);
            EXPECT_EQ(got[k].counters, want[k].counters);
          }
        }
      }
    }
  }
}

// Issue 46: a rewritten tile gets the windows of its history's whole runs of sessions, written
// once and kept (names and bytes) by every later night; a tile's snapshot at every time reads
// as from its whole history, node for node, and the tiled map's as the whole map's.
TEST(Stream, WindowsAreWrittenOnceAndAnswerTheirTimes) {
  const std::vector<std::string> seen = {"AB", "A", "B", "A", "A", "B", "AB", "A", "B"};
  const std::vector<SessionMap> sessions = twoRoomNights(4646, seen);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  std::vector<std::vector<int>> batches;
  std::map<std::pair<TileKey, size_t>, std::pair<std::string, std::vector<uint8_t>>> written;
  size_t windows_seen = 0;
  for (int n = 0; n < static_cast<int>(seen.size()); ++n) {
    stream(folder, sessions, {n}, 3, 0, 2);
    batches.push_back({n});
    const TileIndex index = readTileIndex(folder);
    EXPECT_EQ(index.window_sessions, n >= 1 ? 2u : 0u) << "night " << n;
    size_t windows = 0;
    for (const TileEntry& e : index.tiles) {
      const size_t held = e.sessions.value_or(index.top.sessionCount());
      EXPECT_EQ(e.windows.size(), held / 2) << e.file << " after night " << n;
      for (size_t j = 0; j < e.windows.size(); ++j, ++windows) {
        const std::vector<uint8_t> bytes = readFileBytes(folder / e.windows[j].file);
        const auto [it, fresh] = written.emplace(std::make_pair(e.key, j), std::make_pair(e.windows[j].file, bytes));
        if (!fresh) {
          EXPECT_EQ(it->second.first, e.windows[j].file) << "night " << n;
          EXPECT_TRUE(it->second.second == bytes) << e.windows[j].file << " rewritten on night " << n;
        }
      }
    }
    EXPECT_GE(windows, windows_seen);
    windows_seen = windows;
    // Only what the index names is in the folder.
    size_t files = 1;
    for (const TileEntry& e : index.tiles) files += 2 + e.windows.size();
    size_t on_disk = 0;
    for (const auto& f : fs::recursive_directory_iterator(folder)) on_disk += f.is_regular_file();
    EXPECT_EQ(on_disk, files) << "night " << n;
  }
  EXPECT_GT(windows_seen, 4u);
  const TileIndex index = readTileIndex(folder);
  const TemporalMap whole = wholeBuild(sessions, batches);
  const std::vector<double> times = whole.times();
  for (const TileEntry& e : index.tiles) {
    const TemporalMap tile = readTile(folder, index, e);
    for (const double t : times) {
      const SessionMap a = readTileSnapshot(folder, index, e, t), b = tile.snapshot(t);
      ASSERT_EQ(a.innerPool(), b.innerPool()) << e.file << " at " << formatTime(t);
      ASSERT_TRUE(a == b) << e.file << " at " << formatTime(t);
    }
  }
  for (const double t : times) {
    TiledMap tiled(folder, {0});
    EXPECT_TRUE(tiled.snapshot(t) == whole.snapshot(t)) << formatTime(t);
  }
  EXPECT_TRUE(joined(folder) == whole);
}

int tableVersion(const fs::path& folder) {
  const CmapFile f = decodeCmap(readFileBytes(folder / kTileIndexName), "index");
  return metadataOf(f)["tiles"]["version"].get<int>();
}

// The index lists a kept tile with the sessions its file holds (table version 2, written only
// then); what disagrees with the file, or a table version this build does not know, is refused
// naming the file.
TEST(Stream, AKeptTileIsListedWithTheSessionsItsFileHolds) {
  std::mt19937_64 rng(7);
  std::vector<uint8_t> world_a(12 * 6 * 6, 0), world_b(12 * 6 * 6, 0);
  SessionMap both = roomSession(rng, world_a, 0);
  both.merge(roomSession(rng, world_b, 40));
  const std::vector<SessionMap> sessions = {both, roomSession(rng, world_a, 0)};
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  stream(folder, sessions, {0}, 3, 0);
  EXPECT_EQ(tableVersion(folder), 1);  // every tile holds every session: as before
  stream(folder, sessions, {1}, 3, 0);
  EXPECT_EQ(tableVersion(folder), 2);
  TileIndex index = readTileIndex(folder);
  ASSERT_EQ(index.tiles.size(), 4u);
  for (const TileEntry& e : index.tiles) {
    const bool room_b = e.key.x >= tileOf(at(40, 0, 0), 3).x;
    EXPECT_EQ(e.sessions, room_b ? std::optional<size_t>(1) : std::nullopt);
    EXPECT_EQ(readTile(folder, index, e).sessionCount(), 2u);  // the later session added, unobserved
  }
  // A row that claims no session at all (no tile holds none), or another count than its file holds.
  const TileEntry kept = index.tiles.back();
  index.tiles.back().sessions = 0;
  writeTileIndex(folder, index.top, index.tile_level, index.tiles, nlohmann::json::object());
  EXPECT_THROW(readTileIndex(folder), FormatError);
  index.tiles.back().sessions = 1;
  ASSERT_FALSE(index.tiles.front().sessions.has_value());  // room A's: both sessions
  index.tiles.front().sessions = 1;
  writeTileIndex(folder, index.top, index.tile_level, index.tiles, nlohmann::json::object());
  index = readTileIndex(folder);
  try {
    readTile(folder, index, index.tiles.front());
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find(index.tiles.front().file), std::string::npos) << e.what();
  }
  // A count in a version 1 table, a count of every session or more, a newer table version.
  auto indexWith = [&](int version, const nlohmann::json& sessions_held) {
    nlohmann::json row = {{"key", {kept.key.x, kept.key.y, kept.key.z}}, {"file", kept.file},
                          {"bytes", kept.bytes}, {"crc32", kept.crc32}, {"sessions", sessions_held}};
    const nlohmann::json extra = {{"tiles", {{"version", version}, {"level", 3}, {"list", {row}}}}};
    return encodeTemporalMap(index.top, nlohmann::json::object(), MapKind::Tiled, &extra);
  };
  EXPECT_NO_THROW(decodeTileIndex(indexWith(2, 1), "index"));
  EXPECT_THROW(decodeTileIndex(indexWith(1, 1), "index"), FormatError);
  EXPECT_THROW(decodeTileIndex(indexWith(2, 2), "index"), FormatError);
  try {
    decodeTileIndex(indexWith(kTileTableVersion + 1, 1), "index");
    FAIL() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("tile table version " + std::to_string(kTileTableVersion + 1)), std::string::npos)
        << e.what();
  }
}

TEST(Stream, BadInputIsRefused) {
  const std::vector<SessionMap> sessions = randomSessions(9, 4);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  stream(folder, sessions, {1, 2}, 3, 0);
  const auto before = filesOf(folder);
  // Earlier than the map's last session, or at its time.
  EXPECT_THROW(stream(folder, sessions, {0}, 3, 0), UsageError);
  EXPECT_THROW(stream(folder, sessions, {2}, 3, 0), UsageError);
  // Two sessions at one time.
  EXPECT_THROW(stream(folder, sessions, {3, 3}, 3, 0), UsageError);
  // Another tile size, another resolution.
  EXPECT_THROW(stream(folder, sessions, {3}, 4, 0), UsageError);
  StreamSettings s;
  s.folder = folder;
  s.resolution_m = 0.1;
  const auto coarse = [&](size_t) { return StreamSession{timeOf(3), "x", SessionMap(0.1)}; };
  EXPECT_THROW(streamIntoTiles(s, 1, coarse), UsageError);
  s.resolution_m = 0.05;  // the map's, but not the session's
  EXPECT_THROW(streamIntoTiles(s, 1, coarse), UsageError);
  EXPECT_EQ(filesOf(folder), before);
  // A folder that is not a tiled map, a file, a tile size that is no power of two.
  fs::create_directories(dir / "other");
  writeFileAtomic(dir / "other" / "notes.txt", {1});
  EXPECT_THROW(stream(dir / "other", sessions, {0}, 3, 0), UsageError);
  EXPECT_THROW(stream(dir / "other" / "notes.txt", sessions, {0}, 3, 0), UsageError);
  s.folder = dir / "odd";
  s.tile_size_m = 0.3;
  const auto first = [&](size_t) { return StreamSession{timeOf(0), "x", sessions[0]}; };
  EXPECT_THROW(streamIntoTiles(s, 1, first), UsageError);
  EXPECT_FALSE(fs::exists(dir / "odd"));
}


// ---- Tiles kept as windows (TileIndex::windowed, issue 46) ----

/// True when `a` and `b` give every leaf of either the same state (the windowed layout's older
/// snapshots differ from the whole history's in the lengths and cubes of free space without hits
/// only).
::testing::AssertionResult sameStates(const SessionMap& a, const SessionMap& b) {
  for (const SessionMap* m : {&a, &b}) {
    bool same = true;
    VoxelKey where{};
    m->forEachLeaf([&](const LeafView& l) {
      if (same && a.stateOf(l.key) != b.stateOf(l.key)) {
        same = false;
        where = l.key;
      }
    });
    if (!same) return ::testing::AssertionFailure() << "states differ at " << where.x << " " << where.y << " " << where.z;
  }
  return ::testing::AssertionSuccess();
}

class StreamWindowedProperty : public ::testing::TestWithParam<uint64_t> {};

// Random sessions streamed in random batches into both layouts: the windowed one's tiles join to
// the whole layout's, bit for bit, and to the whole map built batch by batch; a closed window is
// never written again; every session's snapshot reads the same states.
TEST_P(StreamWindowedProperty, TilesKeptAsWindowsHoldTheWholeHistory) {
  std::mt19937_64 rng(GetParam());
  const int n = 11;
  const std::vector<SessionMap> sessions = randomSessions(GetParam() * 104729, n);
  std::vector<std::vector<int>> batches(1);
  for (int i = 0; i < n; ++i) {
    if (i > 0 && rng() % 3 != 0) batches.emplace_back();
    batches.back().push_back(i);
  }
  for (auto& b : batches) std::shuffle(b.begin(), b.end(), rng);
  const int level = 3 + static_cast<int>(rng() % 2);
  const uint32_t k = 1 + static_cast<uint32_t>(rng() % 3);
  SCOPED_TRACE("level " + std::to_string(level) + ", windows of " + std::to_string(k) + ", " +
               std::to_string(batches.size()) + " batches");
  test::TempDir dir;
  const fs::path whole_folder = dir / "whole", folder = dir / "windowed";
  std::map<std::string, std::vector<uint8_t>> closed;  // every closed window's bytes, by name
  for (const auto& b : batches) {
    stream(whole_folder, sessions, b, level, 0, 0);
    stream(folder, sessions, b, level, 0, k, 0, true);
    const TileIndex index = readTileIndex(folder);
    ASSERT_TRUE(index.windowed);
    ASSERT_EQ(index.window_sessions, k);
    size_t files = 1;
    for (const TileEntry& e : index.tiles) {
      files += 2 + e.windows.size();
      for (size_t j = 0; j < e.windows.size(); ++j) {
        // closed with a whole window of its own (the first: the tile's staggered share more)
        EXPECT_GE(e.windows[j].sessions - (j > 0), j == 0 ? firstWindowSessions(e.key, k) : k) << e.file;
      }
      for (const WindowFile& w : e.windows) {
        const std::vector<uint8_t> bytes = readFileBytes(folder / w.file);
        const auto [it, fresh] = closed.emplace(w.file, bytes);
        if (!fresh) {
          EXPECT_TRUE(it->second == bytes) << w.file << " written again";
        }
      }
    }
    size_t on_disk = 0;
    for (const auto& f : fs::recursive_directory_iterator(folder)) on_disk += f.is_regular_file();
    EXPECT_EQ(on_disk, files);  // only what the index names
  }
  EXPECT_GT(closed.size(), 0u);
  const TemporalMap whole = wholeBuild(sessions, batches);
  ASSERT_TRUE(test::sameHistory(joined(folder), whole));
  const TileIndex a = readTileIndex(folder), b = readTileIndex(whole_folder);
  ASSERT_EQ(a.tiles.size(), b.tiles.size());
  for (size_t i = 0; i < a.tiles.size(); ++i) {
    ASSERT_EQ(a.tiles[i].key, b.tiles[i].key);
    EXPECT_TRUE(test::sameHistory(readTile(folder, a, a.tiles[i]), readTile(whole_folder, b, b.tiles[i])))
        << a.tiles[i].file;
  }
  for (const double t : whole.times()) {
    TiledMap tiled(folder, {0});
    EXPECT_TRUE(sameStates(tiled.snapshot(t), whole.snapshot(t))) << formatTime(t);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, StreamWindowedProperty, ::testing::Range<uint64_t>(1, 7));

// A night reads and writes a tile's open window only: a closed window damaged after it was
// closed does not stop the nights that reach its tile, but reading the tile whole, or a
// snapshot of a time it holds, names it; the latest state still reads.
TEST(Stream, AWindowedNightReadsTheOpenWindowOnly) {
  const std::vector<std::string> seen = {"AB", "A", "A", "A", "A", "A", "A"};
  const std::vector<SessionMap> sessions = twoRoomNights(4647, seen);
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  for (int i = 0; i < 5; ++i) stream(folder, sessions, {i}, 3, 0, 2, 0, true);
  TileIndex index = readTileIndex(folder);
  const TileEntry* damaged = nullptr;
  for (const TileEntry& e : index.tiles) {
    if (!e.windows.empty()) damaged = &e;
  }
  ASSERT_NE(damaged, nullptr);
  const std::string window = damaged->windows[0].file;
  const TileKey key = damaged->key;
  std::vector<uint8_t> bytes = readFileBytes(folder / window);
  bytes[bytes.size() / 2] ^= 0x40;
  writeFileAtomic(folder / window, bytes);
  for (int i = 5; i < 7; ++i) {
    const StreamResult r = stream(folder, sessions, {i}, 3, 0, 2, 0, true);
    EXPECT_EQ(r.stats.tiles_read, 2u);  // room A's two tiles, their open windows
  }
  index = readTileIndex(folder);
  const TileEntry* e = index.find(key);
  ASSERT_NE(e, nullptr);
  ASSERT_EQ(e->windows[0].file, window);
  // Reached every night, one session a night: the first window closed with f = 2 or 3 sessions
  // (the tile's share), each later one with two of its own: sessions 0-1, 1-3, 3-5 and the open
  // one 5-6 (f = 2), or 0-2, 2-4 and the open one 4-6 (f = 3).
  const uint32_t f = firstWindowSessions(key, 2);
  ASSERT_TRUE(f == 2 || f == 3) << f;
  ASSERT_EQ(e->windows.size(), f == 2 ? 3u : 2u);
  for (size_t j = 0; j < e->windows.size(); ++j) EXPECT_EQ(e->windows[j].sessions, j == 0 ? f : 3u);
  const size_t open_first = f == 2 ? 5 : 4;
  EXPECT_EQ(openWindowFirst(*e), open_first);
  EXPECT_TRUE(readsWindowAt(index, *e, timeOf(static_cast<int>(open_first))));  // the last closed window's last session
  EXPECT_FALSE(readsWindowAt(index, *e, timeOf(6)));
  auto namesTheWindow = [&](const std::function<void()>& read) {
    try {
      read();
      ADD_FAILURE() << "no error";
    } catch (const FormatError& x) {
      EXPECT_NE(std::string(x.what()).find(window), std::string::npos) << x.what();
    }
  };
  namesTheWindow([&] { readTile(folder, index, *e); });
  namesTheWindow([&] { readTileSnapshot(folder, index, *e, timeOf(0)); });
  EXPECT_NO_THROW(readLatestState(folder, index, *e));
  EXPECT_NO_THROW(readTileSnapshot(folder, index, *e, timeOf(6)));  // the open window's time
  fs::remove(folder / window);
  EXPECT_THROW(readTile(folder, index, *e), IoError);
}

// The two writers of the windowed layout close a tile's windows at the same sessions: the nights
// streamed one by one (a tile's first window closes at its firstWindowSessions, later ones at
// K of their own) and the tile's history written whole (writeTileAsWindows, as `tile
// --windowed-tiles` and a group rebuilt whole write it). Room A is reached every night; its two
// tiles have first windows of 2 and 3 sessions.
TEST(Stream, NightlyWindowsCloseWhereATileWrittenWholeCloses) {
  const std::vector<SessionMap> sessions = twoRoomNights(4650, {"AB", "A", "A", "A", "A", "A", "A", "A"});
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  for (int i = 0; i < 8; ++i) stream(folder, sessions, {i}, 3, 0, 2, 0, true);
  const TileIndex index = readTileIndex(folder);
  std::set<uint32_t> firsts;
  for (const TileEntry& e : index.tiles) {
    if (e.windows.empty()) continue;  // room B's, seen on the first night only
    const uint32_t f = firstWindowSessions(e.key, 2);
    firsts.insert(f);
    // Sessions 0 to 7: the first window [0, f), then [f - 1, f + 2), ... while a later night came.
    std::vector<size_t> expected = {f};
    for (size_t end = f + 2; end <= 7; end += 2) expected.push_back(3);
    std::vector<size_t> nightly;
    for (const WindowFile& w : e.windows) nightly.push_back(w.sessions);
    EXPECT_EQ(nightly, expected) << e.file;
    fs::create_directories(dir / "whole" / "tiles");
    const TileEntry whole = writeTileAsWindows(dir / "whole", e.key, 0, readTile(folder, index, e), 2);
    std::vector<size_t> at_once;
    for (const WindowFile& w : whole.windows) at_once.push_back(w.sessions);
    EXPECT_EQ(at_once, nightly) << e.file;
    EXPECT_EQ(openWindowFirst(whole), openWindowFirst(e)) << e.file;
  }
  EXPECT_EQ(firsts, (std::set<uint32_t>{2, 3}));  // both rules seen
}

// The windowed index's rows: closed windows with their session counts, refused when missing,
// too small, named for another tile, or holding more sessions than the tile; a version 4 table
// names its layout.
TEST(Stream, AWindowedIndexIsChecked) {
  const std::vector<SessionMap> sessions = twoRoomNights(4648, {"AB", "A", "AB", "A", "AB"});
  test::TempDir dir;
  const fs::path folder = dir / "tiled";
  for (int i = 0; i < 5; ++i) stream(folder, sessions, {i}, 3, 0, 1, 0, true);
  const TileIndex index = readTileIndex(folder);
  size_t row = 0, other = 1;
  for (size_t i = 0; i < index.tiles.size(); ++i) {
    if (index.tiles[i].windows.size() >= 2) row = i;
  }
  other = row == 0 ? 1 : 0;
  ASSERT_GE(index.tiles[row].windows.size(), 2u);
  const test::TileTableEdits edits(folder);
  EXPECT_EQ(edits.table()["version"], 4);
  EXPECT_EQ(edits.table()["layout"], "windows");
  const TileIndex same = decodeTileIndex(edits.with([](nlohmann::json&) {}), "index");
  ASSERT_TRUE(same.windowed);
  EXPECT_EQ(openWindowFirst(same.tiles[row]), openWindowFirst(index.tiles[row]));
  edits.expectRefused([](nlohmann::json& t) { t.erase("layout"); }, "names no layout");
  edits.expectRefused([](nlohmann::json& t) { t["layout"] = "tiles"; }, "names no layout");
  edits.expectRefused([](nlohmann::json& t) { t.erase("window_sessions"); }, "without its window session count");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][0].erase("sessions"); }, "malformed");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][1]["sessions"] = 1; }, "cannot hold");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][0]["sessions"] = 0; }, "cannot hold");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][0]["sessions"] = t["list"][row]["windows"][1]["sessions"] = 5; },
          "closed windows");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][0]["file"] = t["list"][other]["file"]; },
          "window file name");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][0]["file"] = t["list"][row]["file"]; },
          "window file name");
  // A closed window named for a later generation than the open one: a later run would write that name.
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["windows"][0]["file"] = tileFileName(index.tiles[row].key, 999); },
          "later generation");
  edits.expectRefused([&](nlohmann::json& t) { t["list"][row]["sessions"] = 0; }, "sessions held");
  // A closed window whose file holds other sessions than its row says.
  TileEntry shifted = index.tiles[row];
  shifted.windows[1].sessions += 1;
  try {
    readTile(folder, index, shifted);
    ADD_FAILURE() << "no error";
  } catch (const FormatError& x) {
    EXPECT_NE(std::string(x.what()).find(shifted.windows[1].file), std::string::npos) << x.what();
  }
  // An open window of another change criterion (its size and checksum those its row lists): a
  // night would decide its changes by it.
  TileEntry recriterioned = index.tiles[row];
  const TemporalMap open = readTemporalMap(folder / recriterioned.file);
  ChangeCriterion criterion;
  criterion.probability_threshold = 0.2;
  const std::vector<uint8_t> bytes = encodeTemporalMapAsItIs(
      TemporalMap::fromParts(open.resolution_m(), criterion, open.parts(), open.sessions()), nlohmann::json::object());
  writeFileAtomic(folder / recriterioned.file, bytes);
  recriterioned.bytes = bytes.size();
  recriterioned.crc32 = static_cast<uint32_t>(crc32(crc32(0L, Z_NULL, 0), bytes.data(), static_cast<uInt>(bytes.size())));
  for (const std::function<void()>& read : std::vector<std::function<void()>>{
           [&] { readOpenWindow(folder, index, recriterioned); }, [&] { readTile(folder, index, recriterioned); }}) {
    try {
      read();
      ADD_FAILURE() << "no error";
    } catch (const FormatError& x) {
      EXPECT_NE(std::string(x.what()).find("change criterion"), std::string::npos) << x.what();
      EXPECT_NE(std::string(x.what()).find(recriterioned.file), std::string::npos) << x.what();
    }
  }
}

// `tile --windowed-tiles` (writeTiledMap): the windowed layout cut from a whole map reads back
// as that map, and later nights stream onto it as onto the streamed folder.
TEST(Stream, AMapCutIntoWindowedTilesTakesLaterNights) {
  const std::vector<SessionMap> sessions = twoRoomNights(4649, {"AB", "A", "B", "AB", "A", "B", "A"});
  std::vector<std::vector<int>> first = {{0}, {1}, {2}, {3}, {4}};
  TemporalMap map = wholeBuild(sessions, first);
  map.compact();
  test::TempDir dir;
  writeTiledMap(dir / "cut", splitIntoTiles(map, 3), nlohmann::json::object(), 2, {}, true);
  const TileIndex index = readTileIndex(dir / "cut");
  ASSERT_TRUE(index.windowed);
  size_t windows = 0;
  for (const TileEntry& e : index.tiles) {
    // Five sessions, windows of 2: [0, 2), [1, 4) and the open [3, 5) where the tile's first
    // window holds 2; [0, 3) and the open [2, 5) where it holds 3.
    const uint32_t f = firstWindowSessions(e.key, 2);
    ASSERT_EQ(e.windows.size(), f == 2 ? 2u : 1u) << e.file;
    for (size_t j = 0; j < e.windows.size(); ++j) EXPECT_EQ(e.windows[j].sessions, j == 0 ? f : 3u) << e.file;
    windows += e.windows.size();
  }
  EXPECT_GT(windows, 0u);
  EXPECT_TRUE(test::sameHistory(joined(dir / "cut"), map));
  for (int i = 5; i < 7; ++i) {
    stream(dir / "cut", sessions, {i}, 3, 0, 2);
    first.push_back({i});
  }
  EXPECT_TRUE(readTileIndex(dir / "cut").windowed);  // the folder keeps its layout
  EXPECT_TRUE(test::sameHistory(joined(dir / "cut"), wholeBuild(sessions, first)));
}

}  // namespace chronomap::stream_test
