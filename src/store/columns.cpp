#include "columns.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "chronomap/core/error.h"
#include "chronomap/core/key.h"

namespace chronomap::columns {

uint64_t ByteReader::varint() {
  uint64_t v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (p_ == end_) fail("is truncated");
    const uint8_t b = *p_++;
    v |= static_cast<uint64_t>(b & 0x7f) << shift;
    if ((b & 0x80) == 0) return v;
  }
  fail("has an overlong number");
}

uint8_t ByteReader::byte() {
  if (p_ == end_) fail("is truncated");
  return *p_++;
}

void ByteReader::expectEnd() const {
  if (p_ != end_) fail("has bytes left over");
}

void ByteReader::fail(const std::string& problem) const { throw FormatError(what_ + " " + problem); }

namespace {

std::string blockName(const std::string& source, const char* tag) { return source + ": block '" + tag + "'"; }

/// Larger than any pool index or colour sum a valid file holds, small enough that adding two
/// cannot overflow: decoded numbers beyond it are refused before any arithmetic.
constexpr int64_t kMaxDelta = int64_t{1} << 40;
constexpr int64_t kMaxResidual = int64_t{1} << 40;

/// Level of the children of a node at `level`.
int childLevel(int level) { return level - 1; }

}  // namespace

void encodeTree(const std::vector<Children>& inner, std::vector<CmapBlock>& blocks) {
  ByteWriter masks, refs;
  // Previous index of each kind in visit order; the root (inner 0) counts as visited.
  int64_t prev_inner = 0, prev_leaf = -1;
  struct Frame {
    uint32_t node;
    int level;
    int slot;
  };
  std::vector<Frame> stack;
  auto enter = [&](uint32_t node, int level) {
    const Children& c = inner[node];
    uint8_t present = 0, leaf = 0;
    for (int i = 0; i < 8; ++i) {
      if (c[i] == kEmptyRef) continue;
      present |= static_cast<uint8_t>(1u << i);
      if (c[i] & kLeafBit) leaf |= static_cast<uint8_t>(1u << i);
    }
    masks.byte(present);
    if (level > 1) masks.byte(leaf);  // at level 1 every child is a unit leaf
    stack.push_back({node, level, 0});
  };
  if (!inner.empty()) enter(0, kTreeDepth);
  while (!stack.empty()) {
    Frame& f = stack.back();
    if (f.slot == 8) {
      stack.pop_back();
      continue;
    }
    const uint32_t r = inner[f.node][f.slot++];
    if (r == kEmptyRef) continue;
    if (r & kLeafBit) {
      const int64_t i = r & ~kLeafBit;
      refs.svarint(i - (prev_leaf + 1));
      prev_leaf = i;
    } else {
      refs.svarint(static_cast<int64_t>(r) - (prev_inner + 1));
      prev_inner = r;
      enter(r, childLevel(f.level));  // invalidates f
    }
  }
  blocks.push_back({kTreeMasks, std::move(masks.bytes())});
  blocks.push_back({kTreeRefs, std::move(refs.bytes())});
}

