#include "chronomap/store/cmap.h"

#include <zlib.h>
#include <zstd.h>
#include <zstd_errors.h>

#include <bit>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <type_traits>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/octree/voxel_queries.h"
#include "columns.h"

namespace chronomap {

static_assert(std::endian::native == std::endian::little, "the .cmap writer assumes a little-endian host");
static_assert(SessionMap::kLeafBit == columns::kLeafBit && SessionMap::kEmpty == columns::kEmptyRef &&
                  std::is_same_v<SessionMap::Children, columns::Children>,
              "version 2 stores session map references as the column codec's");

namespace {

constexpr uint8_t kMagic[8] = {0x89, 'C', 'M', 'A', 'P', '\r', '\n', 0x1a};
constexpr size_t kHeaderBytes = 84;
constexpr size_t kBlockHeaderBytes = 32;
/// An append record: a block header, a CRC-32 of that header, then the stored bytes.
constexpr size_t kRecordHeaderBytes = kBlockHeaderBytes + 4;
constexpr uint32_t kCodecRaw = 0;
constexpr uint32_t kCodecZstd = 1;
/// Largest block a reader will inflate; guards against absurd sizes in crafted files.
constexpr uint64_t kMaxRawBlockBytes = uint64_t{1} << 36;
/// The most zstd can expand, from its format (RFC 8878): a frame is a header of at least 6 bytes
/// and blocks; every block has a 3-byte header and yields at most Block_Maximum_Size, 128 KiB.
/// The block yielding the most per stored byte is an RLE block: its header and one byte, 4 bytes
/// for up to 128 KiB (a compressed block needs at least 5 bytes: its header, a literals header
/// and a sequence count; a raw block yields its own size; skippable frames yield nothing). So n
/// stored bytes decode to at most n / 4 * 131072 = 32768 n bytes: a block claiming more is
/// crafted, and is refused before its claimed size is allocated. No valid block is refused.
constexpr uint64_t kMaxZstdRatio = (uint64_t{128} << 10) / 4;

uint32_t crc(const uint8_t* data, size_t n) {
  uLong c = crc32(0L, Z_NULL, 0);
  while (n > 0) {
    const uInt chunk = static_cast<uInt>(std::min<size_t>(n, 1u << 30));
    c = crc32(c, data, chunk);
    data += chunk;
    n -= chunk;
  }
  return static_cast<uint32_t>(c);
}

template <class T>
void put(std::vector<uint8_t>& out, const T& v) {
  const auto* p = reinterpret_cast<const uint8_t*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

/// memcpy that accepts empty ranges (memcpy's pointers must not be null even for size 0).
void copyBytes(void* dst, const void* src, size_t n) {
  if (n > 0) std::memcpy(dst, src, n);
}

template <class T>
T get(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

/// Appends one block (32-byte header, then its stored bytes) to `out`; with `header_crc` the
/// header is followed by a CRC-32 of itself (append records, docs/file-format.md).
void appendBlock(std::vector<uint8_t>& out, const CmapBlock& b, int zstd_level, bool header_crc = false) {
  if (b.tag.size() != 4) throw UsageError("cmap block tags have four characters");
  std::vector<uint8_t> stored;
  uint32_t codec = kCodecRaw;
  if (zstd_level > 0 && !b.data.empty()) {
    stored.resize(ZSTD_compressBound(b.data.size()));
    const size_t n = ZSTD_compress(stored.data(), stored.size(), b.data.data(), b.data.size(), zstd_level);
    if (ZSTD_isError(n)) throw Error(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
    stored.resize(n);
    codec = kCodecZstd;
  } else {
    stored = b.data;
  }
  const size_t start = out.size();
  out.insert(out.end(), b.tag.begin(), b.tag.end());
  put(out, codec);
  put(out, static_cast<uint64_t>(b.data.size()));
  put(out, static_cast<uint64_t>(stored.size()));
  put(out, crc(stored.data(), stored.size()));
  put(out, crc(b.data.data(), b.data.size()));
  if (header_crc) put(out, crc(out.data() + start, kBlockHeaderBytes));
  out.insert(out.end(), stored.begin(), stored.end());
}

/// The fields of a block header.
struct BlockHeader {
  std::string tag;
  uint32_t codec = 0;
  uint64_t raw_size = 0, stored_size = 0;
  uint32_t crc_stored = 0, crc_raw = 0;
};

BlockHeader blockHeaderAt(const uint8_t* p) {
  BlockHeader h;
  h.tag.assign(reinterpret_cast<const char*>(p), 4);
  h.codec = get<uint32_t>(p + 4);
  h.raw_size = get<uint64_t>(p + 8);
  h.stored_size = get<uint64_t>(p + 16);
  h.crc_stored = get<uint32_t>(p + 24);
  h.crc_raw = get<uint32_t>(p + 28);
  return h;
}

std::string zstdBombMessage(const BlockHeader& h, const std::string& what) {
  std::ostringstream msg;
  msg << what << " claims " << h.raw_size << " bytes from " << h.stored_size
      << " stored bytes, more than zstd can expand to (" << kMaxZstdRatio << ":1); the file is crafted or damaged";
  return msg.str();
}

/// A block may claim up to kMaxZstdRatio times its stored size, and a real one can be that
/// dense, so the claim alone cannot tell a bomb. Memory follows what the data really yields: the
/// first buffer holds the claim up to 64 times the stored size (or 64 MiB), more than real map
/// blocks expand; a block that fills it is decoded again into a buffer four times larger, up to
/// its claim, so a false claim costs at most four times what the block truly holds (and 4/3 of
/// the decoding work).
constexpr uint64_t kFirstZstdRatio = 64;
constexpr uint64_t kFirstZstdBytes = uint64_t{64} << 20;

std::vector<uint8_t> inflateZstd(const BlockHeader& h, const uint8_t* p, const std::string& what) {
  std::vector<uint8_t> out;
  uint64_t capacity = std::min(h.raw_size, std::max(kFirstZstdBytes, kFirstZstdRatio * h.stored_size));
  while (true) {
    out.resize(capacity);
    const size_t n = ZSTD_decompress(out.data(), out.size(), p, h.stored_size);
    const bool too_small = ZSTD_isError(n) && ZSTD_getErrorCode(n) == ZSTD_error_dstSize_tooSmall;
    if (too_small && capacity < h.raw_size) {
      capacity = std::min(h.raw_size, 4 * capacity);
      continue;
    }
    if (ZSTD_isError(n) || n != h.raw_size) throw FormatError(what + " cannot be decompressed");
    return out;
  }
}

/// Checks and inflates the stored bytes of a block whose header is `h` (all present at `p`).
CmapBlock decodeBlock(const BlockHeader& h, const uint8_t* p, const std::string& what) {
  CmapBlock b;
  b.tag = h.tag;
  if (crc(p, h.stored_size) != h.crc_stored) throw FormatError(what + " is corrupt (checksum mismatch)");
  if (h.raw_size > kMaxRawBlockBytes) throw FormatError(what + " claims an impossible size");
  if (h.codec == kCodecRaw) {
    if (h.raw_size != h.stored_size) throw FormatError(what + " has inconsistent sizes");
    b.data.assign(p, p + h.stored_size);
  } else if (h.codec == kCodecZstd) {
    const unsigned long long content = ZSTD_getFrameContentSize(p, h.stored_size);
    if (content != h.raw_size) throw FormatError(what + " has inconsistent sizes");
    if (h.raw_size / kMaxZstdRatio > h.stored_size) throw FormatError(zstdBombMessage(h, what));
    b.data = inflateZstd(h, p, what);
  } else {
    throw FormatError(what + " uses unknown compression " + std::to_string(h.codec));
  }
  if (crc(b.data.data(), b.data.size()) != h.crc_raw) throw FormatError(what + " is corrupt (checksum mismatch)");
  return b;
}

}  // namespace

const char* toString(MapKind kind) {
  switch (kind) {
    case MapKind::Session: return "session";
    case MapKind::Temporal: return "4d";
    case MapKind::Diff: return "diff";
    case MapKind::Tiled: return "tiled";
  }
  return "unknown";
}

const char* kindName(MapKind kind) { return kind == MapKind::Temporal ? "4D" : toString(kind); }

const CmapBlock* CmapFile::find(const std::string& tag) const {
  for (const auto& b : blocks) {
    if (b.tag == tag) return &b;
  }
  return nullptr;
}

void putCounterRecord(uint8_t* out, const VoxelCounters& c) {
  copyBytes(out, &c.length_m, 4);
  copyBytes(out + 4, &c.hits, 4);
  copyBytes(out + 8, &c.red, 4);
  copyBytes(out + 12, &c.green, 4);
  copyBytes(out + 16, &c.blue, 4);
}

void getCounterRecord(const uint8_t* in, VoxelCounters& c) {
  copyBytes(&c.length_m, in, 4);
  copyBytes(&c.hits, in + 4, 4);
  copyBytes(&c.red, in + 8, 4);
  copyBytes(&c.green, in + 12, 4);
  copyBytes(&c.blue, in + 16, 4);
}

void putOffsetRecord(uint8_t* out, const VoxelCounters& c) { copyBytes(out, c.offset, kOffsetRecordBytes); }

void getOffsetRecord(const uint8_t* in, VoxelCounters& c) { copyBytes(c.offset, in, kOffsetRecordBytes); }

const CmapBlock* offsetBlock(const CmapFile& file, const std::string& tag, size_t records, const std::string& what) {
  const CmapBlock* b = file.find(tag);
  if (b && b->data.size() != records * kOffsetRecordBytes) {
    throw FormatError(what + ": the hit position block " + tag + " does not match its records");
  }
  return b;
}

const CmapBlock& CmapFile::block(const std::string& tag, const std::string& source) const {
  if (const CmapBlock* b = find(tag)) return *b;
  throw FormatError(source + ": the file has no '" + tag + "' block");
}

std::vector<uint8_t> encodeCmap(const CmapHeader& header, const std::vector<CmapBlock>& blocks, int zstd_level) {
  std::vector<uint8_t> out(kMagic, kMagic + 8);
  put(out, header.version);
  put(out, static_cast<uint32_t>(header.kind));
  put(out, header.resolution_m);
  for (int a = 0; a < 3; ++a) put(out, header.bounds_min_m[a]);
  for (int a = 0; a < 3; ++a) put(out, header.bounds_max_m[a]);
  put(out, header.tree_depth);
  put(out, static_cast<uint32_t>(blocks.size()));
  put(out, crc(out.data(), out.size()));
  for (const CmapBlock& b : blocks) appendBlock(out, b, zstd_level);
  return out;
}

CmapFile decodeCmap(const std::vector<uint8_t>& bytes, const std::string& source) {
  if (bytes.empty()) throw FormatError(source + ": the file is empty");
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kMagic, 8) != 0) {
    throw FormatError(source + ": not a chronomap map (wrong magic bytes)");
  }
  if (bytes.size() < kHeaderBytes) throw FormatError(source + ": the file is truncated (incomplete header)");
  CmapFile f;
  f.file_bytes = bytes.size();
  const uint8_t* p = bytes.data();
  f.header.version = get<uint32_t>(p + 8);
  if (f.header.version > kCmapFormatVersion) {
    throw FormatError(source + ": written by a newer chronomap (format version " + std::to_string(f.header.version) +
                      "; this build reads up to " + std::to_string(kCmapFormatVersion) + ")");
  }
  if (f.header.version == 0) throw FormatError(source + ": invalid format version 0");
  if (crc(p, kHeaderBytes - 4) != get<uint32_t>(p + kHeaderBytes - 4)) {
    throw FormatError(source + ": the header is corrupt (checksum mismatch)");
  }
  const uint32_t kind = get<uint32_t>(p + 12);
  if (kind < 1 || kind > 4) throw FormatError(source + ": unknown map kind " + std::to_string(kind));
  f.header.kind = static_cast<MapKind>(kind);
  f.header.resolution_m = get<double>(p + 16);
  for (int a = 0; a < 3; ++a) f.header.bounds_min_m[a] = get<double>(p + 24 + 8 * a);
  for (int a = 0; a < 3; ++a) f.header.bounds_max_m[a] = get<double>(p + 48 + 8 * a);
  f.header.tree_depth = get<uint32_t>(p + 72);
  const uint32_t nblocks = get<uint32_t>(p + 76);
  if (!(f.header.resolution_m > 0.0) || !std::isfinite(f.header.resolution_m)) {
    throw FormatError(source + ": invalid resolution in header");
  }
  if (f.header.tree_depth != static_cast<uint32_t>(kTreeDepth)) {
    throw FormatError(source + ": unsupported tree depth " + std::to_string(f.header.tree_depth));
  }
  size_t pos = kHeaderBytes;
  for (uint32_t i = 0; i < nblocks; ++i) {
    if (bytes.size() - pos < kBlockHeaderBytes) {
      throw FormatError(source + ": the file is truncated (block " + std::to_string(i + 1) + " of " +
                        std::to_string(nblocks) + " missing)");
    }
    const BlockHeader h = blockHeaderAt(p + pos);
    pos += kBlockHeaderBytes;
    const std::string what = source + ": block '" + h.tag + "'";
    if (h.stored_size > bytes.size() - pos) throw FormatError(what + " is truncated");
    f.blocks.push_back(decodeBlock(h, p + pos, what));
    pos += h.stored_size;
  }
  f.base_bytes = pos;
  // Append records (4D maps only): each complete one is checked like a block; the file may end
  // inside the last one (an append that was interrupted), which is then not part of the map.
  if (f.header.kind == MapKind::Temporal) {
    while (pos < bytes.size()) {
      const size_t left = bytes.size() - pos;
      const std::string what = source + ": appended record " + std::to_string(f.appended.size() + 1);
      if (left < kRecordHeaderBytes) break;
      if (crc(p + pos, kBlockHeaderBytes) != get<uint32_t>(p + pos + kBlockHeaderBytes)) {
        throw FormatError(what + " is corrupt (header checksum mismatch)");
      }
      const BlockHeader h = blockHeaderAt(p + pos);
      if (h.stored_size > left - kRecordHeaderBytes) break;
      f.appended.push_back(decodeBlock(h, p + pos + kRecordHeaderBytes, what));
      pos += kRecordHeaderBytes + h.stored_size;
    }
    f.incomplete_tail_bytes = bytes.size() - pos;
  } else if (pos != bytes.size()) {
    throw FormatError(source + ": unexpected bytes after the last block");
  }
  f.complete_bytes = pos;
  return f;
}

std::vector<uint8_t> encodeAppendRecord(const CmapBlock& record, int zstd_level) {
  std::vector<uint8_t> out;
  appendBlock(out, record, zstd_level, /*header_crc=*/true);
  return out;
}

CmapFile readCmap(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return decodeCmap(readFileBytes(path), path.string()); });
}

