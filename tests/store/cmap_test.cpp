#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/core/file.h"
#include "test_support.h"

namespace chronomap {
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
  EXPECT_TRUE(back == asStored(m));
  EXPECT_EQ(back.pools().inner, m.pools().inner);
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
  h.version = 1;
  const auto bytes = encodeCmap(h, blocks);
  EXPECT_THROW(sessionMapFrom(decodeCmap(bytes, "crafted.cmap"), "crafted.cmap"), FormatError);
  h.kind = MapKind::Diff;
  EXPECT_THROW(sessionMapFrom(decodeCmap(encodeCmap(h, blocks), "d.cmap"), "d.cmap"), FormatError);
}

void putBlockHeader(std::vector<uint8_t>& frame, uint32_t header) {
  for (int i = 0; i < 3; ++i) frame.push_back(static_cast<uint8_t>(header >> (8 * i)));
}

/// A zstd frame (RFC 8878) whose header claims `content_bytes` but holds `raw_blocks` raw blocks
/// of 128 KiB and one RLE block of 128 KiB: magic, a descriptor (single segment, 8-byte content
/// size), the size, then each block's 3-byte header (last flag, type, size) and its bytes.
std::vector<uint8_t> zstdFrameClaiming(uint64_t content_bytes, int raw_blocks = 0) {
  std::vector<uint8_t> frame = {0x28, 0xb5, 0x2f, 0xfd, 0xe0};
  for (int i = 0; i < 8; ++i) frame.push_back(static_cast<uint8_t>(content_bytes >> (8 * i)));
  for (int b = 0; b < raw_blocks; ++b) {
    putBlockHeader(frame, 131072u << 3);
    frame.insert(frame.end(), 131072, 'r');
  }
  putBlockHeader(frame, 1u | (1u << 1) | (131072u << 3));
  frame.push_back('z');
  return frame;
}

/// A .cmap of one zstd block storing `frame` and claiming `raw_bytes` (checksums valid).
std::vector<uint8_t> cmapWithZstdBlock(const std::vector<uint8_t>& frame, uint64_t raw_bytes) {
  CmapHeader h;
  h.resolution_m = 0.05;
  std::vector<CmapBlock> blocks(1);
  blocks[0].tag = "META";
  blocks[0].data = frame;
  std::vector<uint8_t> bytes = encodeCmap(h, blocks, /*zstd_level=*/0);
  const uint32_t zstd = 1;
  std::memcpy(bytes.data() + 84 + 4, &zstd, 4);     // the block's codec
  std::memcpy(bytes.data() + 84 + 8, &raw_bytes, 8);  // its raw size (the stored CRC is unchanged)
  return bytes;
}

/// Decodes `bytes` in a child allowed 1 GiB more address space. @return 0 when refused with a
/// FormatError holding `message`, 1 when read, 2 for another message, 99 for bad_alloc.
int decodeUnderMemoryLimit(const std::vector<uint8_t>& bytes, const std::string& message) {
  return test::exitCodeUnderMemoryLimit(uint64_t{1} << 30, [&] {
    try {
      decodeCmap(bytes, "bomb.cmap");
      return 1;
    } catch (const FormatError& e) {
      return std::string(e.what()).find(message) != std::string::npos ? 0 : 2;
    }
  });
}