std::vector<Children> decodeTree(const CmapFile& file, const std::string& source, size_t& leaves) {
  const CmapBlock& mask_block = file.block(kTreeMasks, source);
  const CmapBlock& ref_block = file.block(kTreeRefs, source);
  ByteReader masks(mask_block.data, blockName(source, kTreeMasks));
  ByteReader refs(ref_block.data, blockName(source, kTreeRefs));
  auto fail = [&](const std::string& problem) { throw FormatError(source + ": the tree " + problem); };
  if (mask_block.data.empty()) fail("has no root node");
  // Each inner node takes at least one mask byte and each child at least one reference byte, so
  // the block sizes bound the pools: a crafted file cannot make the reader allocate more.
  std::vector<uint8_t> inner_seen(mask_block.data.size(), 0), leaf_seen(ref_block.data.size(), 0);
  std::vector<Children> inner;
  size_t inner_count = 0, leaf_count = 0;
  int64_t prev_inner = 0, prev_leaf = -1, max_inner = 0, max_leaf = -1;
  auto place = [&](int64_t index, std::vector<uint8_t>& seen) {
    if (index < 0 || static_cast<uint64_t>(index) >= seen.size()) fail("refers to an impossible node index");
    if (seen[static_cast<size_t>(index)]) fail("refers to a node twice");
    seen[static_cast<size_t>(index)] = 1;
  };
  struct Frame {
    uint32_t node;
    int level;
    int slot;
    uint8_t present, leaf;
  };
  std::vector<Frame> stack;
  auto enter = [&](uint32_t node, int level) {
    const uint8_t present = masks.byte();
    const uint8_t leaf = level > 1 ? masks.byte() : present;  // at level 1 every child is a leaf
    if ((leaf & ~present) != 0) fail("marks a missing child as a leaf");
    if (node >= inner.size()) inner.resize(node + 1);
    inner[node].fill(kEmptyRef);
    ++inner_count;
    stack.push_back({node, level, 0, present, leaf});
  };
  place(0, inner_seen);
  enter(0, kTreeDepth);
  while (!stack.empty()) {
    Frame& f = stack.back();
    if (f.slot == 8) {
      stack.pop_back();
      continue;
    }
    const int slot = f.slot++;
    if (!(f.present & (1u << slot))) continue;
    const int64_t delta = refs.svarint();
    if (delta > kMaxDelta || delta < -kMaxDelta) fail("refers to an impossible node index");
    if (f.leaf & (1u << slot)) {
      const int64_t i = prev_leaf + 1 + delta;
      place(i, leaf_seen);
      prev_leaf = i;
      max_leaf = std::max(max_leaf, i);
      ++leaf_count;
      inner[f.node][slot] = static_cast<uint32_t>(i) | kLeafBit;
    } else {
      if (childLevel(f.level) == 0) fail("has an inner node below unit level");
      const int64_t i = prev_inner + 1 + delta;
      place(i, inner_seen);
      prev_inner = i;
      max_inner = std::max(max_inner, i);
      inner[f.node][slot] = static_cast<uint32_t>(i);
      enter(static_cast<uint32_t>(i), childLevel(f.level));  // invalidates f
    }
  }
  masks.expectEnd();
  refs.expectEnd();
  // Indices are distinct, so they fill each pool without gaps exactly when the largest is the
  // count less one.
  if (max_inner + 1 != static_cast<int64_t>(inner_count) || max_leaf + 1 != static_cast<int64_t>(leaf_count)) {
    fail("leaves gaps in its node indices");
  }
  leaves = leaf_count;
  return inner;
}

std::vector<const char*> counterTags(uint32_t version) {
  if (version == 2) return {kLengths, kHits, kColours, kColourResiduals, kPositions};
  return {kQuantisedLengths, kHitPlanes, kColours, kPositions};
}

std::vector<const char*> withCounterTags(uint32_t version, std::initializer_list<const char*> first,
                                         std::initializer_list<const char*> last) {
  std::vector<const char*> tags(first);
  for (const char* t : counterTags(version)) tags.push_back(t);
  tags.insert(tags.end(), last.begin(), last.end());
  return tags;
}

void requireExactly(const CmapFile& file, const std::string& source, const std::vector<const char*>& tags) {
  for (const CmapBlock& b : file.blocks) {
    if (std::none_of(tags.begin(), tags.end(), [&](const char* t) { return b.tag == t; })) {
      throw FormatError(source + ": block '" + b.tag + "' is not part of a format version " +
                        std::to_string(file.header.version) + " " + kindName(file.header.kind) +
                        " map (the file is damaged or from a newer chronomap)");
    }
  }
  for (const char* t : tags) {
    const auto n = std::count_if(file.blocks.begin(), file.blocks.end(), [&](const CmapBlock& b) { return b.tag == t; });
    if (n == 0) throw FormatError(source + ": the file has no '" + t + "' block");
    if (n > 1) throw FormatError(source + ": the file has more than one '" + t + "' block");
  }
}