std::vector<uint8_t> encodeSessionMap(const SessionMap& map, const nlohmann::json& meta, int zstd_level,
                                      uint32_t version) {
  if (version < 1 || version > kCmapFormatVersion) {
    throw UsageError("session maps are written in format version 1, 2 or 3");
  }
  CmapHeader header;
  header.kind = MapKind::Session;
  header.resolution_m = map.resolution_m();
  if (const auto bounds = knownBounds(map)) {
    header.bounds_min_m = bounds->min_m;
    header.bounds_max_m = bounds->max_m;
  }
  std::vector<CmapBlock> blocks(1);
  blocks[0].tag = "META";
  const std::string text = meta.is_null() ? "{}" : meta.dump();
  blocks[0].data.assign(text.begin(), text.end());
  // Depth first, whatever the layout in memory (a map's free leaves have a pool of their own).
  const SessionMap::Pools pools = map.pools();
  const auto& leaves = pools.leaves;
  if (version == 1) {
    header.version = 1;
    const auto& inner = pools.inner;
    CmapBlock& tree = blocks.emplace_back(CmapBlock{"INNR", std::vector<uint8_t>(inner.size() * sizeof(SessionMap::Children))});
    copyBytes(tree.data.data(), inner.data(), tree.data.size());
    CmapBlock counters{"LEAF", std::vector<uint8_t>(leaves.size() * kCounterRecordBytes)};
    CmapBlock positions{"HPOS", std::vector<uint8_t>(leaves.size() * kOffsetRecordBytes)};
    for (size_t i = 0; i < leaves.size(); ++i) {
      putCounterRecord(counters.data.data() + i * kCounterRecordBytes, leaves[i]);
      putOffsetRecord(positions.data.data() + i * kOffsetRecordBytes, leaves[i]);
    }
    blocks.push_back(std::move(counters));
    blocks.push_back(std::move(positions));
    return encodeCmap(header, blocks, zstd_level);
  }
  header.version = version;
  columns::encodeTree(pools.inner, blocks);
  columns::encodeCounters(leaves.size(), [&](size_t i) -> const VoxelCounters& { return leaves[i]; }, blocks, version);
  return encodeCmap(header, blocks, zstd_level);
}

