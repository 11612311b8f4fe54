#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

TemporalMap sampleMap(int sessions, uint64_t seed = 1) {
  TemporalMap map(0.05);
  for (int i = 0; i < sessions; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(seed + static_cast<uint64_t>(i)));
  return map;
}

using test::bytesOf;
using test::writeBytes;

TEST(TemporalFile, RoundTripReadsBackIdentically) {
  test::TempDir tmp;
  TemporalMap map = sampleMap(4);
  writeTemporalMap(tmp / "m.cmap", map, {{"note", "test"}});
  const TemporalMap back = readTemporalMap(tmp / "m.cmap");
  TemporalMap compacted = map;
  compacted.compact();
  // Everything exact but the hit positions, lengths and colour sums, which the file keeps
  // quantised (asStored): within their bounds, no entry's state changed.
  const TemporalMap stored = asStored(compacted);
  // The sample's lengths and colour sums are ones the file keeps exactly, and the map keeps its
  // hit positions as the file does: nothing to quantise here.
  EXPECT_TRUE(stored == compacted);
  EXPECT_TRUE(back == stored);
  const auto& written = compacted.parts().entries;
  const auto& read = back.parts().entries;
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 0; i < read.size(); ++i) {
    const VoxelCounters& a = written[i].value;
    const VoxelCounters& b = read[i].value;
    ASSERT_EQ(b.hits, a.hits);
    EXPECT_EQ(b.state(), a.state()) << "entry " << i;
    EXPECT_EQ(b.meanColour(), a.meanColour()) << "entry " << i;
    if (a.length_m > 0.0f) {
      EXPECT_LE(std::abs(b.length_m / a.length_m - 1.0f), kLengthRelativeError) << "entry " << i;
    }
  }
  EXPECT_EQ(back.times(), map.times());
  for (double t : map.times()) EXPECT_TRUE(back.snapshot(t) == stored.snapshot(t));
  // Writing what was read gives the same bytes: the format is deterministic.
  writeTemporalMap(tmp / "again.cmap", back, {{"note", "test"}});
  EXPECT_EQ(bytesOf(tmp / "m.cmap"), bytesOf(tmp / "again.cmap"));
}

// A map compacted already is written without compacting a copy: the bytes are those of the
// same map compacted by the writer; records replaced in place are written as given.
TEST(TemporalFile, ACompactedMapIsWrittenAsItIs) {
  TemporalMap map = sampleMap(5, 7);
  const std::vector<uint8_t> by_writer = encodeTemporalMap(map, nlohmann::json::object());
  EXPECT_FALSE(map.isCompact());
  map.compact();
  ASSERT_TRUE(map.isCompact());
  const size_t relayouts = map.relayouts();
  EXPECT_EQ(map.compact(), 0u);  // at once: nothing merged, nothing laid out again
  EXPECT_EQ(map.relayouts(), relayouts);
  EXPECT_EQ(encodeTemporalMap(map, nlohmann::json::object()), by_writer);

  std::vector<SessionRecord> records = map.sessions();
  for (SessionRecord& r : records) r.name = "renamed";
  map.replaceSessionRecords(records);
  EXPECT_FALSE(map.isCompact());
  const TemporalMap rebuilt = TemporalMap::fromParts(map.resolution_m(), map.criterion(), map.parts(), records);
  EXPECT_TRUE(map == rebuilt);
  map.compact();
  EXPECT_EQ(encodeTemporalMap(map, nlohmann::json::object()), encodeTemporalMap(rebuilt, nlohmann::json::object()));

  records.pop_back();
  EXPECT_THROW(map.replaceSessionRecords(records), UsageError);
  records = map.sessions();
  records.back().time_s += 1.0;
  EXPECT_THROW(map.replaceSessionRecords(records), UsageError);

  // Adding a session ends it: compacting again merges and re-lays out what the add made.
  map.add(1e6, test::randomSessionMap(99));
  EXPECT_FALSE(map.isCompact());
  TemporalMap fresh = TemporalMap::fromParts(map.resolution_m(), map.criterion(), map.parts(), map.sessions());
  EXPECT_EQ(encodeTemporalMap(map, nlohmann::json::object()), encodeTemporalMap(fresh, nlohmann::json::object()));
  map.remove(1e6);
  EXPECT_FALSE(map.isCompact());
}

