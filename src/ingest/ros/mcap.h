#pragma once
// A reader of MCAP files (internal), written to the published MCAP format specification
// (major version 0): the records of the data section, chunks stored uncompressed or compressed
// with lz4 (frame format) or zstd, and the summary section's schemas, channels and chunk
// indexes when the file has them; a file without a summary is read by scanning its records.
// Checked on the way: the magic at both ends, every record length against the bytes that hold
// it, each chunk's stated sizes and CRC, the summary's CRC, and (when scanning) the data
// section's CRC. Every error is a FormatError naming the file and the offset.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace chronomap::mcap {

struct Schema {
  uint16_t id = 0;
  std::string name;      ///< e.g. "sensor_msgs/msg/Image"
  std::string encoding;  ///< e.g. "ros2msg"
};

struct Channel {
  uint16_t id = 0;
  uint16_t schema_id = 0;  ///< 0: none
  std::string topic;
  std::string message_encoding;  ///< e.g. "cdr"
};

/// Where a message's data lie: in the chunk whose record starts at `chunk` (its decompressed
/// records, at `offset`), or, with chunk == kNoChunk, in the file at `offset`.
struct MessageRef {
  static constexpr uint64_t kNoChunk = ~uint64_t{0};
  uint64_t chunk = kNoChunk;
  uint64_t offset = 0;
  uint64_t size = 0;
};

/// One message as the scan meets it; `data` is valid during the callback only.
struct Message {
  uint16_t channel = 0;
  uint64_t log_time = 0;  ///< nanoseconds
  MessageRef ref;
  std::span<const uint8_t> data;
};

/// A message's bytes with what keeps them alive.
struct MessageBytes {
  std::span<const uint8_t> data;
  std::shared_ptr<const void> owner;
};

/// Claimed decompressed sizes are limited to this many times the stored size: lz4's most
/// (a 255-byte run per byte of match length) and zstd's (a 4-byte RLE block yields 128 KiB).
inline constexpr uint64_t kMaxLz4Ratio = 256;
inline constexpr uint64_t kMaxZstdRatio = 32768;

class Reader {
 public:
  /// Opens the file and reads its footer and, when present, its summary.
  /// @throw UsageError when the file does not exist; FormatError when it is no MCAP file.
  explicit Reader(const std::filesystem::path& path);
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  /// Every message in the order the file stores them; schemas and channels are known before
  /// their messages. The channels met on the way are added to channels().
  void forEachMessage(const std::function<void(const Message&)>& fn);
  /// The bytes of one message met by forEachMessage (thread-safe; the last chunk is cached).
  MessageBytes message(const MessageRef& ref) const;

  const std::map<uint16_t, Schema>& schemas() const { return schemas_; }
  const std::map<uint16_t, Channel>& channels() const { return channels_; }
  /// True when the summary's chunk indexes lead the reading (else the data section is scanned).
  bool indexed() const { return !chunk_offsets_.empty(); }
  /// A file cut short (a recorder killed, a copy interrupted): no magic at its end. It is read
  /// as `mcap recover` reads one: the data section record by record up to the first record the
  /// cut left incomplete. After forEachMessage, what was read and what was lost, in words
  /// ("cut short at byte 5,000 of ...: 31 messages read, the last 2,113 bytes lost"); empty for
  /// a whole file.
  bool truncated() const { return truncated_; }
  std::string truncationNote() const;
  const std::filesystem::path& path() const { return path_; }

 private:
  struct Chunk;
  void readBytes(uint64_t offset, uint64_t size, uint8_t* out) const;
  std::vector<uint8_t> readVector(uint64_t offset, uint64_t size) const;
  void readSummary(uint64_t summary_start, uint64_t summary_end, uint64_t footer_at, uint32_t crc);
  /// The chunk record at `offset` (opcode and length included), decompressed and checked.
  std::shared_ptr<const std::vector<uint8_t>> chunk(uint64_t offset) const;
  /// The records of a decompressed chunk: schemas, channels and messages.
  void chunkRecords(uint64_t chunk_at, const std::vector<uint8_t>& records,
                    const std::function<void(const Message&)>& fn);
  /// Reads a schema, channel or message record (of the chunk at `chunk_at`, or kNoChunk) whose
  /// body lies at `body_at`; false for any other kind of record.
  bool record(uint8_t op, std::span<const uint8_t> body, const std::string& where, uint64_t chunk_at,
              uint64_t body_at, const std::function<void(const Message&)>& fn);
  [[noreturn]] void fail(uint64_t offset, const std::string& problem) const;

  std::filesystem::path path_;
  int fd_ = -1;
  uint64_t size_ = 0;
  std::map<uint16_t, Schema> schemas_;
  std::map<uint16_t, Channel> channels_;
  std::vector<uint64_t> chunk_offsets_;  ///< from the summary's chunk indexes, in file order
  bool truncated_ = false;
  uint64_t intact_bytes_ = 0;     ///< where the first incomplete record starts (truncated files)
  uint64_t messages_read_ = 0;    ///< messages met before it
  bool data_whole_ = false;       ///< the cut lies after the data section's end record
  mutable std::mutex mutex_;
  mutable uint64_t cached_at_ = MessageRef::kNoChunk;
  mutable std::shared_ptr<const std::vector<uint8_t>> cached_;
};

}  // namespace chronomap::mcap