uint16_t quantiseLength(float length_m, uint32_t hits) {
  if (!(length_m > 0.0f)) return 0;  // zero (and -0), and what no valid map holds
  uint32_t bits;
  std::memcpy(&bits, &length_m, 4);
  constexpr int kShift = 23 - kLengthMantissaBits;
  uint32_t code = (bits + (1u << (kShift - 1))) >> kShift;
  if (code >= kFirstNonFiniteLengthCode) code = bits >> kShift;  // the largest floats: truncated, not infinite
  if (code == 0) code = 1;  // the smallest subnormals: a positive length stays positive
  if (hits == 0) return static_cast<uint16_t>(code);  // free at any positive length: no state to keep
  VoxelCounters original, stored;
  original.length_m = length_m;
  original.hits = stored.hits = hits;
  stored.length_m = dequantiseLength(static_cast<uint16_t>(code));
  // P > 0.5 exactly when hits / length > ln 2: both lengths clearly on one side of the boundary
  // keep the state without computing P (exp is within an ulp; the margin is many).
  constexpr double kLn2 = 0.69314718055994531, kMargin = 1e-9;
  const double x0 = static_cast<double>(hits) / static_cast<double>(length_m);
  const double x1 = static_cast<double>(hits) / static_cast<double>(stored.length_m);
  if ((x0 > kLn2 * (1 + kMargin) && x1 > kLn2 * (1 + kMargin)) ||
      (x0 < kLn2 * (1 - kMargin) && x1 < kLn2 * (1 - kMargin))) {
    return static_cast<uint16_t>(code);
  }
  if (stored.state() != original.state()) {
    // The state's boundary lies between the length and its nearest code: the code on the
    // length's side of it keeps the state (P is monotonic in the length).
    code = stored.length_m > length_m ? code - 1 : code + 1;
  }
  return static_cast<uint16_t>(code);
}

float dequantiseLength(uint16_t code) {
  const uint32_t bits = static_cast<uint32_t>(code) << (23 - kLengthMantissaBits);
  float out;
  std::memcpy(&out, &bits, 4);
  return out;
}

namespace {

uint32_t& channel(VoxelCounters& c, int i) { return i == 0 ? c.red : i == 1 ? c.green : c.blue; }
uint32_t channel(const VoxelCounters& c, int i) { return i == 0 ? c.red : i == 1 ? c.green : c.blue; }

/// The mean colour channel that a sum stands for: round(sum / hits), at most 255 (a sum above
/// 255 per hit, which no integration makes, is kept exactly by its residual).
uint8_t meanChannel(uint32_t sum, uint32_t hits) {
  return static_cast<uint8_t>(std::min<uint64_t>(255, (uint64_t{sum} + hits / 2) / hits));
}

}  // namespace

uint32_t storedColourSum(uint32_t sum, uint32_t hits) {
  if (hits == 0) return 0;
  return static_cast<uint32_t>(std::min<uint64_t>(0xffffffffu, uint64_t{meanChannel(sum, hits)} * hits));
}

namespace {

/// Version 3's QLEN and PHIT, of `n` records of which `m` have hits.
void encodeLengthsAndHits(size_t n, size_t m, const std::function<const VoxelCounters&(size_t)>& at,
                          std::vector<CmapBlock>& blocks) {
  const size_t flag_bytes = (n + 7) / 8;
  std::vector<uint8_t> lengths(2 * n), flags(flag_bytes + 4 * m);
  uint8_t* planes = flags.data() + flag_bytes;
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    const VoxelCounters& c = at(i);
    const uint16_t code = quantiseLength(c.length_m, c.hits);
    lengths[i] = static_cast<uint8_t>(code);
    lengths[n + i] = static_cast<uint8_t>(code >> 8);
    if (c.hits == 0) continue;
    flags[i / 8] = static_cast<uint8_t>(flags[i / 8] | (1u << (i % 8)));
    for (int b = 0; b < 4; ++b) planes[b * m + k] = static_cast<uint8_t>(c.hits >> (8 * b));
    ++k;
  }
  blocks.push_back({kQuantisedLengths, std::move(lengths)});
  blocks.push_back({kHitPlanes, std::move(flags)});
}