// The evidence rule is stored with the map (and read back); a map without it has no such keys,
// so its bytes are those of builds before the rule existed.
TEST(TemporalFile, TheEvidenceRuleIsStoredOnlyWhenOn) {
  test::TempDir tmp;
  ChangeCriterion rule;
  rule.min_free_length_m = 0.025;
  rule.min_hits = 2;
  TemporalMap with(0.05, rule), without(0.05);
  with.add(1000.0, test::randomSessionMap(3));
  without.add(1000.0, test::randomSessionMap(3));
  writeTemporalMap(tmp / "with.cmap", with, {});
  writeTemporalMap(tmp / "without.cmap", without, {});
  EXPECT_TRUE(readTemporalMap(tmp / "with.cmap").criterion() == rule);
  EXPECT_TRUE(readTemporalMap(tmp / "without.cmap").criterion() == ChangeCriterion{});
  auto metaOf = [](const fs::path& path) {
    const CmapFile file = decodeCmap(bytesOf(path), path.string());
    const CmapBlock& meta = file.block("META", path.string());
    return std::string(meta.data.begin(), meta.data.end());
  };
  EXPECT_NE(metaOf(tmp / "with.cmap").find("\"min_hits\":2"), std::string::npos);
  EXPECT_NE(metaOf(tmp / "with.cmap").find("\"min_free_length_m\":0.025"), std::string::npos);
  EXPECT_EQ(metaOf(tmp / "without.cmap").find("min_hits"), std::string::npos);
  EXPECT_EQ(metaOf(tmp / "without.cmap").find("min_free_length_m"), std::string::npos);

  // A rule the file states badly is refused naming the file: a negative, fractional, huge or
  // textual hit count, a textual or negative length.
  const CmapFile good = decodeCmap(bytesOf(tmp / "with.cmap"), "with.cmap");
  const std::vector<std::pair<const char*, nlohmann::json>> bad = {
      {"min_hits", -3}, {"min_hits", 2.5}, {"min_hits", 2000000}, {"min_hits", "two"},
      {"min_free_length_m", "far"}, {"min_free_length_m", -0.5}};
  for (const auto& [key, value] : bad) {
    CmapFile f = good;
    for (CmapBlock& b : f.blocks) {
      if (b.tag != "META") continue;
      nlohmann::json j = nlohmann::json::parse(b.data.begin(), b.data.end());
      j["criterion"][key] = value;
      const std::string text = j.dump();
      b.data.assign(text.begin(), text.end());
    }
    writeFileAtomic(tmp / "bad.cmap", encodeCmap(f.header, f.blocks));
    try {
      readTemporalMap(tmp / "bad.cmap");
      ADD_FAILURE() << key << " = " << value.dump() << " was read";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.cmap"), std::string::npos) << e.what();
    }
  }
}

TEST(TemporalFile, EmptyMapRoundTrips) {
  test::TempDir tmp;
  writeTemporalMap(tmp / "e.cmap", TemporalMap(0.1), {});
  const TemporalMap back = readTemporalMap(tmp / "e.cmap");
  EXPECT_EQ(back.sessionCount(), 0u);
  EXPECT_DOUBLE_EQ(back.resolution_m(), 0.1);
}

TEST(TemporalFile, AppendEqualsBuildingInOneGo) {
  test::TempDir tmp;
  writeTemporalMap(tmp / "m.cmap", sampleMap(2), {});
  TemporalMap loaded = readTemporalMap(tmp / "m.cmap");
  loaded.add(3000.0, test::randomSessionMap(3));
  writeTemporalMap(tmp / "m.cmap", loaded, {});
  const TemporalMap appended = readTemporalMap(tmp / "m.cmap");
  const TemporalMap direct = sampleMap(3);
  for (double t : direct.times()) {
    const SessionMap a = appended.snapshot(t), b = direct.snapshot(t);
    b.forEachLeaf([&](const LeafView& leaf) {
      if (leaf.level == 0) {
        ASSERT_EQ(a.stateOf(leaf.key), leaf.counters.state());
      }
    });
    EXPECT_EQ(a.counts().occupied_voxels, b.counts().occupied_voxels);
    EXPECT_EQ(a.counts().free_voxels, b.counts().free_voxels);
  }
}

