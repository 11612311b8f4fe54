#pragma once
/// @file
/// 4D maps in the .cmap container (docs/file-format.md, kind "4d").

#include <filesystem>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "chronomap/store/cmap.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// Writes a 4D map atomically (temporary file, then rename): a crash leaves the previous
/// file as it was. Compacts a copy of the map first; `meta` (a JSON object) is stored as is.
void writeTemporalMap(const std::filesystem::path& path, const TemporalMap& map, const nlohmann::json& meta);
/// The bytes writeTemporalMap writes. `version` 1 gives the previous format's layout (kept for
/// tests that old files still read, and for benchmarks that compare sizes); the default, the
/// current one. @throw UsageError for another version.
std::vector<uint8_t> encodeTemporalMap(const TemporalMap& map, const nlohmann::json& meta, uint32_t version);
/// The same under header kind `kind` (4d, or tiled for a tile index), with the members of
/// `*extra` (a JSON object, when given) added to the metadata block.
std::vector<uint8_t> encodeTemporalMap(const TemporalMap& map, const nlohmann::json& meta,
                                       MapKind kind = MapKind::Temporal, const nlohmann::json* extra = nullptr,
                                       uint32_t version = kCmapFormatVersion);
/// encodeTemporalMap(map, meta) without compacting the map first: its lists stay as they are, so
/// that its snapshots keep their nodes and sums bit for bit (a tile's history window, whose
/// lists compaction could merge where the whole history's cannot be; store/tiled_file.h).
std::vector<uint8_t> encodeTemporalMapAsItIs(const TemporalMap& map, const nlohmann::json& meta);
/// The metadata a 4D map or tile index was written with (writeTemporalMap's `meta`: its metadata
/// block's "user" object), or an empty object.
nlohmann::json userMetadataOf(const CmapFile& file);
/// `map` with every entry's counters asStored (io/cmap.h): what writing and reading it gives.
TemporalMap asStored(const TemporalMap& map);
/// How a 4D map file is laid out: a base written in one piece (writeTemporalMap), then the
/// sessions that `chronomap add` appended as records since (docs/file-format.md).
struct TemporalFileLayout {
  uint64_t file_bytes = 0;
  uint64_t base_bytes = 0;
  uint64_t appended_bytes = 0;  ///< complete append records
  size_t appended_sessions = 0;
  uint64_t incomplete_tail_bytes = 0;  ///< an interrupted append after those: not part of the map
  /// Where the next record goes: after the base and the complete records.
  uint64_t completeBytes() const { return base_bytes + appended_bytes; }
};
TemporalFileLayout layoutOf(const CmapFile& file);

/// One time of a 4D map file, read without building the map (a tile read for a snapshot,
/// store/tiled_file.h).
struct StoredSnapshot {
  SessionMap map;                       ///< the map at its session `rank`'s time
  ChangeCriterion criterion;            ///< as the file lists it
  std::vector<SessionRecord> sessions;  ///< as the file lists them, coverages left empty
};
/// temporalMapFrom(file, source).snapshot(t) for a time t of session `rank` (a rank past the
/// file's sessions: its last), node for node, from the file's columns: the tree, every session
/// number, and the counters of the entries valid then only (not the other entries' counters,
/// nor the coverages, so a file damaged there alone reads). Cost: decoding the blocks, then
/// about one entry per history list instead of building every history.
/// @throw FormatError naming `source` as temporalMapFrom for what it reads; UsageError for a
/// file of format version 1 or with appended sessions (read those with temporalMapFrom).
StoredSnapshot snapshotOfColumns(const CmapFile& file, const std::string& source, uint32_t rank);

/// Reads a 4D map: the base, then each appended session added again in file order.
/// @throw IoError, FormatError naming the file.
TemporalMap readTemporalMap(const std::filesystem::path& path, TemporalFileLayout* layout = nullptr);
/// The 4D map stored in a decoded file, appended sessions included. @throw FormatError naming `source`.
TemporalMap temporalMapFrom(const CmapFile& file, const std::string& source);

/// The map stored in the base blocks of a decoded 4d or tiled file, without its appended
/// sessions and whatever its header's kind. @throw FormatError naming `source`.
TemporalMap decodeTemporalBlocks(const CmapFile& file, const std::string& source);

/// The append record (tag `ADDS`) of one session added to a 4D map: reading it back means
/// TemporalMap::add(time_s, session, options) on the map stored before it, which gives the
/// same map as the add that wrote it. Append it with appendToFile (io/file.h).
std::vector<uint8_t> encodeSessionRecord(double time_s, const SessionMap& session, const AddSettings& options);

}  // namespace chronomap
