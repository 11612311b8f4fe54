// MCAP, written to the format specification (mcap.dev/spec), major version 0.

#include "chronomap/export/mcap_writer.h"

#include <zstd.h>

#include <algorithm>
#include <span>
#include <tuple>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/mcap_records.h"

namespace chronomap {

namespace {

void putString(ByteWriter& w, std::string_view s) {
  w.put(static_cast<uint32_t>(s.size()));
  w.bytes.insert(w.bytes.end(), s.begin(), s.end());
}

void appendRecord(std::vector<uint8_t>& out, uint8_t op, const std::vector<uint8_t>& content) {
  ByteWriter head;
  head.put(op);
  head.put(static_cast<uint64_t>(content.size()));
  out.insert(out.end(), head.bytes.begin(), head.bytes.end());
  out.insert(out.end(), content.begin(), content.end());
}

std::vector<uint8_t> zstdCompress(const std::vector<uint8_t>& in, int level) {
  std::vector<uint8_t> out(ZSTD_compressBound(in.size()));
  const size_t n = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), level);
  if (ZSTD_isError(n)) throw IoError(std::string("MCAP chunk: zstd: ") + ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

}  // namespace

struct McapWriter::ChunkIndex {
  uint64_t start_ns = 0, end_ns = 0, chunk_at = 0, chunk_length = 0;
  std::map<uint16_t, uint64_t> message_index_offsets;
  uint64_t message_index_length = 0;
  std::string compression;
  uint64_t compressed_size = 0, uncompressed_size = 0;
};

McapWriter::McapWriter(McapWriterSettings settings) : settings_(std::move(settings)) {
  if (settings_.zstd_level < 0 || settings_.zstd_level > 19) {
    throw UsageError("MCAP writer: zstd level " + std::to_string(settings_.zstd_level) + " is not 0 (none) to 19");
  }
  if (settings_.chunk_bytes == 0) throw UsageError("MCAP writer: a chunk size of 0 bytes; give at least 1");
  file_.assign(std::begin(mcap::kMagic), std::end(mcap::kMagic));
  ByteWriter header;
  putString(header, settings_.profile);
  putString(header, settings_.library);
  appendRecord(file_, mcap::kHeader, header.bytes);
}

McapWriter::~McapWriter() = default;

uint16_t McapWriter::addSchema(const std::string& name, const std::string& encoding, std::string_view data) {
  const auto id = static_cast<uint16_t>(schemas_.size() + 1);
  ByteWriter w;
  w.put(id);
  putString(w, name);
  putString(w, encoding);
  putString(w, data);
  appendRecord(file_, mcap::kSchema, w.bytes);
  appendRecord(schema_records_, mcap::kSchema, w.bytes);
  schemas_[id] = true;
  return id;
}

uint16_t McapWriter::addChannel(uint16_t schema_id, const std::string& topic, const std::string& message_encoding) {
  if (schema_id != 0 && !schemas_.count(schema_id)) {
    throw UsageError("MCAP writer: channel '" + topic + "' names schema " + std::to_string(schema_id) + ", which was not added");
  }
  const auto id = static_cast<uint16_t>(channels_.size() + 1);
  ByteWriter w;
  w.put(id);
  w.put(schema_id);
  putString(w, topic);
  putString(w, message_encoding);
  w.put(uint32_t{0});  // metadata: an empty map
  appendRecord(file_, mcap::kChannel, w.bytes);
  appendRecord(channel_records_, mcap::kChannel, w.bytes);
  channels_[id] = true;
  message_counts_[id] = 0;
  return id;
}

void McapWriter::addMessage(uint16_t channel_id, uint64_t log_time_ns, std::string_view data) {
  if (finished_) throw UsageError("MCAP writer: a message added after finish()");
  if (!channels_.count(channel_id)) {
    throw UsageError("MCAP writer: a message on channel " + std::to_string(channel_id) + ", which was not added");
  }
  if (chunk_.empty()) chunk_start_ns_ = chunk_end_ns_ = log_time_ns;
  chunk_start_ns_ = std::min(chunk_start_ns_, log_time_ns);
  chunk_end_ns_ = std::max(chunk_end_ns_, log_time_ns);
  if (messages_ == 0) start_ns_ = end_ns_ = log_time_ns;
  start_ns_ = std::min(start_ns_, log_time_ns);
  end_ns_ = std::max(end_ns_, log_time_ns);
  chunk_messages_[channel_id].emplace_back(log_time_ns, chunk_.size());
  ByteWriter w;
  w.put(channel_id);
  w.put(static_cast<uint32_t>(message_counts_[channel_id]));  // sequence
  w.put(log_time_ns);
  w.put(log_time_ns);  // publish time
  w.bytes.insert(w.bytes.end(), data.begin(), data.end());
  appendRecord(chunk_, mcap::kMessage, w.bytes);
  ++message_counts_[channel_id];
  ++messages_;
  if (chunk_.size() >= settings_.chunk_bytes) closeChunk();
}

void McapWriter::closeChunk() {
  if (chunk_.empty()) return;
  ChunkIndex index;
  index.start_ns = chunk_start_ns_;
  index.end_ns = chunk_end_ns_;
  index.uncompressed_size = chunk_.size();
  const std::vector<uint8_t> stored = settings_.zstd_level > 0 ? zstdCompress(chunk_, settings_.zstd_level) : chunk_;
  index.compression = settings_.zstd_level > 0 ? "zstd" : "";
  index.compressed_size = stored.size();
  ByteWriter w;
  w.put(chunk_start_ns_);
  w.put(chunk_end_ns_);
  w.put(static_cast<uint64_t>(chunk_.size()));
  w.put(mcap::crc32(chunk_));
  putString(w, index.compression);
  w.put(static_cast<uint64_t>(stored.size()));
  w.bytes.insert(w.bytes.end(), stored.begin(), stored.end());
  index.chunk_at = file_.size();
  appendRecord(file_, mcap::kChunk, w.bytes);
  index.chunk_length = file_.size() - index.chunk_at;
  // One message index per channel of the chunk: where each of its messages lies in the records.
  const uint64_t indexes_at = file_.size();
  for (const auto& [channel, entries] : chunk_messages_) {
    ByteWriter m;
    m.put(channel);
    m.put(static_cast<uint32_t>(entries.size() * 16));
    for (const auto& [time_ns, offset] : entries) {
      m.put(time_ns);
      m.put(offset);
    }
    index.message_index_offsets[channel] = file_.size();
    appendRecord(file_, mcap::kMessageIndex, m.bytes);
  }
  index.message_index_length = file_.size() - indexes_at;
  chunk_indexes_.push_back(std::move(index));
  chunk_.clear();
  chunk_messages_.clear();
}

std::vector<uint8_t> McapWriter::finish() {
  if (finished_) throw UsageError("MCAP writer: finish() called twice");
  closeChunk();
  finished_ = true;
  ByteWriter data_end;
  data_end.put(mcap::crc32(file_));
  appendRecord(file_, mcap::kDataEnd, data_end.bytes);

  // The summary: schemas, channels, statistics, chunk indexes, each group found by an offset.
  const uint64_t summary_at = file_.size();
  std::vector<std::tuple<uint8_t, uint64_t, uint64_t>> groups;  // opcode, start, length
  const auto group = [&](uint8_t op, const std::vector<uint8_t>& records) {
    if (records.empty()) return;
    groups.emplace_back(op, file_.size(), records.size());
    file_.insert(file_.end(), records.begin(), records.end());
  };
  group(mcap::kSchema, schema_records_);
  group(mcap::kChannel, channel_records_);
  ByteWriter stats;
  stats.put(messages_);
  stats.put(static_cast<uint16_t>(schemas_.size()));
  stats.put(static_cast<uint32_t>(channels_.size()));
  stats.put(uint32_t{0});  // attachments
  stats.put(uint32_t{0});  // metadata
  stats.put(static_cast<uint32_t>(chunk_indexes_.size()));
  stats.put(start_ns_);
  stats.put(end_ns_);
  stats.put(static_cast<uint32_t>(message_counts_.size() * 10));
  for (const auto& [channel, count] : message_counts_) {
    stats.put(channel);
    stats.put(count);
  }
  std::vector<uint8_t> stats_record;
  appendRecord(stats_record, mcap::kStatistics, stats.bytes);
  group(mcap::kStatistics, stats_record);
  std::vector<uint8_t> index_records;
  for (const ChunkIndex& c : chunk_indexes_) {
    ByteWriter w;
    w.put(c.start_ns);
    w.put(c.end_ns);
    w.put(c.chunk_at);
    w.put(c.chunk_length);
    w.put(static_cast<uint32_t>(c.message_index_offsets.size() * 10));
    for (const auto& [channel, offset] : c.message_index_offsets) {
      w.put(channel);
      w.put(offset);
    }
    w.put(c.message_index_length);
    putString(w, c.compression);
    w.put(c.compressed_size);
    w.put(c.uncompressed_size);
    appendRecord(index_records, mcap::kChunkIndex, w.bytes);
  }
  group(mcap::kChunkIndex, index_records);

  const uint64_t offsets_at = file_.size();
  for (const auto& [op, start, length] : groups) {
    ByteWriter w;
    w.put(op);
    w.put(start);
    w.put(length);
    appendRecord(file_, mcap::kSummaryOffset, w.bytes);
  }
  // The footer; its CRC covers the summary through the footer's summary_offset_start.
  ByteWriter footer;
  footer.put(static_cast<uint8_t>(mcap::kFooter));
  footer.put(mcap::kFooterContent);
  footer.put(summary_at);
  footer.put(offsets_at);
  file_.insert(file_.end(), footer.bytes.begin(), footer.bytes.end());
  ByteWriter crc;
  crc.put(mcap::crc32(std::span<const uint8_t>(file_).subspan(summary_at)));
  file_.insert(file_.end(), crc.bytes.begin(), crc.bytes.end());
  file_.insert(file_.end(), std::begin(mcap::kMagic), std::end(mcap::kMagic));
  return std::move(file_);
}

size_t McapWriter::write(const std::filesystem::path& path) {
  const std::vector<uint8_t> bytes = finish();
  writeFileAtomic(path, bytes);
  return bytes.size();
}

}  // namespace chronomap