TEST(TemporalFile, TruncatedAndCorruptFilesAreRejectedByName) {
  test::TempDir tmp;
  writeTemporalMap(tmp / "m.cmap", sampleMap(3), {});
  const auto good = bytesOf(tmp / "m.cmap");
  for (size_t keep : {size_t{0}, size_t{10}, size_t{90}, good.size() / 2, good.size() - 1}) {
    writeBytes(tmp / "t.cmap", std::vector<uint8_t>(good.begin(), good.begin() + static_cast<long>(keep)));
    try {
      readTemporalMap(tmp / "t.cmap");
      FAIL() << "truncated to " << keep << " bytes was accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("t.cmap"), std::string::npos) << e.what();
    }
  }
  for (size_t at = 84; at < good.size(); at += std::max<size_t>(1, good.size() / 37)) {
    auto bad = good;
    bad[at] ^= 0x5a;
    writeBytes(tmp / "c.cmap", bad);
    EXPECT_THROW(readTemporalMap(tmp / "c.cmap"), FormatError) << "byte " << at;
  }
}

TEST(TemporalFile, SessionFilesAreNotFourDimensional) {
  test::TempDir tmp;
  writeSessionMap(tmp / "s.cmap", test::randomSessionMap(1), {});
  try {
    readTemporalMap(tmp / "s.cmap");
    FAIL();
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("not a 4D map"), std::string::npos) << e.what();
  }
  writeTemporalMap(tmp / "m.cmap", sampleMap(1), {});
  EXPECT_THROW(readSessionMap(tmp / "m.cmap"), FormatError);
}

TEST(TemporalFile, CraftedBlocksAreRejected) {
  // Valid container, invalid content: every block is checked, not just the checksums; in the
  // current format version, in version 2 and in version 1.
  test::TempDir tmp;
  const TemporalMap map = sampleMap(2);
  for (uint32_t version : {kCmapFormatVersion, 2u, 1u}) {
    const CmapFile file = decodeCmap(encodeTemporalMap(map, {}, version), "m.cmap");
    auto rewrite = [&](const std::string& tag, auto&& mutate) {
      CmapFile f = file;
      size_t found = 0;
      for (auto& b : f.blocks) {
        if (b.tag == tag) mutate(b.data), ++found;
      }
      EXPECT_EQ(found, 1u) << tag;
      writeFileAtomic(tmp / "x.cmap", encodeCmap(f.header, f.blocks));
      return tmp / "x.cmap";
    };
    auto expectRejected = [&](const fs::path& path, const std::string& what) {
      try {
        readTemporalMap(path);
        ADD_FAILURE() << "version " << version << ": " << what << " was read";
      } catch (const FormatError& e) {
        EXPECT_NE(std::string(e.what()).find("x.cmap"), std::string::npos) << e.what();
      }
    };
    expectRejected(rewrite("COVR", [](auto& d) { d.push_back(1); }), "coverage with a byte more");
    expectRejected(rewrite("COVR", [](auto& d) { std::fill(d.begin(), d.end(), uint8_t{0xff}); }), "overlong coverage");
    expectRejected(rewrite("META", [](auto& d) { d = std::vector<uint8_t>{'{', '}'}; }), "metadata without sessions");
    if (version == 1) {
      expectRejected(rewrite("LSTS", [](auto& d) { d.erase(d.end() - std::min<std::ptrdiff_t>(4, std::ssize(d)), d.end()); }),
                     "a list size short");
      expectRejected(rewrite("ENTR", [](auto& d) { d[0] = 0xff; d[1] = 0xff; }), "a session past the sessions");
      expectRejected(rewrite("INNR", [](auto& d) { d[3] = 0x12; }), "a reference past the pools");
      continue;
    }
    const std::vector<const char*> tags =
        version == 2 ? std::vector<const char*>{"TMSK", "TREF", "LSIZ", "ESES", "CLEN", "CHIT", "CRGB", "CRES", "CPOS"}
                     : std::vector<const char*>{"TMSK", "TREF", "LSIZ", "ESES", "QLEN", "PHIT", "CRGB", "CPOS"};
    for (const char* tag : tags) {
      expectRejected(rewrite(tag, [](auto& d) { d.pop_back(); }), std::string(tag) + " a byte short");
      expectRejected(rewrite(tag, [](auto& d) { d.push_back(0); }), std::string(tag) + " a byte long");
    }
    expectRejected(rewrite("LSIZ", [](auto& d) { d[0] = 0; }), "an empty list");
    expectRejected(rewrite("ESES", [](auto& d) { d[0] = 9; }), "a session past the sessions");
    expectRejected(rewrite("ESES", [](auto& d) { std::fill(d.begin(), d.end(), uint8_t{0xff}); }), "overlong sessions");
    expectRejected(rewrite("TREF", [](auto& d) { d[1] = 0x41; }), "a reference past the pools");
  }
}