/// Version 3's QLEN and PHIT for `n` records, checked against each other: the lengths' codes,
/// one flag a record (it has hits) and the flagged records' hits, byte plane after byte plane.
struct LengthsAndHits {
  LengthsAndHits(const CmapFile& file, const std::string& source_in, size_t n_in) : source(source_in), n(n_in) {
    const CmapBlock& length_block = file.block(kQuantisedLengths, source);
    if (length_block.data.size() != 2 * n) {
      throw FormatError(blockName(source, kQuantisedLengths) + " does not match the tree");
    }
    const CmapBlock& hit_block = file.block(kHitPlanes, source);
    const size_t flag_bytes = (n + 7) / 8;
    if (hit_block.data.size() < flag_bytes) throw FormatError(blockName(source, kHitPlanes) + " is truncated");
    lengths = length_block.data.data();
    flags = hit_block.data.data();
    for (size_t b = 0; b < flag_bytes; ++b) with_hits += static_cast<size_t>(std::popcount(flags[b]));
    if (n % 8 != 0 && (flags[n / 8] >> (n % 8)) != 0) {
      throw FormatError(blockName(source, kHitPlanes) + " flags records that do not exist");
    }
    if (hit_block.data.size() != flag_bytes + 4 * with_hits) {
      throw FormatError(blockName(source, kHitPlanes) + " does not match the tree");
    }
    planes = flags + flag_bytes;
  }
  bool flagged(size_t i) const { return (flags[i / 8] >> (i % 8)) & 1; }
  /// Record i's ray length. @throw FormatError for a code that is no length.
  float lengthOf(size_t i) const {
    const uint32_t code = lengths[i] | uint32_t{lengths[n + i]} << 8;
    if (code >= kFirstNonFiniteLengthCode) {
      throw FormatError(blockName(source, kQuantisedLengths) + " holds an impossible length");
    }
    return dequantiseLength(static_cast<uint16_t>(code));
  }
  /// The hits of the k-th flagged record. @throw FormatError for none.
  uint32_t hitsOf(size_t k) const {
    uint32_t h = 0;
    for (int b = 0; b < 4; ++b) h |= static_cast<uint32_t>(planes[b * with_hits + k]) << (8 * b);
    if (h == 0) throw FormatError(blockName(source, kHitPlanes) + " flags a record without hits");
    return h;
  }

  const std::string& source;
  size_t n;
  size_t with_hits = 0;
  const uint8_t* lengths = nullptr;
  const uint8_t* flags = nullptr;
  const uint8_t* planes = nullptr;
};

/// The mean colours and hit positions (COLR, CPOS) of `with_hits` records, checked for size.
struct HitBlocks {
  const CmapBlock& means;
  const CmapBlock& positions;
};
HitBlocks hitBlocksOf(const CmapFile& file, const std::string& source, size_t with_hits) {
  const CmapBlock& means = file.block(kColours, source);
  const CmapBlock& positions = file.block(kPositions, source);
  if (means.data.size() != 3 * with_hits) throw FormatError(blockName(source, kColours) + " does not match the hit counts");
  if (positions.data.size() != 3 * with_hits) {
    throw FormatError(blockName(source, kPositions) + " does not match the hit counts");
  }
  return {means, positions};
}

/// Reads version 3's QLEN and PHIT; returns how many of the `n` records have hits.
size_t decodeLengthsAndHits(const CmapFile& file, const std::string& source, size_t n,
                            const std::function<VoxelCounters&(size_t)>& at) {
  const LengthsAndHits v3(file, source, n);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    VoxelCounters& c = at(i);
    c.length_m = v3.lengthOf(i);
    c.hits = 0;
    if (!v3.flagged(i)) continue;
    c.hits = v3.hitsOf(k);
    ++k;
  }
  return v3.with_hits;
}

}  // namespace

