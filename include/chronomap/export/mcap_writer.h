#pragma once
/// @file
/// A writer of MCAP files (the published specification, major version 0), the container
/// Foxglove plays: messages in zstd-compressed chunks, each chunk followed by its message
/// indexes, and a summary (schemas, channels, statistics, chunk indexes, summary offsets) that
/// lets a reader seek by time. The layout of the files the official writers make; the framing
/// and CRC are the reader's (ingest/mcap_records.h).

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace chronomap {

/// How McapWriter writes.
struct McapWriterSettings {
  /// zstd level of the chunks (1..19); 0 stores them uncompressed.
  int zstd_level = 3;
  /// A chunk is closed once its records hold this many bytes (a message is never split).
  size_t chunk_bytes = size_t{4} << 20;
  std::string profile;                ///< the header's profile ("" : none in particular)
  std::string library = "chronomap";  ///< the header's library
};

/// Builds an MCAP file in memory; finish() returns its bytes, write() puts them in a file.
class McapWriter {
 public:
  /// @throw UsageError for a zstd level outside 0..19 or a chunk size of 0.
  explicit McapWriter(McapWriterSettings settings = {});
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Adds a schema; @return its id (1, 2, ...).
  uint16_t addSchema(const std::string& name, const std::string& encoding, std::string_view data);
  /// Adds a channel of a schema (0: none); @return its id (1, 2, ...).
  /// @throw UsageError for a schema id not added.
  uint16_t addChannel(uint16_t schema_id, const std::string& topic, const std::string& message_encoding);
  /// Adds a message at `log_time_ns` (nanoseconds since the epoch; also its publish time).
  /// @throw UsageError for a channel id not added.
  void addMessage(uint16_t channel_id, uint64_t log_time_ns, std::string_view data);

  /// Messages added so far, per channel id.
  const std::map<uint16_t, uint64_t>& messageCounts() const { return message_counts_; }

  /// Closes the last chunk and appends the data end, the summary and the footer.
  /// @return the whole file; the writer takes nothing more after it.
  std::vector<uint8_t> finish();
  /// finish(), written to `path` atomically. @return the bytes written.
  size_t write(const std::filesystem::path& path);

 private:
  struct ChunkIndex;
  void closeChunk();

  McapWriterSettings settings_;
  std::vector<uint8_t> file_;            ///< magic, header, schemas, channels, chunks so far
  std::vector<uint8_t> schema_records_;  ///< again for the summary
  std::vector<uint8_t> channel_records_;
  std::map<uint16_t, bool> schemas_, channels_;
  std::map<uint16_t, uint64_t> message_counts_;
  // The open chunk: its records, time span and per channel (log time, offset) of its messages.
  std::vector<uint8_t> chunk_;
  uint64_t chunk_start_ns_ = 0, chunk_end_ns_ = 0;
  std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> chunk_messages_;
  std::vector<ChunkIndex> chunk_indexes_;
  uint64_t messages_ = 0, start_ns_ = 0, end_ns_ = 0;
  bool finished_ = false;
};

}  // namespace chronomap