TEST(TemporalFile, VersionOneFilesStillReadExactly) {
  // Written by the previous format's writer: read back exactly, positions as floats included,
  // pools in the writer's layout; written again they take the current version.
  TemporalMap map = sampleMap(4);
  map.compact();
  const std::vector<uint8_t> old = encodeTemporalMap(map, {{"old", true}}, 1);
  const CmapFile f = decodeCmap(old, "old.cmap");
  EXPECT_EQ(f.header.version, 1u);
  const TemporalMap back = temporalMapFrom(f, "old.cmap");
  EXPECT_TRUE(back == map);
  EXPECT_EQ(back.parts().inner, map.parts().inner);
  EXPECT_EQ(back.parts().entries, map.parts().entries);
  const std::vector<uint8_t> now = encodeTemporalMap(back, {{"old", true}});
  EXPECT_EQ(decodeCmap(now, "new.cmap").header.version, kCmapFormatVersion);
  EXPECT_LT(now.size(), old.size());
  // The current version keeps the writer's two-layer pool order too.
  const TemporalMap again = temporalMapFrom(decodeCmap(now, "new.cmap"), "new.cmap");
  EXPECT_EQ(again.parts().inner, map.parts().inner);
  EXPECT_EQ(again.parts().list_sizes, map.parts().list_sizes);
}

TEST(TemporalFile, RandomMapsKeepPositionsWithinTheirBound) {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    TemporalMap map = sampleMap(3, 10 * seed);
    map.compact();
    const TemporalMap back = temporalMapFrom(decodeCmap(encodeTemporalMap(map, {}), "r.cmap"), "r.cmap");
    const TemporalMap::Parts a = map.parts(), b = back.parts();
    ASSERT_EQ(a.inner, b.inner);
    ASSERT_EQ(a.list_sizes, b.list_sizes);
    ASSERT_EQ(a.entries.size(), b.entries.size());
    for (size_t i = 0; i < a.entries.size(); ++i) {
      const VoxelCounters &x = a.entries[i].value, &y = b.entries[i].value;
      ASSERT_EQ(a.entries[i].session, b.entries[i].session);
      ASSERT_EQ(std::memcmp(&x, &y, offsetof(VoxelCounters, offset)), 0) << "entry " << i;
      for (int axis = 0; axis < 3; ++axis) {
        EXPECT_LE(std::abs(x.meanOffset(axis) - y.meanOffset(axis)) * map.resolution_m(), map.resolution_m() / 256);
      }
    }
  }
}

