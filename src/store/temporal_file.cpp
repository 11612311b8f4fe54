#include "chronomap/store/temporal_file.h"

#include <cstring>
#include <optional>
#include <type_traits>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "columns.h"

namespace chronomap {

/// An entry as ENTR stores it: the session number, then the counters as a LEAF record.
constexpr size_t kEntryRecordBytes = 4 + kCounterRecordBytes;
static_assert(sizeof(TemporalMap::Children) == 32, "inner nodes are stored as 32 bytes");
static_assert(TemporalMap::kListBit == columns::kLeafBit && TemporalMap::kEmpty == columns::kEmptyRef &&
                  std::is_same_v<TemporalMap::Children, columns::Children>,
              "version 2 stores 4D map references (lists as leaves) as the column codec's");

namespace {

template <class T>
std::vector<uint8_t> bytesOf(const std::vector<T>& v) {
  std::vector<uint8_t> out(v.size() * sizeof(T));
  if (!out.empty()) std::memcpy(out.data(), v.data(), out.size());
  return out;
}

template <class T>
std::vector<T> vectorOf(const CmapBlock& b, const std::string& source) {
  if (b.data.size() % sizeof(T) != 0) throw FormatError(source + ": block " + b.tag + " has an impossible size");
  std::vector<T> v(b.data.size() / sizeof(T));
  if (!v.empty()) std::memcpy(v.data(), b.data.data(), b.data.size());
  return v;
}

std::vector<uint8_t> entryBytes(const std::vector<TemporalMap::Entry>& entries) {
  std::vector<uint8_t> out(entries.size() * kEntryRecordBytes);
  for (size_t i = 0; i < entries.size(); ++i) {
    uint8_t* p = out.data() + i * kEntryRecordBytes;
    std::memcpy(p, &entries[i].session, 4);
    putCounterRecord(p + 4, entries[i].value);
  }
  return out;
}

std::vector<uint8_t> entryOffsetBytes(const std::vector<TemporalMap::Entry>& entries) {
  std::vector<uint8_t> out(entries.size() * kOffsetRecordBytes);
  for (size_t i = 0; i < entries.size(); ++i) putOffsetRecord(out.data() + i * kOffsetRecordBytes, entries[i].value);
  return out;
}

/// The entries of ENTR, with their hit positions from EPOS when the file has them (files
/// written before them have not: every surface then sits at its voxel's centre).
std::vector<TemporalMap::Entry> entriesOf(const CmapFile& file, const std::string& source) {
  const CmapBlock& b = file.block("ENTR", source);
  if (b.data.size() % kEntryRecordBytes != 0) throw FormatError(source + ": block ENTR has an impossible size");
  std::vector<TemporalMap::Entry> entries(b.data.size() / kEntryRecordBytes);
  for (size_t i = 0; i < entries.size(); ++i) {
    const uint8_t* p = b.data.data() + i * kEntryRecordBytes;
    std::memcpy(&entries[i].session, p, 4);
    getCounterRecord(p + 4, entries[i].value);
  }
  if (const CmapBlock* positions = offsetBlock(file, "EPOS", entries.size(), source)) {
    for (size_t i = 0; i < entries.size(); ++i) {
      getOffsetRecord(positions->data.data() + i * kOffsetRecordBytes, entries[i].value);
    }
  }
  return entries;
}

/// Version 2: list sizes (LSIZ) as varints; each list's session numbers (ESES) as the first,
/// then the gaps less one, varints.
constexpr const char* kListSizes = "LSIZ";
constexpr const char* kEntrySessions = "ESES";

std::vector<uint8_t> listSizeBytes(const std::vector<uint32_t>& sizes) {
  columns::ByteWriter w;
  for (uint32_t s : sizes) w.varint(s);
  return std::move(w.bytes());
}

std::vector<uint8_t> sessionBytes(const std::vector<uint32_t>& sizes, const std::vector<TemporalMap::Entry>& entries) {
  columns::ByteWriter w;
  size_t at = 0;
  for (uint32_t s : sizes) {
    for (uint32_t k = 0; k < s; ++k, ++at) {
      w.varint(k == 0 ? entries[at].session : entries[at].session - entries[at - 1].session - 1);
    }
  }
  return std::move(w.bytes());
}

/// The parts of a version 2 file (their consistency is checked by TemporalMap::fromParts).
TemporalMap::Parts partsOfVersion2(const CmapFile& file, const std::string& source) {
  columns::requireExactly(file, source,
                          columns::withCounterTags(file.header.version,
                                                   {"META", columns::kTreeMasks, columns::kTreeRefs, kListSizes,
                                                    kEntrySessions},
                                                   {"COVR"}));
  TemporalMap::Parts parts;
  size_t lists = 0;
  parts.inner = columns::decodeTree(file, source, lists);
  columns::ByteReader sizes(file.block(kListSizes, source).data, source + ": block '" + kListSizes + "'");
  parts.list_sizes.resize(lists);
  uint64_t total = 0;
  for (uint32_t& s : parts.list_sizes) {
    const uint64_t v = sizes.varint();
    if (v == 0 || v > 0xffffu) sizes.fail("holds a history list of impossible length");
    s = static_cast<uint32_t>(v);
    total += v;
  }
  sizes.expectEnd();
  // Every entry takes at least one byte of ESES: a crafted total cannot allocate more than that.
  const CmapBlock& session_block = file.block(kEntrySessions, source);
  columns::ByteReader sessions(session_block.data, source + ": block '" + kEntrySessions + "'");
  if (total > session_block.data.size()) sessions.fail("is truncated");
  parts.entries.resize(total);
  size_t at = 0;
  for (uint32_t s : parts.list_sizes) {
    for (uint32_t k = 0; k < s; ++k, ++at) {
      const uint64_t gap = sessions.varint();
      if (gap > 0xffffffffu) sessions.fail("holds an impossible session number");
      const uint64_t v = gap + (k == 0 ? 0 : uint64_t{parts.entries[at - 1].session} + 1);
      if (v > 0xffffffffu) sessions.fail("holds an impossible session number");
      parts.entries[at].session = static_cast<uint32_t>(v);
    }
  }
  sessions.expectEnd();
  columns::decodeCounters(file, source, parts.entries.size(),
                          [&](size_t i) -> VoxelCounters& { return parts.entries[i].value; });
  return parts;
}

}  // namespace

nlohmann::json userMetadataOf(const CmapFile& file) {
  const nlohmann::json meta = metadataOf(file);
  if (meta.is_object() && meta.contains("user") && meta["user"].is_object()) return meta["user"];
  return nlohmann::json::object();
}

void writeTemporalMap(const std::filesystem::path& path, const TemporalMap& map, const nlohmann::json& meta) {
  writeFileAtomic(path, encodeTemporalMap(map, meta));
}

std::vector<uint8_t> encodeTemporalMap(const TemporalMap& map, const nlohmann::json& meta, uint32_t version) {
  return encodeTemporalMap(map, meta, MapKind::Temporal, nullptr, version);
}

namespace {

std::vector<uint8_t> encodeTemporal(const TemporalMap& map, const nlohmann::json& meta, MapKind kind,
                                    const nlohmann::json* extra, uint32_t version, bool compact) {
  if (version < 1 || version > kCmapFormatVersion) throw UsageError("4D maps are written in format version 1, 2 or 3");
  std::optional<TemporalMap> copy;  // a map compacted already is written as it is
  if (compact && !map.isCompact()) {
    copy = map;
    copy->compact();
  }
  const TemporalMap& compacted = copy ? *copy : map;
  const TemporalMap::Parts parts = compacted.parts();

  CmapHeader header;
  header.kind = kind;
  header.resolution_m = map.resolution_m();
  bool any = false;
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
  compacted.forEachListPlace([&](const VoxelKey& k, int level) {
    const Eigen::Vector3d a = map.grid().cornerOf(k);
    const Eigen::Vector3d b = a + Eigen::Vector3d::Constant(map.resolution_m() * (1 << level));
    lo = any ? lo.cwiseMin(a) : a;
    hi = any ? hi.cwiseMax(b) : b;
    any = true;
  });
  header.bounds_min_m = lo;
  header.bounds_max_m = hi;

  nlohmann::json j = nlohmann::json::object();
  j["user"] = meta.is_object() ? meta : nlohmann::json::object();
  j["criterion"] = {{"probability_threshold", map.criterion().probability_threshold},
                    {"color_distance", map.criterion().colour_distance},
                    {"surface_shift_voxels", map.criterion().surface_shift_voxels}};
  // The evidence rule only when on, so that maps without it keep their bytes (older readers refuse
  // nothing: they would read such a map without the rule, so a later add there would differ).
  if (map.criterion().min_free_length_m > 0.0) j["criterion"]["min_free_length_m"] = map.criterion().min_free_length_m;
  if (map.criterion().min_hits > 0) j["criterion"]["min_hits"] = map.criterion().min_hits;
  nlohmann::json sessions = nlohmann::json::array();
  std::vector<uint8_t> coverage;
  for (const SessionRecord& s : compacted.sessions()) {
    sessions.push_back({{"time_s", s.time_s},
                        {"name", s.name},
                        {"nodes_separate", s.nodes_separate},
                        {"nodes_added", s.nodes_added}});
    coverage.insert(coverage.end(), s.coverage.encoded().begin(), s.coverage.encoded().end());
  }
  j["sessions"] = std::move(sessions);
  if (extra && extra->is_object()) {
    for (const auto& [key, value] : extra->items()) j[key] = value;
  }
  const std::string text = j.dump();

  std::vector<CmapBlock> blocks;
  blocks.push_back({"META", std::vector<uint8_t>(text.begin(), text.end())});
  if (version == 1) {
    header.version = 1;
    blocks.push_back({"INNR", bytesOf(parts.inner)});
    blocks.push_back({"LSTS", bytesOf(parts.list_sizes)});
    blocks.push_back({"ENTR", entryBytes(parts.entries)});
    blocks.push_back({"COVR", std::move(coverage)});
    blocks.push_back({"EPOS", entryOffsetBytes(parts.entries)});
    return encodeCmap(header, blocks);
  }
  header.version = version;
  columns::encodeTree(parts.inner, blocks);
  blocks.push_back({kListSizes, listSizeBytes(parts.list_sizes)});
  blocks.push_back({kEntrySessions, sessionBytes(parts.list_sizes, parts.entries)});
  columns::encodeCounters(
      parts.entries.size(), [&](size_t i) -> const VoxelCounters& { return parts.entries[i].value; }, blocks,
      version);
  blocks.push_back({"COVR", std::move(coverage)});
  return encodeCmap(header, blocks);
}

}  // namespace

std::vector<uint8_t> encodeTemporalMap(const TemporalMap& map, const nlohmann::json& meta, MapKind kind,
                                       const nlohmann::json* extra, uint32_t version) {
  return encodeTemporal(map, meta, kind, extra, version, true);
}

std::vector<uint8_t> encodeTemporalMapAsItIs(const TemporalMap& map, const nlohmann::json& meta) {
  return encodeTemporal(map, meta, MapKind::Temporal, nullptr, kCmapFormatVersion, false);
}

namespace {

/// The change criterion and the session records (coverages left empty) of a 4D map's META block.
void describedIn(const CmapFile& file, const std::string& source, ChangeCriterion& criterion,
                 std::vector<SessionRecord>& sessions) {
  const CmapBlock& meta_block = file.block("META", source);
  const nlohmann::json j = nlohmann::json::parse(meta_block.data.begin(), meta_block.data.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("sessions") || !j["sessions"].is_array()) {
    throw FormatError(source + ": 4D map metadata is not a valid JSON description");
  }
  criterion = ChangeCriterion{};
  sessions.clear();
  try {
    if (j.contains("criterion")) {
      criterion.probability_threshold = j["criterion"].value("probability_threshold", 0.0);
      criterion.colour_distance = j["criterion"].value("color_distance", 0.0);
      criterion.surface_shift_voxels = j["criterion"].value("surface_shift_voxels", 0.0);
      const nlohmann::json& c = j["criterion"];
      if (c.contains("min_free_length_m") && !c["min_free_length_m"].is_number()) {
        throw FormatError(source + ": the criterion's min_free_length_m is not a number");
      }
      if (c.contains("min_hits") && (!c["min_hits"].is_number_unsigned() || c["min_hits"].get<uint64_t>() > 1000000)) {
        throw FormatError(source + ": the criterion's min_hits is not a whole number in [0, 1000000]");
      }
      criterion.min_free_length_m = c.value("min_free_length_m", 0.0);
      criterion.min_hits = static_cast<uint32_t>(c.value("min_hits", uint64_t{0}));
      criterion.validate();
    }
    for (const auto& s : j["sessions"]) {
      SessionRecord r;
      r.time_s = s.at("time_s").get<double>();
      r.name = s.value("name", std::string());
      r.nodes_separate = s.value("nodes_separate", uint64_t{0});
      r.nodes_added = s.value("nodes_added", int64_t{0});
      sessions.push_back(std::move(r));
    }
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(source + ": 4D map metadata is malformed: " + e.what());
  } catch (const UsageError& e) {
    throw FormatError(source + ": 4D map metadata is malformed: " + e.what());
  }
}

}  // namespace

TemporalMap decodeTemporalBlocks(const CmapFile& file, const std::string& source) {
  ChangeCriterion criterion;
  std::vector<SessionRecord> sessions;
  describedIn(file, source, criterion, sessions);
  const CmapBlock& cov = file.block("COVR", source);
  size_t pos = 0;
  for (SessionRecord& s : sessions) {
    try {
      s.coverage = Coverage::decodeFrom(cov.data, pos);
    } catch (const FormatError& e) {
      throw FormatError(source + ": " + e.what());
    }
  }
  if (pos != cov.data.size()) throw FormatError(source + ": coverage block has trailing bytes");

  TemporalMap::Parts parts;
  if (file.header.version == 1) {
    parts.inner = vectorOf<TemporalMap::Children>(file.block("INNR", source), source);
    parts.list_sizes = vectorOf<uint32_t>(file.block("LSTS", source), source);
    parts.entries = entriesOf(file, source);
  } else {
    parts = partsOfVersion2(file, source);
  }
  try {
    return TemporalMap::fromParts(file.header.resolution_m, criterion, std::move(parts), std::move(sessions));
  } catch (const FormatError& e) {
    throw FormatError(source + ": " + e.what());
  } catch (const UsageError& e) {
    throw FormatError(source + ": " + e.what());
  }
}

StoredSnapshot snapshotOfColumns(const CmapFile& file, const std::string& source, uint32_t rank) {
  if (file.header.kind != MapKind::Temporal) {
    throw FormatError(source + ": holds a " + std::string(kindName(file.header.kind)) + " map, not a 4D map");
  }
  if (file.header.version < 2 || !file.appended.empty()) {
    throw UsageError(source +
                     ": only a 4D map of format version 2 or later without appended sessions is read at one time");
  }
  columns::requireExactly(file, source,
                          columns::withCounterTags(file.header.version,
                                                   {"META", columns::kTreeMasks, columns::kTreeRefs, kListSizes,
                                                    kEntrySessions},
                                                   {"COVR"}));
  StoredSnapshot out{SessionMap(file.header.resolution_m), {}, {}};
  describedIn(file, source, out.criterion, out.sessions);  // (coverage: not read)
  size_t lists = 0;
  const std::vector<TemporalMap::Children> inner = columns::decodeTree(file, source, lists);
  // Each list's entry valid at `rank`: its last one of a session at or before it. Every
  // session number is read (varints, one list after another) and checked as fromParts checks it.
  columns::ByteReader sizes(file.block(kListSizes, source).data, source + ": block '" + kListSizes + "'");
  const CmapBlock& session_block = file.block(kEntrySessions, source);
  columns::ByteReader sessions(session_block.data, source + ": block '" + kEntrySessions + "'");
  std::vector<size_t> chosen;  // entry indices, increasing
  std::vector<uint32_t> chosen_list;
  chosen.reserve(lists);
  chosen_list.reserve(lists);
  size_t at = 0;
  for (size_t l = 0; l < lists; ++l) {
    const uint64_t n = sizes.varint();
    if (n == 0 || n > 0xffffu) sizes.fail("holds a history list of impossible length");
    uint64_t previous = 0;
    std::optional<size_t> valid;
    for (uint64_t k = 0; k < n; ++k, ++at) {
      const uint64_t gap = sessions.varint();
      if (gap > 0xffffffffu) sessions.fail("holds an impossible session number");
      const uint64_t v = gap + (k == 0 ? 0 : previous + 1);
      if (v > 0xffffffffu) sessions.fail("holds an impossible session number");
      if (v >= out.sessions.size()) throw FormatError(source + ": 4D map has a history entry with an invalid session");
      if (v <= rank) valid = at;
      previous = v;
    }
    if (valid) {
      chosen.push_back(*valid);
      chosen_list.push_back(static_cast<uint32_t>(l));
    }
  }
  sizes.expectEnd();
  sessions.expectEnd();
  std::vector<std::optional<VoxelCounters>> states(lists);
  std::vector<VoxelCounters> values(chosen.size());
  columns::decodeCountersOf(file, source, at, chosen, [&](size_t k) -> VoxelCounters& { return values[k]; });
  for (size_t k = 0; k < chosen.size(); ++k) states[chosen_list[k]] = values[k];
  try {
    out.map = TemporalMap::snapshotOfStates(file.header.resolution_m, inner, states);
  } catch (const FormatError& e) {
    throw FormatError(source + ": " + e.what());
  }
  return out;
}

TemporalMap temporalMapFrom(const CmapFile& file, const std::string& source) {
  if (file.header.kind != MapKind::Temporal) {
    throw FormatError(source + ": holds a " + std::string(kindName(file.header.kind)) + " map, not a 4D map");
  }
  TemporalMap map = decodeTemporalBlocks(file, source);
  for (size_t i = 0; i < file.appended.size(); ++i) {
    const std::string what = source + ": appended session " + std::to_string(i + 1);
    const CmapBlock& record = file.appended[i];
    if (record.tag != "ADDS") throw FormatError(what + " has the unknown tag '" + record.tag + "'");
    const CmapFile inner = decodeCmap(record.data, what);
    if (!inner.appended.empty() || inner.base_bytes != record.data.size()) {
      throw FormatError(what + " holds more than one session map");
    }
    const SessionMap session = sessionMapFrom(inner, what);
    const nlohmann::json meta = metadataOf(inner);
    AddSettings options;
    double time_s = 0.0;
    try {
      time_s = meta.at("time_s").get<double>();
      options.replace = meta.at("replace").get<bool>();
      options.name = meta.at("name").get<std::string>();
    } catch (const nlohmann::json::exception& e) {
      throw FormatError(what + ": its description is malformed: " + e.what());
    }
    try {
      map.add(time_s, session, options);
    } catch (const UsageError& e) {
      throw FormatError(what + " cannot be added again: " + e.what());
    }
  }
  return map;
}

TemporalMap asStored(const TemporalMap& map) {
  TemporalMap::Parts parts = map.parts();
  for (TemporalMap::Entry& e : parts.entries) e.value = asStored(e.value);
  return TemporalMap::fromParts(map.resolution_m(), map.criterion(), std::move(parts), map.sessions());
}

TemporalFileLayout layoutOf(const CmapFile& file) {
  TemporalFileLayout l;
  l.file_bytes = file.file_bytes;
  l.base_bytes = file.base_bytes;
  l.appended_bytes = file.complete_bytes - file.base_bytes;
  l.appended_sessions = file.appended.size();
  l.incomplete_tail_bytes = file.incomplete_tail_bytes;
  return l;
}

TemporalMap readTemporalMap(const std::filesystem::path& path, TemporalFileLayout* layout) {
  return readNamingMemory(path, [&] {
    const CmapFile file = readCmap(path);
    if (layout) *layout = layoutOf(file);
    return temporalMapFrom(file, path.string());
  });
}

std::vector<uint8_t> encodeSessionRecord(double time_s, const SessionMap& session, const AddSettings& options) {
  const nlohmann::json meta = {{"time_s", time_s}, {"replace", options.replace}, {"name", options.name}};
  CmapBlock record{"ADDS", encodeSessionMap(session, meta, /*zstd_level=*/0)};
  return encodeAppendRecord(record);
}

}  // namespace chronomap