void writeSessionMap(const std::filesystem::path& path, const SessionMap& map, const nlohmann::json& meta) {
  writeFileAtomic(path, encodeSessionMap(map, meta));
}

namespace {

/// The pools of a version 1 session map: INNR, LEAF and the optional HPOS.
void poolsOfVersion1(const CmapFile& file, const std::string& source, std::vector<SessionMap::Children>& inner,
                     std::vector<VoxelCounters>& leaves) {
  const CmapBlock& inner_block = file.block("INNR", source);
  const CmapBlock& leaf_block = file.block("LEAF", source);
  if (inner_block.data.size() % sizeof(SessionMap::Children) != 0 || leaf_block.data.size() % kCounterRecordBytes != 0) {
    throw FormatError(source + ": node blocks have impossible sizes");
  }
  inner.resize(inner_block.data.size() / sizeof(SessionMap::Children));
  copyBytes(inner.data(), inner_block.data.data(), inner_block.data.size());
  leaves.resize(leaf_block.data.size() / kCounterRecordBytes);
  for (size_t i = 0; i < leaves.size(); ++i) getCounterRecord(leaf_block.data.data() + i * kCounterRecordBytes, leaves[i]);
  // Hit positions: absent in files written before them (then every surface sits at its centre).
  if (const CmapBlock* positions = offsetBlock(file, "HPOS", leaves.size(), source)) {
    for (size_t i = 0; i < leaves.size(); ++i) getOffsetRecord(positions->data.data() + i * kOffsetRecordBytes, leaves[i]);
  }
}

}  // namespace