TEST(TemporalFile, FilesWithoutHitPositionsReadWithHitsAtTheCentres) {
  test::TempDir tmp;
  TemporalMap map = sampleMap(3);
  map.compact();
  writeFileAtomic(tmp / "m.cmap", encodeTemporalMap(map, {}, 1));  // format version 1
  CmapFile f = readCmap(tmp / "m.cmap");
  ASSERT_NE(f.find("EPOS"), nullptr);
  std::erase_if(f.blocks, [](const CmapBlock& b) { return b.tag == "EPOS"; });
  writeFileAtomic(tmp / "old.cmap", encodeCmap(f.header, f.blocks));
  const TemporalMap old = readTemporalMap(tmp / "old.cmap");
  TemporalMap::Parts expected = map.parts(), got = old.parts();
  size_t with_positions = 0;
  for (TemporalMap::Entry& e : expected.entries) {
    with_positions += e.value.offset[0] != 0.0f;
    for (float& o : e.value.offset) o = 0.0f;
  }
  EXPECT_GT(with_positions, 100u);
  EXPECT_EQ(got.entries, expected.entries);
  // A position block of the wrong size, or with impossible positions, is refused.
  for (auto mutate : {+[](std::vector<uint8_t>& d) { d.erase(d.end() - std::min<std::ptrdiff_t>(12, std::ssize(d)), d.end()); },
                      +[](std::vector<uint8_t>& d) {
                        const float nan = std::nanf("");
                        for (size_t i = 0; i + 4 <= d.size(); i += 4) std::memcpy(d.data() + i, &nan, 4);
                      }}) {
    CmapFile g = readCmap(tmp / "m.cmap");
    for (auto& b : g.blocks) {
      if (b.tag == "EPOS") mutate(b.data);
    }
    writeFileAtomic(tmp / "x.cmap", encodeCmap(g.header, g.blocks));
    EXPECT_THROW(readTemporalMap(tmp / "x.cmap"), FormatError);
  }
}

/// A base of two sessions, then three sessions appended as records (one out of time order, one
/// replacing), as `chronomap add` appends them. `stages[k]` is the map after k records and
/// `ends[k]` the file length then.
struct AppendedFile {
  std::vector<TemporalMap> stages;
  std::vector<uint64_t> ends;
};

AppendedFile writeAppended(const fs::path& path) {
  AppendedFile f;
  writeTemporalMap(path, sampleMap(2), {});
  f.stages.push_back(readTemporalMap(path));
  f.ends.push_back(fs::file_size(path));
  const struct {
    double time_s;
    uint64_t seed;
    bool replace;
  } adds[] = {{3000.0, 3, false}, {1500.0, 4, false}, {3000.0, 5, true}};
  for (const auto& a : adds) {
    const SessionMap session = test::randomSessionMap(a.seed);
    const AddSettings options{a.replace, "seed " + std::to_string(a.seed)};
    TemporalMap next = f.stages.back();
    next.add(a.time_s, session, options);
    appendToFile(path, f.ends.back(), encodeSessionRecord(a.time_s, session, options));
    f.stages.push_back(std::move(next));
    f.ends.push_back(fs::file_size(path));
  }
  return f;
}

TEST(TemporalFile, AppendedSessionsReadBackAsTheMapThatAddedThem) {
  test::TempDir tmp;
  const AppendedFile f = writeAppended(tmp / "m.cmap");
  TemporalFileLayout layout;
  const TemporalMap back = readTemporalMap(tmp / "m.cmap", &layout);
  // As the add that wrote the last record held it, but for the positions the file quantises.
  EXPECT_TRUE(back == asStored(f.stages.back()));
  EXPECT_EQ(back.times(), (std::vector<double>{1000.0, 1500.0, 2000.0, 3000.0}));
  EXPECT_EQ(layout.appended_sessions, 3u);
  EXPECT_EQ(layout.base_bytes, f.ends.front());
  EXPECT_EQ(layout.completeBytes(), f.ends.back());
  EXPECT_EQ(layout.incomplete_tail_bytes, 0u);
  // The same map as building it in memory in one go, and writing it whole folds the records in.
  TemporalMap direct = sampleMap(2);
  direct.add(3000.0, test::randomSessionMap(3), {false, "seed 3"});
  direct.add(1500.0, test::randomSessionMap(4), {false, "seed 4"});
  direct.add(3000.0, test::randomSessionMap(5), {true, "seed 5"});
  EXPECT_TRUE(back == asStored(direct));
  writeTemporalMap(tmp / "whole.cmap", back, {});
  TemporalFileLayout whole;
  TemporalMap compacted = direct;
  compacted.compact();  // as every whole write does
  EXPECT_TRUE(readTemporalMap(tmp / "whole.cmap", &whole) == asStored(compacted));
  EXPECT_EQ(whole.appended_sessions, 0u);
}