void encodeCounters(size_t n, const std::function<const VoxelCounters&(size_t)>& at, std::vector<CmapBlock>& blocks,
                    uint32_t version) {
  ByteWriter residuals;
  size_t with_hits = 0;
  for (size_t i = 0; i < n; ++i) with_hits += at(i).hits > 0;
  if (version == 2) {
    std::vector<uint8_t> lengths(4 * n);
    ByteWriter hits;
    for (size_t i = 0; i < n; ++i) {
      const VoxelCounters& c = at(i);
      uint32_t bits;
      std::memcpy(&bits, &c.length_m, 4);
      for (int b = 0; b < 4; ++b) lengths[b * n + i] = static_cast<uint8_t>(bits >> (8 * b));
      hits.varint(c.hits);
    }
    blocks.push_back({kLengths, std::move(lengths)});
    blocks.push_back({kHits, std::move(hits.bytes())});
  } else {
    encodeLengthsAndHits(n, with_hits, at, blocks);
  }
  // Colours: the mean (a byte, as smooth as the surfaces) and, in version 2, the sum's remainder
  // beyond mean * hits (small, often zero), each channel's stream after the other's.
  std::vector<uint8_t> means(3 * with_hits), positions(3 * with_hits);
  size_t k = 0;  // one pass over the records, the three channels of each at once
  for (size_t i = 0; i < n; ++i) {
    const VoxelCounters& c = at(i);
    if (c.hits == 0) continue;
    for (int ch = 0; ch < 3; ++ch) {
      means[ch * with_hits + k] = meanChannel(channel(c, ch), c.hits);
      positions[ch * with_hits + k] = quantiseOffset(c.offset[ch], c.hits);
    }
    ++k;
  }
  if (version == 2) {  // the residuals' stream: each channel's after the other's
    for (int ch = 0; ch < 3; ++ch) {
      k = 0;
      for (size_t i = 0; i < n; ++i) {
        const VoxelCounters& c = at(i);
        if (c.hits == 0) continue;
        residuals.svarint(static_cast<int64_t>(channel(c, ch)) - static_cast<int64_t>(means[ch * with_hits + k]) * c.hits);
        ++k;
      }
    }
  }
  blocks.push_back({kColours, std::move(means)});
  if (version == 2) blocks.push_back({kColourResiduals, std::move(residuals.bytes())});
  blocks.push_back({kPositions, std::move(positions)});
}