TEST(Cmap, RefusesZstdBlocksClaimingMoreThanTheyCanHold) {
  // 17 stored bytes whose block header and zstd frame both claim 32 GiB: refused before the claim
  // is allocated, by zstd's most expansion (before, the reader allocated 32 GiB).
  const uint64_t claimed = uint64_t{1} << 35;
  EXPECT_EQ(decodeUnderMemoryLimit(cmapWithZstdBlock(zstdFrameClaiming(claimed), claimed),
                                   "bomb.cmap: block 'META' claims 34359738368 bytes from 17 stored bytes"),
            0);
  // 256 KiB stored (two raw blocks) claiming 4 GiB, within that bound: the buffer follows what
  // the frame yields (384 KiB), not the claim, and the frame is refused once decoded.
  const uint64_t four_gib = uint64_t{4} << 30;
  EXPECT_EQ(decodeUnderMemoryLimit(cmapWithZstdBlock(zstdFrameClaiming(four_gib, 2), four_gib),
                                   "bomb.cmap: block 'META' cannot be decompressed"),
            0);
  // The same frames claiming their true size are read: the bounds leave real RLE blocks alone.
  const std::vector<uint8_t> truth = [] {
    std::vector<uint8_t> v(2 * 131072, 'r');
    v.insert(v.end(), 131072, 'z');
    return v;
  }();
  std::vector<uint8_t> bytes = cmapWithZstdBlock(zstdFrameClaiming(truth.size(), 2), truth.size());
  const uint32_t crc_raw = static_cast<uint32_t>(crc32(0, truth.data(), static_cast<uInt>(truth.size())));
  std::memcpy(bytes.data() + 84 + 28, &crc_raw, 4);
  EXPECT_EQ(decodeCmap(bytes, "rle.cmap").blocks.at(0).data, truth);
  // And so is what zstd itself writes for the most compressible data (96 MiB of zeros), which
  // also takes the path that grows the buffer (its first holds 64 MiB).
  CmapHeader h;
  h.resolution_m = 0.05;
  std::vector<CmapBlock> blocks(1);
  blocks[0].tag = "META";
  blocks[0].data.assign(size_t{96} << 20, 0);
  const std::vector<uint8_t> packed = encodeCmap(h, blocks, 3);
  EXPECT_GT(blocks[0].data.size() / packed.size(), 10000u) << "expected zstd near its maximum ratio";
  EXPECT_EQ(decodeCmap(packed, "zeros.cmap").blocks.at(0).data, blocks[0].data);
}

TEST(Cmap, FilesWithoutHitPositionsReadWithHitsAtTheCentres) {
  // Files written before the hit positions were kept have no HPOS block.
  const SessionMap m = sampleMap();
  CmapFile f = decodeCmap(encodeSessionMap(m, nullptr, 3, 1), "m.cmap");
  ASSERT_NE(f.find("HPOS"), nullptr);
  std::erase_if(f.blocks, [](const CmapBlock& b) { return b.tag == "HPOS"; });
  const SessionMap old = sessionMapFrom(decodeCmap(encodeCmap(f.header, f.blocks), "old.cmap"), "old.cmap");
  const std::vector<VoxelCounters> leaves = m.pools().leaves, old_leaves = old.pools().leaves;
  ASSERT_EQ(old_leaves.size(), leaves.size());
  size_t with_hits = 0;
  for (size_t i = 0; i < leaves.size(); ++i) {
    VoxelCounters expected = leaves[i];
    with_hits += expected.hits > 0 && expected.offset[0] != 0.0f;
    for (float& o : expected.offset) o = 0.0f;
    EXPECT_EQ(old_leaves[i], expected);
  }
  EXPECT_GT(with_hits, 100u) << "the sample map has positions to lose";
}

TEST(Cmap, RejectsImpossibleHitPositions) {
  const SessionMap m = sampleMap();
  const CmapFile f = decodeCmap(encodeSessionMap(m, nullptr, 3, 1), "m.cmap");
  // The first leaf with hits, and one without (format version 1 stores the sums as floats).
  const std::vector<VoxelCounters> leaves = m.pools().leaves;  // in the file's order
  size_t hit = 0, empty = 0;
  while (leaves[hit].hits == 0) ++hit;
  while (leaves[empty].hits != 0) ++empty;
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
  const float too_far = 0.51f * static_cast<float>(leaves[hit].hits);
  EXPECT_THROW(sessionMapFrom(withPositions([&](auto& d) { setFloat(d, hit * 12 + 4, too_far); }), "crafted.cmap"),
               FormatError);
  EXPECT_THROW(sessionMapFrom(withPositions([&](auto& d) { setFloat(d, empty * 12, 0.1f); }), "crafted.cmap"),
               FormatError)
      << "a position without hits";
}