// Snapshots bit for bit: the same pools in the same layout (compaction, which every whole
// write does, merges lists but changes no snapshot).
void expectSameSnapshot(const TemporalMap& a, const TemporalMap& b, double t) {
  const SessionMap sa = a.snapshot(t), sb = b.snapshot(t);
  ASSERT_EQ(sa.innerPool(), sb.innerPool()) << "t=" << t;
  ASSERT_TRUE(test::samePools(sa, sb)) << "t=" << t;
}

// The block of test::randomSessionMap, every voxel free, compressed.
SessionMap allFree() {
  SessionMap m(0.05);
  for (int z = 0; z < 16; ++z) {
    for (int y = 0; y < 16; ++y) {
      for (int x = 0; x < 16; ++x) m.add(test::at(x, y, z), test::freeVoxel(0.25f));
    }
  }
  m.compressFree();
  return m;
}

TEST(TemporalFile, AMapBuiltInMemoryAnswersAsItsFile) {
  // Hit positions are kept in memory as the file keeps them, so the map that add() built and
  // the same map written and read back give the same snapshots and histories, bit for bit,
  // but for what format version 3 quantises besides (lengths, colour sums: asStored).
  test::TempDir tmp;
  TemporalMap map = sampleMap(3, 21);
  map.add(1500.0, test::randomSessionMap(31), {false, "out of order"});
  map.add(2000.0, test::randomSessionMap(32), {true, "replaced"});
  writeTemporalMap(tmp / "m.cmap", map, {});
  const TemporalMap back = readTemporalMap(tmp / "m.cmap");
  TemporalMap compacted = map;
  compacted.compact();  // as the write did: histories of merged lists are one level up
  std::vector<double> times = map.times();
  times.push_back(times.back() + 1.0);
  times.push_back(times.front() - 1.0);
  const TemporalMap stored = asStored(compacted);
  for (double t : times) {
    expectSameSnapshot(stored, back, t);
    // Positions are kept in memory as the file keeps them: they read back bit for bit.
    const SessionMap::Pools a = compacted.snapshot(t).pools(), b = back.snapshot(t).pools();
    ASSERT_EQ(a.leaves.size(), b.leaves.size());
    for (size_t i = 0; i < a.leaves.size(); ++i) {
      for (int axis = 0; axis < 3; ++axis) ASSERT_EQ(a.leaves[i].offset[axis], b.leaves[i].offset[axis]);
    }
  }
  size_t with_hits = 0, voxels = 0;
  for (uint64_t seed : {21u, 22u, 23u, 31u, 32u}) {
    const SessionMap session = test::randomSessionMap(seed);
    session.forEachLeaf([&](const LeafView& leaf) {
      const std::vector<HistoryEntry> a = compacted.history(leaf.key), b = back.history(leaf.key);
      ASSERT_EQ(a.size(), b.size());
      ++voxels;
      for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i].time_s, b[i].time_s);
        ASSERT_EQ(a[i].level, b[i].level);
        ASSERT_EQ(asStored(a[i].counters), b[i].counters);
        for (int axis = 0; axis < 3; ++axis) ASSERT_EQ(a[i].counters.offset[axis], b[i].counters.offset[axis]);
        with_hits += a[i].counters.hits > 0 && a[i].counters.meanOffset(0) != 0.0;
      }
    });
  }
  EXPECT_GT(voxels, 1000u);
  EXPECT_GT(with_hits, 100u) << "positions were compared";
  // A single session's positions read as the file keeps them (within its stated bound).
  TemporalMap one(0.05);
  const SessionMap session = test::randomSessionMap(41);
  one.add(1000.0, session);
  session.forEachLeaf([&](const LeafView& leaf) {
    if (leaf.level > 0 || leaf.counters.hits == 0) return;
    const auto v = one.valueAt(leaf.key, 1000.0);
    ASSERT_TRUE(v.has_value());
    for (int axis = 0; axis < 3; ++axis) ASSERT_EQ(v->offset[axis], asStored(leaf.counters).offset[axis]);
  });
}