void decodeCounters(const CmapFile& file, const std::string& source, size_t n,
                    const std::function<VoxelCounters&(size_t)>& at) {
  const bool exact = file.header.version == 2;
  size_t with_hits = 0;
  if (exact) {
    const CmapBlock& lengths = file.block(kLengths, source);
    if (lengths.data.size() != 4 * n) throw FormatError(blockName(source, kLengths) + " does not match the tree");
    ByteReader hits(file.block(kHits, source).data, blockName(source, kHits));
    for (size_t i = 0; i < n; ++i) {
      VoxelCounters& c = at(i);
      uint32_t bits = 0;
      for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(lengths.data[b * n + i]) << (8 * b);
      std::memcpy(&c.length_m, &bits, 4);
      const uint64_t h = hits.varint();
      if (h > 0xffffffffu) hits.fail("holds an impossible hit count");
      c.hits = static_cast<uint32_t>(h);
      with_hits += c.hits > 0;
    }
    hits.expectEnd();
  } else {
    with_hits = decodeLengthsAndHits(file, source, n, at);
  }
  const HitBlocks hit_blocks = hitBlocksOf(file, source, with_hits);
  const CmapBlock& means = hit_blocks.means;  // references, not bindings: the lambda below captures them
  const CmapBlock& positions = hit_blocks.positions;
  static const std::vector<uint8_t> kNone;
  ByteReader residuals(exact ? file.block(kColourResiduals, source).data : kNone, blockName(source, kColourResiduals));
  // One record's channel from its mean, the residual (version 2) and its position byte.
  auto decodeChannel = [&](VoxelCounters& c, int ch, size_t k) {
    const int64_t residual = exact ? residuals.svarint() : 0;
    if (residual > kMaxResidual || residual < -kMaxResidual) residuals.fail("holds an impossible colour sum");
    int64_t sum = int64_t{means.data[ch * with_hits + k]} * c.hits + residual;
    if (!exact) sum = std::min<int64_t>(sum, 0xffffffffll);  // as storedColourSum caps it
    if (sum < 0 || sum > 0xffffffffll) residuals.fail("holds an impossible colour sum");
    channel(c, ch) = static_cast<uint32_t>(sum);
    const uint8_t q = positions.data[ch * with_hits + k];
    if (q > 2 * kOffsetLevels) throw FormatError(blockName(source, kPositions) + " holds an impossible position");
    c.offset[ch] = dequantiseOffset(q, c.hits);
  };
  if (exact) {  // version 2's residuals come each channel after the other
    for (int ch = 0; ch < 3; ++ch) {
      size_t k = 0;
      for (size_t i = 0; i < n; ++i) {
        VoxelCounters& c = at(i);
        if (c.hits > 0) decodeChannel(c, ch, k++);
      }
    }
  } else {  // one pass, the three channels of each record at once
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) {
      VoxelCounters& c = at(i);
      if (c.hits == 0) continue;
      for (int ch = 0; ch < 3; ++ch) decodeChannel(c, ch, k);
      ++k;
    }
  }
  residuals.expectEnd();
}

void decodeCountersOf(const CmapFile& file, const std::string& source, size_t n, const std::vector<size_t>& records,
                      const std::function<VoxelCounters&(size_t)>& at) {
  for (size_t k = 0; k < records.size(); ++k) {
    if (records[k] >= n || (k > 0 && records[k] <= records[k - 1])) {
      throw UsageError("decodeCountersOf: records must be increasing and below the record count");
    }
  }
  if (file.header.version == 2) {  // varints: every record decoded, the ones asked kept
    std::vector<VoxelCounters> all(n);
    decodeCounters(file, source, n, [&](size_t i) -> VoxelCounters& { return all[i]; });
    for (size_t k = 0; k < records.size(); ++k) at(k) = all[records[k]];
    return;
  }
  // Version 3: fixed-width planes; a record's place among those with hits is a count of flags.
  const LengthsAndHits v3(file, source, n);
  const size_t m = v3.with_hits;
  const auto [means, positions] = hitBlocksOf(file, source, m);
  const uint8_t* flags = v3.flags;
  size_t byte_at = 0, before = 0;  // `before`: records with hits in the bytes of flags before byte_at
  for (size_t k = 0; k < records.size(); ++k) {
    const size_t i = records[k];
    for (; byte_at < i / 8; ++byte_at) before += static_cast<size_t>(std::popcount(flags[byte_at]));
    VoxelCounters& c = at(k);
    c = VoxelCounters{};
    c.length_m = v3.lengthOf(i);
    if (!v3.flagged(i)) continue;
    const auto lower = static_cast<uint8_t>(flags[i / 8] & ((1u << (i % 8)) - 1));  // flags before i in its byte
    const size_t h_at = before + static_cast<size_t>(std::popcount(lower));
    const uint32_t h = v3.hitsOf(h_at);
    c.hits = h;
    for (int ch = 0; ch < 3; ++ch) {
      channel(c, ch) = static_cast<uint32_t>(std::min<int64_t>(int64_t{means.data[ch * m + h_at]} * h, 0xffffffffll));
      const uint8_t q = positions.data[ch * m + h_at];
      if (q > 2 * kOffsetLevels) throw FormatError(blockName(source, kPositions) + " holds an impossible position");
      c.offset[ch] = dequantiseOffset(q, h);
    }
  }
}

}  // namespace chronomap::columns