SessionMap sessionMapFrom(const CmapFile& file, const std::string& source) {
  if (file.header.kind != MapKind::Session) {
    // A 4D map where one state is wanted: say how to take one.
    const std::string hint = file.header.kind == MapKind::Temporal
                                 ? " (one time of it: chronomap snapshot MAP --at TIME -o SESSION.cmap)"
                                 : "";
    throw FormatError(source + ": holds a " + std::string(kindName(file.header.kind)) + " map, not a session map" + hint);
  }
  std::vector<SessionMap::Children> inner;
  std::vector<VoxelCounters> leaves;
  if (file.header.version == 1) {
    poolsOfVersion1(file, source, inner, leaves);
  } else {
    columns::requireExactly(
        file, source,
        columns::withCounterTags(file.header.version, {"META", columns::kTreeMasks, columns::kTreeRefs}, {}));
    size_t n = 0;
    inner = columns::decodeTree(file, source, n);
    leaves.resize(n);
    columns::decodeCounters(file, source, n, [&](size_t i) -> VoxelCounters& { return leaves[i]; });
  }
  SessionMap map(file.header.resolution_m);
  try {
    map.assignPools(std::move(inner), std::move(leaves));
  } catch (const FormatError& e) {
    throw FormatError(source + ": " + e.what());
  }
  return map;
}

