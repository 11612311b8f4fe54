#include <gtest/gtest.h>
#include <zlib.h>

#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "chronomap/core/error.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/file.h"
#include "test_support.h"

namespace chronomap::io {
namespace {

SessionMap sampleMap() {
  SessionMap m(0.05);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> c(30000, 30063);
  for (int i = 0; i < 2000; ++i) {
    VoxelCounters d;
    d.length_m = 0.01f * static_cast<float>(i % 7 + 1);
    d.hits = static_cast<uint32_t>(i % 3 == 0);
    d.red = 200 * d.hits;
    d.offset[0] = 0.25f * static_cast<float>(d.hits);
    d.offset[2] = -0.5f * static_cast<float>(d.hits);
    m.add({static_cast<uint16_t>(c(rng)), static_cast<uint16_t>(c(rng)), static_cast<uint16_t>(c(rng))}, d);
  }
  for (uint16_t x = 0; x < 8; ++x)
    for (uint16_t y = 0; y < 8; ++y)
      for (uint16_t z = 0; z < 8; ++z) {
        VoxelCounters f;
        f.length_m = 0.05f;
        m.add({static_cast<uint16_t>(31000 + x), static_cast<uint16_t>(31000 + y), static_cast<uint16_t>(31000 + z)}, f);
      }
  m.compressFree();
  return m;
}

using test::writeBytes;

TEST(Cmap, SessionMapRoundTripsWithMetadata) {
  test::TempDir tmp;
  const SessionMap m = sampleMap();
  writeSessionMap(tmp / "m.cmap", m, {{"frames", 3}});
  const CmapFile f = readCmap(tmp / "m.cmap");
  EXPECT_EQ(f.header.kind, MapKind::Session);
  EXPECT_EQ(f.header.version, kCmapFormatVersion);
  EXPECT_DOUBLE_EQ(f.header.resolution_m, 0.05);
  EXPECT_EQ(metadataOf(f)["frames"], 3);
  const SessionMap back = sessionMapFrom(f, "m.cmap");
  EXPECT_TRUE(back == m);
  EXPECT_EQ(back.innerPool(), m.innerPool());
  EXPECT_EQ(back.counts().compressed_leaves, 1u);
  // Bounds cover the known voxels.
  EXPECT_NEAR(f.header.bounds_max_m.x(), (31008 - 32768) * 0.05, 1e-9);
  // Writing twice gives identical bytes.
  writeSessionMap(tmp / "m2.cmap", back, {{"frames", 3}});
  EXPECT_EQ(readFileBytes(tmp / "m.cmap"), readFileBytes(tmp / "m2.cmap"));
}

TEST(Cmap, EmptyMapRoundTrips) {
  test::TempDir tmp;
  writeSessionMap(tmp / "e.cmap", SessionMap(0.1), nullptr);
  const SessionMap back = readSessionMap(tmp / "e.cmap");
  EXPECT_TRUE(back.empty());
  EXPECT_DOUBLE_EQ(back.resolution_m(), 0.1);
}

TEST(Cmap, RejectsEveryTruncation) {
  test::TempDir tmp;
  writeSessionMap(tmp / "m.cmap", sampleMap(), {{"k", "v"}});
  const auto bytes = readFileBytes(tmp / "m.cmap");
  for (size_t cut = 0; cut < bytes.size(); cut += std::max<size_t>(1, bytes.size() / 300)) {
    const std::vector<uint8_t> part(bytes.begin(), bytes.begin() + static_cast<long>(cut));
    EXPECT_THROW(decodeCmap(part, "m.cmap"), FormatError) << "cut at " << cut;
  }
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(decodeCmap(longer, "m.cmap"), FormatError);
}

TEST(Cmap, RejectsFlippedBytesAnywhere) {
  test::TempDir tmp;
  writeSessionMap(tmp / "m.cmap", sampleMap(), {{"k", "v"}});
  const auto bytes = readFileBytes(tmp / "m.cmap");
  std::mt19937 rng(9);
  for (size_t pos = 0; pos < bytes.size(); pos += std::max<size_t>(1, bytes.size() / 400)) {
    auto bad = bytes;
    bad[pos] ^= static_cast<uint8_t>(1u << (rng() % 8));
    EXPECT_THROW(sessionMapFrom(decodeCmap(bad, "m.cmap"), "m.cmap"), FormatError) << "flip at " << pos;
  }
}

TEST(Cmap, ExplainsWrongMagicNewerVersionAndEmptyFiles) {
  test::TempDir tmp;
  writeSessionMap(tmp / "m.cmap", sampleMap(), nullptr);
  auto bytes = readFileBytes(tmp / "m.cmap");
  auto expectMessage = [&](const std::vector<uint8_t>& b, const std::string& fragment) {
    writeBytes(tmp / "x.cmap", b);
    try {
      readSessionMap(tmp / "x.cmap");
      FAIL() << fragment;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("x.cmap"), std::string::npos) << e.what();
    }
  };
  auto magic = bytes;
  magic[1] = 'X';
  expectMessage(magic, "wrong magic");
  auto newer = bytes;
  newer[8] = static_cast<uint8_t>(kCmapFormatVersion + 1);
  expectMessage(newer, "newer chronomap");
  expectMessage({}, "empty");
  std::vector<uint8_t> ply = {'p', 'l', 'y', '\n'};
  expectMessage(ply, "wrong magic");
}

TEST(Cmap, RejectsAValidContainerWithAnInvalidTree) {
  CmapHeader h;
  h.resolution_m = 0.05;
  std::vector<CmapBlock> blocks(2);
  blocks[0].tag = "INNR";
  SessionMap::Children root;
  root.fill(SessionMap::kEmpty);
  root[3] = 7;  // dangling
  blocks[0].data.resize(sizeof(root));
  std::memcpy(blocks[0].data.data(), &root, sizeof(root));
  blocks[1].tag = "LEAF";
  const auto bytes = encodeCmap(h, blocks);
  EXPECT_THROW(sessionMapFrom(decodeCmap(bytes, "crafted.cmap"), "crafted.cmap"), FormatError);
  h.kind = MapKind::Diff;
  EXPECT_THROW(sessionMapFrom(decodeCmap(encodeCmap(h, blocks), "d.cmap"), "d.cmap"), FormatError);
}

/// A zstd frame (RFC 8878) whose header claims `content_bytes` but holds one RLE block of 128 KiB:
/// magic, a descriptor (single segment, 8-byte content size), the size, a 3-byte block header
/// (last block, RLE, 131072 bytes) and the repeated byte.
std::vector<uint8_t> zstdFrameClaiming(uint64_t content_bytes) {
  std::vector<uint8_t> frame = {0x28, 0xb5, 0x2f, 0xfd, 0xe0};
  for (int i = 0; i < 8; ++i) frame.push_back(static_cast<uint8_t>(content_bytes >> (8 * i)));
  const uint32_t block_header = 1u | (1u << 1) | (131072u << 3);
  for (int i = 0; i < 3; ++i) frame.push_back(static_cast<uint8_t>(block_header >> (8 * i)));
  frame.push_back('z');
  return frame;
}

TEST(Cmap, RefusesZstdBlocksClaimingMoreThanTheyCanHold) {
  // A block of 17 stored bytes whose header and zstd frame both claim 32 GiB, checksums valid:
  // refused before its claimed size is allocated (before, the reader allocated 32 GiB).
  CmapHeader h;
  h.resolution_m = 0.05;
  std::vector<CmapBlock> blocks(1);
  blocks[0].tag = "META";
  const uint64_t claimed = uint64_t{1} << 35;
  blocks[0].data = zstdFrameClaiming(claimed);
  std::vector<uint8_t> bytes = encodeCmap(h, blocks, /*zstd_level=*/0);
  const uint32_t zstd = 1;
  std::memcpy(bytes.data() + 84 + 4, &zstd, 4);      // the block's codec
  std::memcpy(bytes.data() + 84 + 8, &claimed, 8);   // its raw size (the stored CRC is unchanged)
  const int code = test::exitCodeUnderMemoryLimit(uint64_t{1} << 30, [&] {
    try {
      decodeCmap(bytes, "bomb.cmap");
      return 1;
    } catch (const FormatError& e) {
      const std::string m = e.what();
      return m.find("bomb.cmap: block 'META' claims 34359738368 bytes from 17 stored bytes") != std::string::npos ? 0
                                                                                                                  : 2;
    }
  });
  EXPECT_EQ(code, 0) << "0: refused naming the block, 1: read, 2: another message, 99: out of memory";
  // The same frame claiming its true size is read: the bound leaves real RLE blocks alone.
  blocks[0].data = zstdFrameClaiming(131072);
  bytes = encodeCmap(h, blocks, 0);
  std::memcpy(bytes.data() + 84 + 4, &zstd, 4);
  const uint64_t real = 131072;
  std::memcpy(bytes.data() + 84 + 8, &real, 8);
  const uint32_t crc_raw = static_cast<uint32_t>(crc32(0, std::vector<uint8_t>(131072, 'z').data(), 131072));
  std::memcpy(bytes.data() + 84 + 28, &crc_raw, 4);
  EXPECT_EQ(decodeCmap(bytes, "rle.cmap").blocks.at(0).data, std::vector<uint8_t>(131072, 'z'));
  // And so is what zstd itself writes for the most compressible data (8 MiB of zeros).
  blocks[0].data.assign(size_t{8} << 20, 0);
  const std::vector<uint8_t> packed = encodeCmap(h, blocks, 3);
  EXPECT_GT(blocks[0].data.size() / packed.size(), 10000u) << "expected zstd near its maximum ratio";
  EXPECT_EQ(decodeCmap(packed, "zeros.cmap").blocks.at(0).data, blocks[0].data);
}

TEST(Cmap, FilesWithoutHitPositionsReadWithHitsAtTheCentres) {
  // Files written before the hit positions were kept have no HPOS block.
  const SessionMap m = sampleMap();
  CmapFile f = decodeCmap(encodeSessionMap(m, nullptr), "m.cmap");
  ASSERT_NE(f.find("HPOS"), nullptr);
  std::erase_if(f.blocks, [](const CmapBlock& b) { return b.tag == "HPOS"; });
  const SessionMap old = sessionMapFrom(decodeCmap(encodeCmap(f.header, f.blocks), "old.cmap"), "old.cmap");
  ASSERT_EQ(old.leafCount(), m.leafCount());
  size_t with_hits = 0;
  for (size_t i = 0; i < m.leafCount(); ++i) {
    VoxelCounters expected = m.leafPool()[i];
    with_hits += expected.hits > 0 && expected.offset[0] != 0.0f;
    for (float& o : expected.offset) o = 0.0f;
    EXPECT_EQ(old.leafPool()[i], expected);
  }
  EXPECT_GT(with_hits, 100u) << "the sample map has positions to lose";
}

TEST(Cmap, RejectsImpossibleHitPositions) {
  const SessionMap m = sampleMap();
  const CmapFile f = decodeCmap(encodeSessionMap(m, nullptr), "m.cmap");
  // The first leaf with hits, and one without.
  size_t hit = 0, empty = 0;
  while (m.leafPool()[hit].hits == 0) ++hit;
  while (m.leafPool()[empty].hits != 0) ++empty;
  auto withPositions = [&](auto&& mutate) {
    CmapFile g = f;
    for (CmapBlock& b : g.blocks) {
      if (b.tag == "HPOS") mutate(b.data);
    }
    return decodeCmap(encodeCmap(g.header, g.blocks), "crafted.cmap");
  };
  auto setFloat = [](std::vector<uint8_t>& d, size_t at, float v) { std::memcpy(d.data() + at, &v, 4); };
  EXPECT_NO_THROW(sessionMapFrom(withPositions([](auto&) {}), "crafted.cmap"));
  EXPECT_THROW(sessionMapFrom(withPositions([](auto& d) { d.pop_back(); }), "crafted.cmap"), FormatError);
  EXPECT_THROW(sessionMapFrom(withPositions([&](auto& d) { setFloat(d, hit * 12, std::nanf("")); }), "crafted.cmap"),
               FormatError);
  // Beyond half a voxel per hit: no ray ends outside its voxel.
  const float too_far = 0.51f * static_cast<float>(m.leafPool()[hit].hits);
  EXPECT_THROW(sessionMapFrom(withPositions([&](auto& d) { setFloat(d, hit * 12 + 4, too_far); }), "crafted.cmap"),
               FormatError);
  EXPECT_THROW(sessionMapFrom(withPositions([&](auto& d) { setFloat(d, empty * 12, 0.1f); }), "crafted.cmap"),
               FormatError)
      << "a position without hits";
}

TEST(Cmap, FailedWriteLeavesTheOldFileIntact) {
  test::TempDir tmp;
  writeSessionMap(tmp / "m.cmap", sampleMap(), nullptr);
  const auto before = readFileBytes(tmp / "m.cmap");
  EXPECT_THROW(writeSessionMap(tmp / "no-such-dir" / "m.cmap", sampleMap(), nullptr), IoError);
  // Make the folder read-only: the temporary file cannot be created, the old file stays.
  if (::geteuid() != 0) {
    std::filesystem::permissions(tmp.path(), std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
    EXPECT_THROW(writeSessionMap(tmp / "m.cmap", SessionMap(0.1), nullptr), IoError);
    std::filesystem::permissions(tmp.path(), std::filesystem::perms::owner_all);
  }
  EXPECT_EQ(readFileBytes(tmp / "m.cmap"), before);
  size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(tmp.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);  // no temporary file left behind
}

TEST(Cmap, FullDiskLeavesTheOldFileIntact) {
  test::TempDir tmp;
  writeSessionMap(tmp / "m.cmap", SessionMap(0.1), nullptr);
  const auto before = readFileBytes(tmp / "m.cmap");
  // A 4 KiB file-size limit in a child process stands in for a full disk.
  const int code = test::exitCodeUnderFileSizeLimit(4096, [&] {
    try {
      writeSessionMap(tmp / "m.cmap", sampleMap(), nullptr);
    } catch (const IoError&) {
      return 42;
    }
    return 0;
  });
  EXPECT_EQ(code, 42) << "the write should fail with an IoError";
  EXPECT_EQ(readFileBytes(tmp / "m.cmap"), before);
  size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(tmp.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);  // the temporary file was removed
}

}  // namespace
}  // namespace chronomap::io