TEST(TemporalFile, CoarseEntriesAreRebuiltOnRead) {
  // Random sessions alternate with all-free ones (cubes uniform again), some added out of
  // order, one replaced; the file holds only the lists (the format is unchanged), and the map
  // read back, whole or with appended sessions, answers every snapshot bit for bit.
  test::TempDir tmp;
  TemporalMap map(0.05);
  const double times[] = {1000, 3000, 2000, 5000, 4000, 6000};
  for (int i = 0; i < 6; ++i) {
    map.add(times[i], i % 2 ? allFree() : test::randomSessionMap(static_cast<uint64_t>(10 + i)));
  }
  map.add(2000, allFree(), AddSettings{true, "replaced"});
  writeTemporalMap(tmp / "m.cmap", map, {});
  const TemporalMap back = readTemporalMap(tmp / "m.cmap");
  const TemporalMap stored = asStored(map);
  size_t coarse_total = 0;
  for (double t : map.times()) {
    expectSameSnapshot(stored, back, t);
    expectSameSnapshot(stored, back, t + 1.0);
    TemporalMap::SnapshotVisits v;
    back.snapshot(t, &v);
    coarse_total += v.coarse;
  }
  EXPECT_GT(coarse_total, 0u) << "the all-free sessions make cubes uniform again";
  EXPECT_EQ(back.snapshot(2000).leafCount(), 1u) << "at 2000 the whole block reads free";

  const AppendedFile f = writeAppended(tmp / "a.cmap");
  const TemporalMap appended = readTemporalMap(tmp / "a.cmap");
  const TemporalMap stored_stage = asStored(f.stages.back());
  for (double t : appended.times()) expectSameSnapshot(appended, stored_stage, t);
}

TEST(TemporalFile, AnInterruptedAppendLeavesThePreviousMap) {
  // A kill during an append leaves the bytes before it and a prefix of the record: every such
  // prefix reads as the map before that record, and the next append replaces it.
  test::TempDir tmp;
  const AppendedFile f = writeAppended(tmp / "m.cmap");
  const auto good = bytesOf(tmp / "m.cmap");
  std::mt19937_64 rng(7);
  for (size_t k = 0; k + 1 < f.ends.size(); ++k) {
    const uint64_t begin = f.ends[k], end = f.ends[k + 1];
    std::vector<uint64_t> cuts = {begin + 1, begin + 35, begin + 36, begin + 37, end - 1};
    for (int i = 0; i < 12; ++i) cuts.push_back(begin + 1 + rng() % (end - begin - 1));
    for (uint64_t cut : cuts) {
      writeBytes(tmp / "t.cmap", std::vector<uint8_t>(good.begin(), good.begin() + static_cast<long>(cut)));
      TemporalFileLayout layout;
      const TemporalMap back = readTemporalMap(tmp / "t.cmap", &layout);
      ASSERT_TRUE(back == asStored(f.stages[k])) << "record " << k + 1 << " cut after " << cut - begin << " bytes";
      EXPECT_EQ(layout.appended_sessions, k);
      EXPECT_EQ(layout.incomplete_tail_bytes, cut - begin);
      // Appending the record again cuts the interrupted one off first.
      const std::vector<uint8_t> record(good.begin() + static_cast<long>(begin), good.begin() + static_cast<long>(end));
      appendToFile(tmp / "t.cmap", layout.completeBytes(), record);
      ASSERT_TRUE(readTemporalMap(tmp / "t.cmap") == asStored(f.stages[k + 1]));
    }
  }
}

