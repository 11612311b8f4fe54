#pragma once
/// @file
/// The .cmap container (docs/file-format.md): magic, format version, kind, resolution, bounds,
/// then checksummed blocks, each optionally zstd-compressed. Written atomically.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include "chronomap/octree/session_map.h"

namespace chronomap {

/// What a .cmap file holds.
enum class MapKind : uint32_t { Session = 1, Temporal = 2, Diff = 3, Tiled = 4 };
/// "session", "4d", "diff", "tiled".
const char* toString(MapKind kind);
/// Its name in messages: "session", "4D", "diff", "tiled" (toString's names are the files' and
/// the JSON outputs' own, "4d" among them).
const char* kindName(MapKind kind);

/// The format version this build writes and the newest it reads. Version 2 stores session and
/// 4D maps field by field, hit positions quantised; version 3 also quantises the ray lengths and
/// keeps colour sums as mean * hits (see asStored); versions 1 and 2 still read.
inline constexpr uint32_t kCmapFormatVersion = 3;

/// Hit positions in version 2 and 3 files are mean offsets from the voxel centre quantised in steps of
/// 1/254 voxel, zero (the centre) exact: each axis of a voxel's mean hit position is kept to
/// within half a step, resolution / 508 (plus float rounding), under the resolution / 256 that
/// the tests check.
inline constexpr double kPositionStepVoxels = 1.0 / 254.0;

/// Ray lengths in version 3 files keep 8 mantissa bits: each within 2^-9 of the length written,
/// and within 2^-8 where the nearest value would change the voxel's state (unknown, free,
/// occupied), which they never do; so P = 1 - exp(-hits / length) moves by at most 2^-8 / e.
inline constexpr double kLengthRelativeError = 1.0 / 256.0;

/// Fixed-size header of a .cmap file.
struct CmapHeader {
  uint32_t version = kCmapFormatVersion;
  MapKind kind = MapKind::Session;
  double resolution_m = 0.0;
  uint32_t tree_depth = kTreeDepth;
  Eigen::Vector3d bounds_min_m = Eigen::Vector3d::Zero();  ///< of the known voxels
  Eigen::Vector3d bounds_max_m = Eigen::Vector3d::Zero();
};

/// One named block of payload (tag: four ASCII characters).
struct CmapBlock {
  std::string tag;
  std::vector<uint8_t> data;
};

/// A decoded .cmap file.
struct CmapFile {
  CmapHeader header;
  std::vector<CmapBlock> blocks;
  /// 4D maps only: the complete append records after the blocks, in file order.
  std::vector<CmapBlock> appended;
  uint64_t file_bytes = 0;
  uint64_t base_bytes = 0;             ///< header and blocks
  uint64_t complete_bytes = 0;         ///< header, blocks and complete append records
  uint64_t incomplete_tail_bytes = 0;  ///< an interrupted append's bytes after those (ignored)
  /// The block with this tag. @throw FormatError naming `source` when missing.
  const CmapBlock& block(const std::string& tag, const std::string& source) const;
  /// The block with this tag, or null.
  const CmapBlock* find(const std::string& tag) const;
};

/// Encodes header and blocks; blocks are zstd-compressed at `zstd_level` (0 stores them raw).
std::vector<uint8_t> encodeCmap(const CmapHeader& header, const std::vector<CmapBlock>& blocks, int zstd_level = 3);
/// One append record (docs/file-format.md): the block, its header guarded by its own CRC-32.
std::vector<uint8_t> encodeAppendRecord(const CmapBlock& record, int zstd_level = 3);
/// Decodes and checks a whole file image.
/// @throw FormatError naming `source`: truncated, corrupt (checksum), wrong magic, newer version.
CmapFile decodeCmap(const std::vector<uint8_t>& bytes, const std::string& source);
/// Reads and decodes a .cmap file. @throw IoError, FormatError.
CmapFile readCmap(const std::filesystem::path& path);

/// The bytes of a session map file (see writeSessionMap). `version` 1 gives the previous format's
/// layout (kept for tests that old files still read, and for benchmarks that compare sizes).
/// @throw UsageError for a version other than 1 and kCmapFormatVersion.
std::vector<uint8_t> encodeSessionMap(const SessionMap& map, const nlohmann::json& meta, int zstd_level = 3,
                                      uint32_t version = kCmapFormatVersion);
/// Writes a session map with optional metadata (a JSON object) atomically.
void writeSessionMap(const std::filesystem::path& path, const SessionMap& map, const nlohmann::json& meta);
/// Reads a session map. @throw FormatError when the file is not a valid session map.
SessionMap readSessionMap(const std::filesystem::path& path);
/// The session map stored in a decoded file. @throw FormatError.
SessionMap sessionMapFrom(const CmapFile& file, const std::string& source);
/// `c` as a file keeps it: the hit positions quantised (kPositionStepVoxels), the length
/// quantised (kLengthRelativeError, state kept), each colour sum mean * hits (the mean colour
/// exact); hits exact.
/// Reading a written map gives asStored of every counter; asStored(asStored(c)) == asStored(c).
VoxelCounters asStored(const VoxelCounters& c);
/// `map` with every leaf asStored: what writing and reading it back gives.
SessionMap asStored(const SessionMap& map);
/// The metadata block of a file, or an empty object.
nlohmann::json metadataOf(const CmapFile& file);

/// Version 1 records (read, no longer written).
/// Size of the counters as a LEAF or ENTR record stores them: length, hits, colour sums.
inline constexpr size_t kCounterRecordBytes = 20;
/// Size of the hit offsets as an HPOS or EPOS record stores them: three f32 sums. They have a
/// block of their own so that files written before them still read (positions at the centre).
inline constexpr size_t kOffsetRecordBytes = 12;
/// Writes `c`'s length, hits and colour sums to `out` (kCounterRecordBytes).
void putCounterRecord(uint8_t* out, const VoxelCounters& c);
/// Reads them back into `c` (its offsets untouched).
void getCounterRecord(const uint8_t* in, VoxelCounters& c);
/// Writes `c`'s hit offset sums to `out` (kOffsetRecordBytes).
void putOffsetRecord(uint8_t* out, const VoxelCounters& c);
/// Reads them back into `c`.
void getOffsetRecord(const uint8_t* in, VoxelCounters& c);
/// The optional hit position block `tag` (HPOS, EPOS) of `file`, holding one record for each
/// of `records` counters, or null when the file has none (it was written before them).
/// @throw FormatError naming `what` when its size does not match.
const CmapBlock* offsetBlock(const CmapFile& file, const std::string& tag, size_t records, const std::string& what);

}  // namespace chronomap
