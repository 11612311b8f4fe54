#pragma once
/// @file
/// The column encoding of format versions 2 and 3 (docs/file-format.md): a tree's shape as child
/// masks and reference deltas, and voxel counters one field at a time (lengths as byte planes, hits
/// and colour sums as varints, hit positions as quantised mean offsets), each its own block so
/// that zstd sees one kind of value at a time. Internal to chronomap_io.

#include <array>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

#include "chronomap/core/counters.h"
#include "chronomap/core/offset_quantiser.h"
#include "chronomap/store/cmap.h"

namespace chronomap::columns {

/// Appends unsigned LEB128 varints and bytes.
class ByteWriter {
 public:
  void varint(uint64_t v) {
    while (v >= 0x80) {
      bytes_.push_back(static_cast<uint8_t>(v | 0x80));
      v >>= 7;
    }
    bytes_.push_back(static_cast<uint8_t>(v));
  }
  /// Signed values, zigzag-coded so that small magnitudes take one byte.
  void svarint(int64_t v) { varint((static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63)); }
  void byte(uint8_t b) { bytes_.push_back(b); }
  std::vector<uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

/// Reads what ByteWriter wrote; every read past the end or malformed varint throws
/// FormatError("<what> is truncated" / "... has an overlong number").
class ByteReader {
 public:
  ByteReader(const std::vector<uint8_t>& bytes, std::string what)
      : p_(bytes.data()), end_(bytes.data() + bytes.size()), what_(std::move(what)) {}
  uint64_t varint();
  int64_t svarint() {
    const uint64_t u = varint();
    return static_cast<int64_t>(u >> 1) ^ -static_cast<int64_t>(u & 1);
  }
  uint8_t byte();
  bool atEnd() const { return p_ == end_; }
  /// @throw FormatError when bytes are left over.
  void expectEnd() const;
  [[noreturn]] void fail(const std::string& problem) const;