/// A map of random counters: random keys in a 64-voxel cube, lengths of any magnitude, hit counts
/// up to 2000, colour sums up to 255 per hit, offsets anywhere in the voxel (the extremes
/// included), and a block of free space that compresses.
SessionMap randomCounters(uint32_t seed, double resolution_m) {
  SessionMap m(resolution_m);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> key(20000, 20063);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int i = 0; i < 1500; ++i) {
    VoxelCounters d;
    d.length_m = std::ldexp(unit(rng), static_cast<int>(rng() % 20) - 10);
    if (rng() % 2) {
      d.hits = 1 + static_cast<uint32_t>(rng() % 2000);
      for (uint32_t* c : {&d.red, &d.green, &d.blue}) *c = static_cast<uint32_t>(rng() % (255 * d.hits + 1));
      for (float& o : d.offset) {
        const uint32_t pick = rng() % 10;
        const float mean = pick == 0 ? -0.5f : pick == 1 ? 0.5f : unit(rng) - 0.5f;
        o = mean * static_cast<float>(d.hits);
      }
    }
    m.add({static_cast<uint16_t>(key(rng)), static_cast<uint16_t>(key(rng)), static_cast<uint16_t>(key(rng))}, d);
  }
  for (uint16_t x = 0; x < 16; ++x)
    for (uint16_t y = 0; y < 16; ++y)
      for (uint16_t z = 0; z < 4; ++z) {
        VoxelCounters f;
        f.length_m = 0.01f * static_cast<float>(1 + (x + y + z) % 5);
        m.add({static_cast<uint16_t>(21000 + x), static_cast<uint16_t>(21000 + y), static_cast<uint16_t>(21000 + z)}, f);
      }
  m.compressFree();
  return m;
}

TEST(Cmap, RandomMapsRoundTripWithinTheStatedBounds) {
  for (uint32_t seed = 1; seed <= 6; ++seed) {
    const double resolution_m = seed % 2 ? 0.05 : 0.02;
    const SessionMap m = randomCounters(seed, resolution_m);
    const std::vector<uint8_t> bytes = encodeSessionMap(m, {{"seed", seed}});
    const SessionMap back = sessionMapFrom(decodeCmap(bytes, "r.cmap"), "r.cmap");
    const SessionMap::Pools pm = m.pools(), pb = back.pools();
    ASSERT_EQ(pb.inner, pm.inner) << "seed " << seed;
    ASSERT_EQ(pb.leaves.size(), pm.leaves.size());
    double worst_m = 0.0, worst_length = 0.0;
    for (size_t i = 0; i < pm.leaves.size(); ++i) {
      const VoxelCounters& a = pm.leaves[i];
      const VoxelCounters& b = pb.leaves[i];
      ASSERT_EQ(b.hits, a.hits) << "leaf " << i << ": hits exact";
      EXPECT_EQ(b.meanColour(), a.meanColour()) << "leaf " << i << ": mean colour exact";
      EXPECT_EQ(b.state(), a.state()) << "leaf " << i << ": the state never changes";
      // Lengths within 2^-8 relative (kLengthRelativeError), so P within 2^-8 / e.
      const double relative = std::abs(double{b.length_m} / double{a.length_m} - 1.0);
      EXPECT_LE(relative, kLengthRelativeError) << "leaf " << i;
      EXPECT_LE(std::abs(b.probability() - a.probability()), kLengthRelativeError / std::exp(1.0) + 1e-9);
      worst_length = std::max(worst_length, relative);
      for (int axis = 0; axis < 3; ++axis) {
        // The mean hit position, in metres, within resolution / 256 of the one written.
        const double error_m = std::abs(a.meanOffset(axis) - b.meanOffset(axis)) * resolution_m;
        EXPECT_LE(error_m, resolution_m / 256) << "leaf " << i << " axis " << axis;
        // Tighter: half a quantisation step, with room for float rounding of the sums.
        EXPECT_LE(error_m, resolution_m * (kPositionStepVoxels / 2 + 1e-5)) << "leaf " << i << " axis " << axis;
        worst_m = std::max(worst_m, error_m);
      }
      EXPECT_TRUE(b.offsetsValid());
    }
    EXPECT_GT(worst_m, resolution_m / 2000) << "positions are quantised, not kept as floats";
    EXPECT_GT(worst_length, kLengthRelativeError / 8) << "lengths are quantised, not kept as floats";
    EXPECT_TRUE(back == asStored(m));
    // Quantising twice changes nothing: a map read and written again gives the same bytes.
    EXPECT_EQ(encodeSessionMap(back, {{"seed", seed}}), bytes);
    EXPECT_TRUE(asStored(back) == back);
  }
}

