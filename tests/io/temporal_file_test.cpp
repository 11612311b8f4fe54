#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/io/file.h"
#include "chronomap/io/temporal_file.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

TemporalMap sampleMap(int sessions, uint64_t seed = 1) {
  TemporalMap map(0.05);
  for (int i = 0; i < sessions; ++i) map.add(1000.0 * (i + 1), test::randomSessionMap(seed + static_cast<uint64_t>(i)));
  return map;
}

std::vector<uint8_t> bytesOf(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const fs::path& p, const std::vector<uint8_t>& b) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

TEST(TemporalFile, RoundTripReadsBackIdentically) {
  test::TempDir tmp;
  TemporalMap map = sampleMap(4);
  io::writeTemporalMap(tmp / "m.cmap", map, {{"note", "test"}});
  const TemporalMap back = io::readTemporalMap(tmp / "m.cmap");
  TemporalMap compacted = map;
  compacted.compact();
  EXPECT_TRUE(back == compacted);
  EXPECT_EQ(back.times(), map.times());
  for (double t : map.times()) EXPECT_TRUE(back.snapshot(t) == compacted.snapshot(t));
  // Writing what was read gives the same bytes: the format is deterministic.
  io::writeTemporalMap(tmp / "again.cmap", back, {{"note", "test"}});
  EXPECT_EQ(bytesOf(tmp / "m.cmap"), bytesOf(tmp / "again.cmap"));
}

TEST(TemporalFile, EmptyMapRoundTrips) {
  test::TempDir tmp;
  io::writeTemporalMap(tmp / "e.cmap", TemporalMap(0.1), {});
  const TemporalMap back = io::readTemporalMap(tmp / "e.cmap");
  EXPECT_EQ(back.sessionCount(), 0u);
  EXPECT_DOUBLE_EQ(back.resolution_m(), 0.1);
}

TEST(TemporalFile, AppendEqualsBuildingInOneGo) {
  test::TempDir tmp;
  io::writeTemporalMap(tmp / "m.cmap", sampleMap(2), {});
  TemporalMap loaded = io::readTemporalMap(tmp / "m.cmap");
  loaded.add(3000.0, test::randomSessionMap(3));
  io::writeTemporalMap(tmp / "m.cmap", loaded, {});
  const TemporalMap appended = io::readTemporalMap(tmp / "m.cmap");
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
  io::writeTemporalMap(tmp / "m.cmap", sampleMap(3), {});
  const auto good = bytesOf(tmp / "m.cmap");
  for (size_t keep : {size_t{0}, size_t{10}, size_t{90}, good.size() / 2, good.size() - 1}) {
    writeBytes(tmp / "t.cmap", std::vector<uint8_t>(good.begin(), good.begin() + static_cast<long>(keep)));
    try {
      io::readTemporalMap(tmp / "t.cmap");
      FAIL() << "truncated to " << keep << " bytes was accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("t.cmap"), std::string::npos) << e.what();
    }
  }
  for (size_t at = 84; at < good.size(); at += std::max<size_t>(1, good.size() / 37)) {
    auto bad = good;
    bad[at] ^= 0x5a;
    writeBytes(tmp / "c.cmap", bad);
    EXPECT_THROW(io::readTemporalMap(tmp / "c.cmap"), FormatError) << "byte " << at;
  }
}

TEST(TemporalFile, SessionFilesAreNotFourDimensional) {
  test::TempDir tmp;
  io::writeSessionMap(tmp / "s.cmap", test::randomSessionMap(1), {});
  try {
    io::readTemporalMap(tmp / "s.cmap");
    FAIL();
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("not a 4D map"), std::string::npos) << e.what();
  }
  io::writeTemporalMap(tmp / "m.cmap", sampleMap(1), {});
  EXPECT_THROW(io::readSessionMap(tmp / "m.cmap"), FormatError);
}

TEST(TemporalFile, CraftedBlocksAreRejected) {
  // Valid container, invalid content: every block is checked, not just the checksums.
  test::TempDir tmp;
  const TemporalMap map = sampleMap(2);
  io::writeTemporalMap(tmp / "m.cmap", map, {});
  const io::CmapFile file = io::readCmap(tmp / "m.cmap");
  auto rewrite = [&](const std::string& tag, auto&& mutate) {
    io::CmapFile f = file;
    for (auto& b : f.blocks) {
      if (b.tag == tag) mutate(b.data);
    }
    io::writeFileAtomic(tmp / "x.cmap", io::encodeCmap(f.header, f.blocks));
    return tmp / "x.cmap";
  };
  EXPECT_THROW(io::readTemporalMap(rewrite("LSTS", [](auto& d) { d.erase(d.end() - std::min<std::ptrdiff_t>(4, std::ssize(d)), d.end()); })), FormatError);
  EXPECT_THROW(io::readTemporalMap(rewrite("ENTR", [](auto& d) { d[0] = 0xff; d[1] = 0xff; })), FormatError);
  EXPECT_THROW(io::readTemporalMap(rewrite("COVR", [](auto& d) { d.push_back(1); })), FormatError);
  EXPECT_THROW(io::readTemporalMap(rewrite("COVR", [](auto& d) { std::fill(d.begin(), d.end(), uint8_t{0xff}); })), FormatError);
  EXPECT_THROW(io::readTemporalMap(rewrite("META", [](auto& d) { d = std::vector<uint8_t>{'{', '}'}; })), FormatError);
  EXPECT_THROW(io::readTemporalMap(rewrite("INNR", [](auto& d) { d[3] = 0x12; })), FormatError);
}

}  // namespace
}  // namespace chronomap