 private:
  const uint8_t* p_;
  const uint8_t* end_;
  std::string what_;
};

/// Block tags of version 2 (both kinds share the tree and counter blocks).
inline constexpr const char* kTreeMasks = "TMSK";
inline constexpr const char* kTreeRefs = "TREF";
inline constexpr const char* kLengths = "CLEN";
inline constexpr const char* kHits = "CHIT";
inline constexpr const char* kColours = "CRGB";
inline constexpr const char* kColourResiduals = "CRES";
inline constexpr const char* kPositions = "CPOS";
/// Version 3 replaces CLEN and CHIT by these and drops CRES (colour sums kept as mean * hits).
inline constexpr const char* kQuantisedLengths = "QLEN";
inline constexpr const char* kHitPlanes = "PHIT";
/// The counter blocks of a file of `version` (2 or 3), in the order they are written.
std::vector<const char*> counterTags(uint32_t version);

/// A tree as both map kinds store it: 8 references per inner node, kEmpty (all ones), an inner
/// index, or kLeafBit | leaf index (a leaf, or a 4D map's slot list); node 0 is the root at
/// level kTreeDepth.
using Children = std::array<uint32_t, 8>;
inline constexpr uint32_t kEmptyRef = 0xffffffffu;
inline constexpr uint32_t kLeafBit = 0x80000000u;

/// Appends the shape of `inner` as two blocks: TMSK (per inner node in depth-first order, slots
/// in order: a byte whose bit i says slot i has a child, then, above level 1, a byte whose bit i
/// says that child is a leaf) and TREF (per child, same order: its index minus one more than the
/// previous index of its kind, zigzag varint; all zeros for pools laid out depth first).
void encodeTree(const std::vector<Children>& inner, std::vector<CmapBlock>& blocks);
/// The inner pool and the number of leaves that TMSK and TREF describe, indices as written.
/// @throw FormatError naming `source` for a malformed shape (indices out of range or repeated,
/// an inner node at unit level, bytes missing or left over).
std::vector<Children> decodeTree(const CmapFile& file, const std::string& source, size_t& leaves);

/// The counters of `n` records, `at(i)` giving record i, as `version` (2 or 3) stores them.
/// Version 3: QLEN (each length as quantiseLength's 16-bit code, two byte planes, low first),
/// PHIT (a bitmap, bit i%8 of byte i/8 set when record i has hits, then the hit counts of those
/// records as four byte planes, lowest first), CRGB and CPOS as in version 2, no CRES.
/// Version 2 appends CLEN (the f32 lengths' bits as
/// 4 byte planes, lowest byte first), CHIT (hits, varints), and for the records with hits, each
/// as a red, then a green, then a blue plane: CRGB (mean colour, round(sum / hits), a byte), CRES
/// (sum - mean * hits, zigzag varints) and CPOS (the quantised mean offsets, see quantiseOffset;
/// x, y, z planes).
void encodeCounters(size_t n, const std::function<const VoxelCounters&(size_t)>& at, std::vector<CmapBlock>& blocks,
                    uint32_t version);
/// Fills the counters of `n` records (`at(i)` giving record i) from those blocks (of the file's
/// version).
/// @throw FormatError naming `source` when a block is missing or its size does not match.
void decodeCounters(const CmapFile& file, const std::string& source, size_t n,
                    const std::function<VoxelCounters&(size_t)>& at);

/// decodeCounters for the records `records` alone (increasing indices below `n`): `at(k)` is
/// given record records[k]'s counters. Version 3 reads only their bytes of the planes (the
/// sizes of the blocks are checked as decodeCounters checks them, the values of the records
/// read only); version 2 decodes every record.
/// @throw FormatError as decodeCounters; UsageError for records out of order or range.
void decodeCountersOf(const CmapFile& file, const std::string& source, size_t n, const std::vector<size_t>& records,
                      const std::function<VoxelCounters&(size_t)>& at);

/// Checks that `file` holds exactly the blocks `tags`, each once. Version 2 readers refuse other
/// blocks (a block the format gains comes with a new version), so that a damaged tag, which no
/// checksum covers, is an error rather than a block silently missing.
/// @throw FormatError naming `source` and the block.
void requireExactly(const CmapFile& file, const std::string& source, const std::vector<const char*>& tags);
/// `first`, then the counter blocks of `version`, then `last`.
std::vector<const char*> withCounterTags(uint32_t version, std::initializer_list<const char*> first,
                                         std::initializer_list<const char*> last);

/// Hit positions in versions 2 and 3: the core's one quantiser (core/offset_quantiser.h), a mean
/// offset as the byte round(mean * 254) + 127 (0..254; 255 is refused).
using chronomap::dequantiseOffset;
using chronomap::kOffsetLevels;
using chronomap::quantiseOffset;

/// Lengths in version 3: a length keeps 8 of its 23 mantissa bits, rounded to nearest, as the
/// 16-bit code (f32 bits + 2^14) >> 15 (lengths are non-negative, the sign bit is always 0;
/// the largest finite floats are truncated instead of rounding to infinity). Relative error at
/// most 2^-9. Where rounding to nearest would change the voxel's state (unknown, free, occupied:
/// P = 1 - exp(-hits / length) crossing 0.5, or a positive length becoming 0) the neighbouring
/// code on the length's side is taken instead: relative error at most 2^-8, state unchanged.
/// A positive length stays positive (subnormals below 2^-134 become that). Codes are exact
/// floats, so quantising a decoded length gives its code again.
inline constexpr int kLengthMantissaBits = 8;
/// Codes from this one up stand for infinity or NaN: refused.
inline constexpr uint32_t kFirstNonFiniteLengthCode = 0xff00;
uint16_t quantiseLength(float length_m, uint32_t hits);
float dequantiseLength(uint16_t code);
/// Colour sums in version 3: mean * hits (the mean colour, round(sum / hits), is exact).
uint32_t storedColourSum(uint32_t sum, uint32_t hits);

}  // namespace chronomap::columns