VoxelCounters asStored(const VoxelCounters& c) {
  VoxelCounters out = c;
  out.length_m = columns::dequantiseLength(columns::quantiseLength(c.length_m, c.hits));
  out.red = columns::storedColourSum(c.red, c.hits);
  out.green = columns::storedColourSum(c.green, c.hits);
  out.blue = columns::storedColourSum(c.blue, c.hits);
  for (int a = 0; a < 3; ++a) {
    out.offset[a] = c.hits > 0 ? columns::dequantiseOffset(columns::quantiseOffset(c.offset[a], c.hits), c.hits) : 0.0f;
  }
  return out;
}

SessionMap asStored(const SessionMap& map) {
  SessionMap::Pools pools = map.pools();
  for (VoxelCounters& c : pools.leaves) c = asStored(c);
  SessionMap out(map.resolution_m());
  out.assignPools(std::move(pools.inner), std::move(pools.leaves));
  return out;
}

SessionMap readSessionMap(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return sessionMapFrom(readCmap(path), path.string()); });
}

nlohmann::json metadataOf(const CmapFile& file) {
  for (const auto& b : file.blocks) {
    if (b.tag == "META") {
      auto j = nlohmann::json::parse(b.data.begin(), b.data.end(), nullptr, false);
      if (!j.is_discarded() && j.is_object()) return j;
    }
  }
  return nlohmann::json::object();
}

}  // namespace chronomap