TEST(Cmap, QuantisedLengthsNeverChangeAVoxelsState) {
  // Lengths at and around P = 0.5 (length = hits / ln 2), tiny and huge lengths: the stored
  // length keeps the state, stays within the bound, and is its own quantisation.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> near(-1e-3, 1e-3);
  // The slow reference (normal floats): the nearest float with an 8-bit mantissa, then the
  // neighbour on the length's side when the state, computed with exp, differs.
  auto reference = [](const VoxelCounters& c) {
    const float step = std::ldexp(1.0f, std::ilogb(c.length_m) - 8);
    const float nearest = std::floor(c.length_m / step + 0.5f) * step;  // halves up, as the code's bits round
    VoxelCounters s = c;
    s.length_m = nearest;
    if (s.state() != c.state()) s.length_m = nearest > c.length_m ? nearest - step : nearest + step;
    return s.length_m;
  };
  size_t stepped = 0;
  for (int i = 0; i < 20000; ++i) {
    VoxelCounters c;
    c.hits = 1 + static_cast<uint32_t>(rng() % 100000);
    const double boundary = c.hits / std::log(2.0);
    float length = static_cast<float>(boundary * (1.0 + near(rng)));
    // Every float next to the boundary too, where rounding to nearest would cross it.
    if (i % 4 == 0) length = std::nextafter(static_cast<float>(boundary), i % 8 ? 0.0f : 1e30f);
    c.length_m = length;
    const VoxelCounters s = asStored(c);
    ASSERT_EQ(s.length_m, reference(c)) << c.hits << " hits, length " << length;
    ASSERT_EQ(s.state(), c.state()) << c.hits << " hits, length " << length;
    ASSERT_LE(std::abs(double{s.length_m} / double{length} - 1.0), kLengthRelativeError) << c.hits << " " << length;
    ASSERT_EQ(asStored(s).length_m, s.length_m);
    stepped += std::abs(double{s.length_m} / double{length} - 1.0) > kLengthRelativeError / 2;
  }
  EXPECT_GT(stepped, 0u) << "some lengths were moved off their nearest code to keep their state";
  for (float length : {std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::min(), 1e-30f,
                       std::numeric_limits<float>::max(), 3e38f}) {
    for (uint32_t hits : {0u, 1u, 1000u}) {
      VoxelCounters c;
      c.length_m = length;
      c.hits = hits;
      const VoxelCounters s = asStored(c);
      EXPECT_EQ(s.state(), c.state()) << length << " " << hits;
      EXPECT_TRUE(std::isfinite(s.length_m) && s.length_m > 0.0f) << length;
      EXPECT_EQ(asStored(s).length_m, s.length_m);
    }
  }
  VoxelCounters zero;
  zero.hits = 3;
  EXPECT_EQ(asStored(zero).length_m, 0.0f);
}

TEST(Cmap, VersionTwoFilesStillReadExactly) {
  // Version 2 kept lengths and colour sums bit for bit; its files read so.
  const SessionMap m = randomCounters(12, 0.05);
  const std::vector<uint8_t> two = encodeSessionMap(m, nullptr, 3, 2);
  const CmapFile f = decodeCmap(two, "two.cmap");
  EXPECT_EQ(f.header.version, 2u);
  ASSERT_NE(f.find("CRES"), nullptr);
  const SessionMap back = sessionMapFrom(f, "two.cmap");
  const SessionMap::Pools pm = m.pools(), pb = back.pools();
  ASSERT_EQ(pb.leaves.size(), pm.leaves.size());
  for (size_t i = 0; i < pm.leaves.size(); ++i) {
    const VoxelCounters& a = pm.leaves[i];
    const VoxelCounters& b = pb.leaves[i];
    ASSERT_EQ(std::memcmp(&a, &b, offsetof(VoxelCounters, offset)), 0) << "leaf " << i << ": length, hits, colour exact";
  }
  // Written again, it takes the current version, smaller, quantised once.
  const std::vector<uint8_t> now = encodeSessionMap(back, nullptr);
  EXPECT_EQ(decodeCmap(now, "now.cmap").header.version, kCmapFormatVersion);
  EXPECT_LT(now.size(), two.size());
  EXPECT_TRUE(sessionMapFrom(decodeCmap(now, "now.cmap"), "now.cmap") == asStored(m));
}

TEST(Cmap, HitsAtTheCentreStayThereExactly) {
  // Maps made without positions (every hit at its voxel's centre) keep their positions bit for
  // bit (lengths and colour sums as asStored).
  SessionMap m = randomCounters(7, 0.05);
  SessionMap::Pools pools = m.pools();
  for (VoxelCounters& c : pools.leaves) c.offset[0] = c.offset[1] = c.offset[2] = 0.0f;
  m.assignPools(std::move(pools.inner), std::move(pools.leaves));
  const SessionMap back = sessionMapFrom(decodeCmap(encodeSessionMap(m, nullptr), "c.cmap"), "c.cmap");
  EXPECT_EQ(back.pools().leaves, asStored(m).pools().leaves);
  for (const VoxelCounters& c : back.pools().leaves) {
    EXPECT_TRUE(c.offset[0] == 0.0f && c.offset[1] == 0.0f && c.offset[2] == 0.0f);
  }
}