TEST(TemporalFile, CorruptOrCraftedAppendedRecordsAreRejected) {
  test::TempDir tmp;
  const AppendedFile f = writeAppended(tmp / "m.cmap");
  const auto good = bytesOf(tmp / "m.cmap");
  // Every flipped byte of a complete record is caught: its header carries its own checksum.
  for (uint64_t at = f.ends.front(); at < good.size(); at += 1 + (good.size() - f.ends.front()) / 61) {
    auto bad = good;
    bad[at] ^= 0x21;
    writeBytes(tmp / "c.cmap", bad);
    try {
      readTemporalMap(tmp / "c.cmap");
      FAIL() << "byte " << at << " flipped was accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("appended record"), std::string::npos) << e.what();
    }
  }
  // Well-formed records whose content is wrong.
  const std::vector<uint8_t> base(good.begin(), good.begin() + static_cast<long>(f.ends.front()));
  auto withRecord = [&](const std::vector<uint8_t>& record) {
    std::vector<uint8_t> bytes = base;
    bytes.insert(bytes.end(), record.begin(), record.end());
    writeBytes(tmp / "x.cmap", bytes);
    return tmp / "x.cmap";
  };
  const SessionMap session = test::randomSessionMap(9);
  auto expectRejected = [&](const std::vector<uint8_t>& record, const std::string& words) {
    try {
      readTemporalMap(withRecord(record));
      FAIL() << "accepted; expected: " << words;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  // A time the base already holds, without replace.
  expectRejected(encodeSessionRecord(1000.0, session, {}), "cannot be added again");
  expectRejected(encodeAppendRecord({"XTRA", {1, 2, 3}}), "unknown tag");
  expectRejected(encodeAppendRecord({"ADDS", {1, 2, 3}}), "appended session 1");
  expectRejected(encodeAppendRecord({"ADDS", encodeSessionMap(session, {{"time_s", 5.0}}, 0)}),
                 "description is malformed");
  expectRejected(encodeAppendRecord({"ADDS", encodeSessionMap(test::randomSessionMap(9, 16, 0.1, 0.1),
                                                                      {{"time_s", 5.0}, {"replace", false}, {"name", ""}}, 0)}),
                 "resolution");
  // Session and diff files take no records at all.
  writeSessionMap(tmp / "s.cmap", session, {});
  auto s_bytes = bytesOf(tmp / "s.cmap");
  const auto record = encodeSessionRecord(5.0, session, {});
  s_bytes.insert(s_bytes.end(), record.begin(), record.end());
  writeBytes(tmp / "s.cmap", s_bytes);
  EXPECT_THROW(readSessionMap(tmp / "s.cmap"), FormatError);
}

TEST(TemporalFile, AFailedAppendLeavesTheFileAsItWas) {
  test::TempDir tmp;
  writeTemporalMap(tmp / "m.cmap", sampleMap(2), {});
  const auto before = bytesOf(tmp / "m.cmap");
  const auto record = encodeSessionRecord(3000.0, test::randomSessionMap(3, 32, 0.3), {});
  // A file-size limit just above the current size makes the write fail part-way (as a full
  // disk does), in a child process so that the limit stays there.
  const int code = test::exitCodeUnderFileSizeLimit(before.size() + 100, [&] {
    try {
      appendToFile(tmp / "m.cmap", before.size(), record);
    } catch (const IoError& e) {
      return std::string(e.what()).find("the map is unchanged") != std::string::npos ? 3 : 4;
    }
    return 0;
  });
  EXPECT_EQ(code, 3);
  EXPECT_EQ(bytesOf(tmp / "m.cmap"), before);
  // A file that is shorter than what was read is refused, not extended.
  EXPECT_THROW(appendToFile(tmp / "m.cmap", before.size() + 1, record), IoError);
  EXPECT_EQ(bytesOf(tmp / "m.cmap"), before);
}

}  // namespace
}  // namespace chronomap