TEST(Cmap, VersionOneFilesStillReadExactly) {
  // Written by the previous format's writer (pools and float records as they lie in memory).
  const SessionMap m = randomCounters(11, 0.05);
  const std::vector<uint8_t> old = encodeSessionMap(m, {{"old", true}}, 3, 1);
  const CmapFile f = decodeCmap(old, "old.cmap");
  EXPECT_EQ(f.header.version, 1u);
  ASSERT_NE(f.find("INNR"), nullptr);
  const SessionMap back = sessionMapFrom(f, "old.cmap");
  EXPECT_EQ(back.innerPool(), m.innerPool());
  EXPECT_EQ(back.pools().leaves, m.pools().leaves) << "version 1 keeps positions as floats";
  EXPECT_EQ(metadataOf(f)["old"], true);
  // Written again, it takes the current version, smaller even for these random counters.
  const std::vector<uint8_t> now = encodeSessionMap(back, {{"old", true}});
  EXPECT_EQ(decodeCmap(now, "new.cmap").header.version, kCmapFormatVersion);
  EXPECT_LT(now.size(), old.size());
}

void craftedBlocksGiveOneClearError(uint32_t version) {
  SCOPED_TRACE("version " + std::to_string(version));
  const SessionMap m = randomCounters(5, 0.05);
  const CmapFile f = decodeCmap(encodeSessionMap(m, nullptr, 3, version), "m.cmap");
  auto readWith = [&](const std::string& tag, auto&& mutate) {
    CmapFile g = f;
    for (CmapBlock& b : g.blocks) {
      if (b.tag == tag) mutate(b.data);
    }
    return sessionMapFrom(decodeCmap(encodeCmap(g.header, g.blocks), "crafted.cmap"), "crafted.cmap");
  };
  auto expectError = [&](const std::string& tag, auto&& mutate, const std::string& what) {
    try {
      readWith(tag, mutate);
      ADD_FAILURE() << tag << ": " << what << " was read";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("crafted.cmap"), std::string::npos) << e.what();
    }
  };
  if (version == 3) {
    EXPECT_TRUE(readWith("META", [](auto&) {}) == asStored(m));
  }
  const std::vector<const char*> tags =
      version == 2 ? std::vector<const char*>{"TMSK", "TREF", "CLEN", "CHIT", "CRGB", "CRES", "CPOS"}
                   : std::vector<const char*>{"TMSK", "TREF", "QLEN", "PHIT", "CRGB", "CPOS"};
  for (const char* tag : tags) {
    expectError(tag, [](std::vector<uint8_t>& d) { d.pop_back(); }, "a block one byte short");
    expectError(tag, [](std::vector<uint8_t>& d) { d.push_back(0); }, "a block one byte long");
    expectError(tag, [](std::vector<uint8_t>& d) { d.clear(); }, "an empty block");
    CmapFile g = f;
    std::erase_if(g.blocks, [&](const CmapBlock& b) { return b.tag == tag; });
    EXPECT_THROW(sessionMapFrom(decodeCmap(encodeCmap(g.header, g.blocks), "crafted.cmap"), "crafted.cmap"), FormatError)
        << "without " << tag;
  }
  // A block the version does not have (a damaged tag: no checksum covers the tags), or twice.
  for (const char* change : {"rename", "twice"}) {
    CmapFile g = f;
    if (std::string(change) == "rename") {
      g.blocks[0].tag = "MEUA";
    } else {
      g.blocks.push_back(g.blocks[0]);
    }
    try {
      sessionMapFrom(decodeCmap(encodeCmap(g.header, g.blocks), "crafted.cmap"), "crafted.cmap");
      ADD_FAILURE() << change << " was read";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("crafted.cmap"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(std::string(change) == "rename" ? "'MEUA' is not part" : "more than one"),
                std::string::npos)
          << e.what();
    }
  }
  expectError("CPOS", [](std::vector<uint8_t>& d) { d[0] = 255; }, "a position code past 254");
  // References out of range, repeated, or past what a number can hold.
  expectError("TREF", [](std::vector<uint8_t>& d) { d[0] = 0x7e; }, "a reference past the pools");
  expectError("TREF", [](std::vector<uint8_t>& d) { d.assign(d.size(), 0xff); }, "an overlong number");
  // A child marked as a leaf that is not there, and an inner node at unit level.
  expectError("TMSK", [](std::vector<uint8_t>& d) { d[1] = static_cast<uint8_t>(~d[0]); }, "a leaf mask beyond the children");
  expectError("TMSK", [](std::vector<uint8_t>& d) { d.assign(d.size(), 0xff); }, "every slot filled");
  // Hit counts that change which records have colours and positions, lengths that are not
  // lengths, colour sums beyond 32 bits.
  if (version == 3) {
    expectError("PHIT", [](std::vector<uint8_t>& d) { d[0] ^= 1; }, "one hit record more or less");
    expectError("QLEN", [](std::vector<uint8_t>& d) { d[d.size() / 2] = 0xff; }, "an infinite or NaN length");
    const size_t n = m.leafCount();
    expectError("PHIT", [n](std::vector<uint8_t>& d) { d[(n + 7) / 8 - 1] |= 0x80; }, "a record past the last flagged");
    expectError("PHIT", [n](std::vector<uint8_t>& d) {
      const size_t m4 = (d.size() - (n + 7) / 8) / 4;
      for (int b = 0; b < 4; ++b) d[(n + 7) / 8 + b * m4] = 0;
    }, "a flagged record without hits");
    return;
  }
  expectError("CHIT", [](std::vector<uint8_t>& d) { d[0] = d[0] == 0 ? 1 : 0; }, "one hit record more or less");
  expectError("CLEN", [](std::vector<uint8_t>& d) { d[3 * d.size() / 4] = 0xff; }, "a negative NaN length");
  expectError("CRES", [](std::vector<uint8_t>& d) {
    d.insert(d.begin(), {0xfe, 0xff, 0xff, 0xff, 0x7f});
    d.pop_back();
  }, "a colour sum beyond 32 bits");
}

TEST(Cmap, CraftedVersionTwoAndThreeBlocksGiveOneClearError) {
  for (uint32_t version : {2u, 3u}) craftedBlocksGiveOneClearError(version);
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

// A diff file's settings are checked as it is read: the shift test's plane ratio out of [0, 1],
// of another type or null is a corrupt file; a file written before the ratio existed reads 0.
TEST(DiffFile, ShiftPlaneRatioOutOfRangeIsRefused) {
  test::TempDir tmp;
  SessionMap before(0.05), after(0.05);
  VoxelCounters free_voxel, hit;
  free_voxel.length_m = 0.05f;
  hit.length_m = 0.05f;
  hit.hits = 4;
  before.add({32768, 32768, 32768}, free_voxel);
  after.add({32768, 32768, 32768}, hit);
  DiffSettings s;
  s.neighbourhood_voxels = 1;
  s.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  s.shift_plane_ratio = DiffSettings::kRecommendedShiftPlaneRatio;
  writeDiffMap(tmp / "d.cmap", diff(before, after, s), nlohmann::json::object());
  ASSERT_EQ(readDiffMap(tmp / "d.cmap").settings().shift_plane_ratio, DiffSettings::kRecommendedShiftPlaneRatio);
  const CmapFile file = decodeCmap(readFileBytes(tmp / "d.cmap"), "x.cmap");
  auto withMeta = [&](auto&& mutate) {
    CmapFile f = file;
    size_t found = 0;
    for (CmapBlock& b : f.blocks) {
      if (b.tag != "META") continue;
      nlohmann::json j = nlohmann::json::parse(b.data.begin(), b.data.end());
      mutate(j);
      const std::string text = j.dump();
      b.data.assign(text.begin(), text.end());
      ++found;
    }
    EXPECT_EQ(found, 1u);
    return f;
  };
  EXPECT_EQ(diffMapFrom(withMeta([](nlohmann::json& j) { j.erase("shift_plane_ratio"); }), "x.cmap")
                .settings()
                .shift_plane_ratio,
            0.0)
      << "written before the ratio: the whole move";
  for (const nlohmann::json& bad : {nlohmann::json(1.5), nlohmann::json(-0.1), nlohmann::json("0.15"), nlohmann::json()}) {
    try {
      diffMapFrom(withMeta([&](nlohmann::json& j) { j["shift_plane_ratio"] = bad; }), "x.cmap");
      ADD_FAILURE() << bad.dump() << " was read";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("x.cmap: invalid diff settings"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace chronomap
