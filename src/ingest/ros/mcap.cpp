// MCAP, read to the format specification (mcap.dev/spec), major version 0.

#include "mcap.h"

#include <fcntl.h>
#include <lz4frame.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string_view>

#include "chronomap/core/error.h"
#include "chronomap/ingest/mcap_records.h"

namespace chronomap::mcap {

namespace fs = std::filesystem;

namespace {

/// Little-endian fields of one record's content; a field past the end is a FormatError
/// naming `where`.
class Cursor {
 public:
  Cursor(std::span<const uint8_t> bytes, std::string where) : b_(bytes), where_(std::move(where)) {}
  uint8_t u8() { return static_cast<uint8_t>(le(1)); }
  uint16_t u16() { return static_cast<uint16_t>(le(2)); }
  uint32_t u32() { return static_cast<uint32_t>(le(4)); }
  uint64_t u64() { return le(8); }
  std::span<const uint8_t> bytes(uint64_t n) {
    need(n);
    auto out = b_.subspan(pos_, n);
    pos_ += n;
    return out;
  }
  std::string str() {
    const auto s = bytes(u32());
    return {reinterpret_cast<const char*>(s.data()), s.size()};
  }
  /// A map or array stored with a u32 byte length, as a cursor of its own.
  Cursor sub32(const char* what) { return Cursor(bytes(u32()), where_ + ", " + what); }
  std::span<const uint8_t> rest() { return bytes(b_.size() - pos_); }
  bool done() const { return pos_ == b_.size(); }
  size_t pos() const { return pos_; }

 private:
  void need(uint64_t n) const {
    if (n > b_.size() - pos_) {
      throw FormatError(where_ + ": a field needs " + std::to_string(n) + " bytes, the record has " +
                        std::to_string(b_.size() - pos_) + " left");
    }
  }
  uint64_t le(int n) {
    need(static_cast<uint64_t>(n));
    uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | b_[pos_ + static_cast<size_t>(i)];
    pos_ += static_cast<size_t>(n);
    return v;
  }
  std::span<const uint8_t> b_;
  size_t pos_ = 0;
  std::string where_;
};

std::vector<uint8_t> lz4Decompress(std::span<const uint8_t> in, uint64_t size, const std::string& where) {
  if (size > kMaxLz4Ratio * in.size() + 1024) {
    throw FormatError(where + ": lz4 chunk claims " + std::to_string(size) + " bytes from " +
                      std::to_string(in.size()) + " (more than lz4 can pack)");
  }
  std::vector<uint8_t> out(size);
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) throw FormatError(where + ": lz4: no memory");
  size_t in_pos = 0, out_pos = 0, hint = 1;
  while (hint != 0 && in_pos < in.size()) {
    size_t in_n = in.size() - in_pos, out_n = out.size() - out_pos;
    hint = LZ4F_decompress(ctx, out.data() + out_pos, &out_n, in.data() + in_pos, &in_n, nullptr);
    if (LZ4F_isError(hint)) {
      const std::string name = LZ4F_getErrorName(hint);
      LZ4F_freeDecompressionContext(ctx);
      throw FormatError(where + ": lz4: " + name);
    }
    in_pos += in_n;
    out_pos += out_n;
    if (in_n == 0 && out_n == 0) break;  // the output is full and the frame wants more room
  }
  LZ4F_freeDecompressionContext(ctx);
  if (hint != 0 || out_pos != out.size()) {
    throw FormatError(where + ": lz4 frame gives " + (hint != 0 ? std::string("more or less than ") : std::string()) +
                      std::to_string(out_pos) + " bytes, the chunk states " + std::to_string(size));
  }
  return out;
}

std::vector<uint8_t> zstdDecompress(std::span<const uint8_t> in, uint64_t size, const std::string& where) {
  if (size > kMaxZstdRatio * in.size()) {
    throw FormatError(where + ": zstd chunk claims " + std::to_string(size) + " bytes from " +
                      std::to_string(in.size()) + " (more than zstd can pack)");
  }
  // Sized by what the frame yields, not by the claim alone (docs/reliability.md, "Limits").
  std::vector<uint8_t> out(std::min<uint64_t>(size, std::max<uint64_t>(64 * in.size(), 64u << 20)));
  ZSTD_DStream* ds = ZSTD_createDStream();
  if (!ds) throw FormatError(where + ": zstd: no memory");
  ZSTD_inBuffer ib{in.data(), in.size(), 0};
  ZSTD_outBuffer ob{out.data(), out.size(), 0};
  size_t ret = 1;
  while (true) {
    ret = ZSTD_decompressStream(ds, &ob, &ib);
    if (ZSTD_isError(ret)) {
      const std::string name = ZSTD_getErrorName(ret);
      ZSTD_freeDStream(ds);
      throw FormatError(where + ": zstd: " + name);
    }
    if (ret == 0 && ib.pos == ib.size) break;
    if (ob.pos == ob.size) {
      if (out.size() >= size) break;  // more than claimed
      out.resize(std::min<uint64_t>(size, out.size() * 4));
      ob.dst = out.data();
      ob.size = out.size();
    } else if (ib.pos == ib.size) {
      break;  // the input ends inside a frame
    }
  }
  ZSTD_freeDStream(ds);
  if (ret != 0 || ib.pos != ib.size || ob.pos != size) {
    throw FormatError(where + ": zstd data give " + (ret != 0 ? std::string("a truncated frame of ") : std::string()) +
                      std::to_string(ob.pos) + " bytes, the chunk states " + std::to_string(size));
  }
  out.resize(size);
  return out;
}

std::string offsetText(uint64_t offset) { return "byte " + std::to_string(offset); }

}  // namespace

Reader::Reader(const fs::path& path) : path_(path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file");
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw IoError(path.string() + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd_);
    throw UsageError(path.string() + ": not a regular file");
  }
  size_ = static_cast<uint64_t>(st.st_size);
  try {
    // Leading magic and header record; trailing footer and magic.
    const uint64_t least = 8 + kRecordHead + 8 + kRecordHead + kFooterContent + 8;
    uint8_t head[8] = {};
    readBytes(0, std::min<uint64_t>(size_, 8), head);
    if (std::memcmp(head, kMagic, static_cast<size_t>(std::min<uint64_t>(size_, 5))) != 0) {
      fail(0, "not an MCAP file (no MCAP magic)");
    }
    if (size_ < 8 + kRecordHead) fail(0, "too short for an MCAP file (" + std::to_string(size_) + " bytes; truncated?)");
    if (head[5] != '0') fail(5, "MCAP major version '" + std::string(1, static_cast<char>(head[5])) + "' is not read");
    if (std::memcmp(head, kMagic, 8) != 0) fail(0, "not an MCAP file (no MCAP magic)");
    uint8_t op = 0;
    readBytes(8, 1, &op);
    if (op != kHeader) fail(8, "the first record is not a header");
    if (size_ < least) {
      truncated_ = true;
      return;
    }
    uint8_t tail[8];
    readBytes(size_ - 8, 8, tail);
    if (std::memcmp(tail, kMagic, 8) != 0) {
      truncated_ = true;  // no footer to trust: the data section is scanned up to the cut
      return;
    }
    const uint64_t footer_at = size_ - 8 - kRecordHead - kFooterContent;
    const std::vector<uint8_t> footer = readVector(footer_at, kRecordHead + kFooterContent);
    Cursor fc(footer, path_.string() + ": footer");
    if (fc.u8() != kFooter || fc.u64() != kFooterContent) fail(footer_at, "no footer record before the end magic");
    const uint64_t summary_start = fc.u64(), summary_offset_start = fc.u64();
    const uint32_t summary_crc = fc.u32();
    if (summary_start != 0) {
      const uint64_t summary_end = summary_offset_start != 0 ? summary_offset_start : footer_at;
      if (summary_start < 8 + kRecordHead || summary_start > footer_at || summary_end < summary_start ||
          summary_end > footer_at) {
        fail(footer_at, "the footer's summary offsets lie outside the file");
      }
      readSummary(summary_start, summary_end, footer_at, summary_crc);
    }
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

Reader::~Reader() {
  if (fd_ >= 0) ::close(fd_);
}

void Reader::fail(uint64_t offset, const std::string& problem) const {
  throw FormatError(path_.string() + ": " + offsetText(offset) + ": " + problem);
}

void Reader::readBytes(uint64_t offset, uint64_t size, uint8_t* out) const {
  if (offset > size_ || size > size_ - offset) fail(offset, "reads past the end of the file (truncated?)");
  uint64_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd_, out + done, static_cast<size_t>(std::min<uint64_t>(size - done, 1u << 30)),
                              static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw IoError(path_.string() + ": read failed at " + offsetText(offset + done));
    done += static_cast<uint64_t>(n);
  }
}

std::vector<uint8_t> Reader::readVector(uint64_t offset, uint64_t size) const {
  if (offset > size_ || size > size_ - offset) fail(offset, "reads past the end of the file (truncated?)");
  std::vector<uint8_t> out(size);
  readBytes(offset, size, out.data());
  return out;
}

void Reader::readSummary(uint64_t start, uint64_t end, uint64_t footer_at, uint32_t crc) {
  const std::vector<uint8_t> summary = readVector(start, end - start);
  if (crc != 0) {
    // Everything from the summary's start through the footer's summary_offset_start field.
    const std::vector<uint8_t> between = readVector(end, footer_at + kRecordHead + 16 - end);
    if (crc32(between, crc32(summary)) != crc) fail(start, "the summary section's CRC does not match");
  }
  std::vector<std::pair<uint64_t, uint64_t>> chunks;  // (offset, length)
  uint64_t pos = 0;
  while (pos < summary.size()) {
    const uint64_t at = start + pos;
    Cursor head(std::span<const uint8_t>(summary).subspan(pos), path_.string() + ": summary " + offsetText(at));
    const uint8_t op = head.u8();
    const uint64_t len = head.u64();
    if (len > summary.size() - pos - kRecordHead) fail(at, "a summary record runs past the summary section");
    const std::span<const uint8_t> body = head.bytes(len);
    const std::string where = path_.string() + ": summary " + offsetText(at);
    pos += kRecordHead + len;
    if (op == kSchema || op == kChannel) {
      record(op, body, where, MessageRef::kNoChunk, 0, {});
    } else if (op == kChunkIndex) {
      Cursor c(body, where);
      c.u64();  // message_start_time
      c.u64();  // message_end_time
      const uint64_t chunk_at = c.u64(), chunk_length = c.u64();
      if (chunk_at < 8 || chunk_at > size_ || chunk_length > size_ - chunk_at || chunk_length < kRecordHead) {
        fail(at, "a chunk index points outside the file");
      }
      chunks.emplace_back(chunk_at, chunk_length);
    }
  }
  std::sort(chunks.begin(), chunks.end());
  for (const auto& [at, length] : chunks) chunk_offsets_.push_back(at);
}

std::shared_ptr<const std::vector<uint8_t>> Reader::chunk(uint64_t offset) const {
  uint8_t head[kRecordHead];
  readBytes(offset, kRecordHead, head);
  Cursor hc(head, path_.string() + ": " + offsetText(offset));
  if (hc.u8() != kChunk) fail(offset, "a chunk index points at a record that is not a chunk");
  const uint64_t len = hc.u64();
  if (len > size_ - offset - kRecordHead) fail(offset, "the chunk's length runs past the end of the file");
  const std::vector<uint8_t> body = readVector(offset + kRecordHead, len);
  const std::string where = path_.string() + ": chunk at " + offsetText(offset);
  Cursor c(body, where);
  c.u64();  // message_start_time
  c.u64();  // message_end_time
  const uint64_t uncompressed_size = c.u64();
  const uint32_t uncompressed_crc = c.u32();
  const std::string compression = c.str();
  const uint64_t records_len = c.u64();
  const auto records = c.bytes(records_len);
  std::vector<uint8_t> out;
  if (compression.empty()) {
    if (uncompressed_size != records.size()) {
      fail(offset, "uncompressed chunk of " + std::to_string(records.size()) + " bytes states " +
                       std::to_string(uncompressed_size));
    }
    out.assign(records.begin(), records.end());
  } else if (compression == "lz4") {
    out = lz4Decompress(records, uncompressed_size, where);
  } else if (compression == "zstd") {
    out = zstdDecompress(records, uncompressed_size, where);
  } else {
    fail(offset, "unknown chunk compression '" + compression + "' (read: none, lz4, zstd)");
  }
  if (uncompressed_crc != 0 && crc32(out) != uncompressed_crc) fail(offset, "the chunk's CRC does not match its data");
  return std::make_shared<const std::vector<uint8_t>>(std::move(out));
}

void Reader::chunkRecords(uint64_t chunk_at, const std::vector<uint8_t>& records,
                          const std::function<void(const Message&)>& fn) {
  const std::span<const uint8_t> all(records);
  uint64_t pos = 0;
  while (pos < all.size()) {
    const std::string where = path_.string() + ": chunk at " + offsetText(chunk_at) + ", record at " +
                              std::to_string(pos);
    Cursor head(all.subspan(pos), where);
    const uint8_t op = head.u8();
    const uint64_t len = head.u64();
    if (len > all.size() - pos - kRecordHead) throw FormatError(where + ": the record runs past the chunk's end");
    const std::span<const uint8_t> body = head.bytes(len);
    const uint64_t body_at = pos + kRecordHead;
    pos += kRecordHead + len;
    record(op, body, where, chunk_at, body_at, fn);
  }
}

bool Reader::record(uint8_t op, std::span<const uint8_t> body, const std::string& where, uint64_t chunk_at,
                    uint64_t body_at, const std::function<void(const Message&)>& fn) {
  Cursor c(body, where);
  if (op == kSchema) {
    Schema s;
    s.id = c.u16();
    s.name = c.str();
    s.encoding = c.str();
    schemas_[s.id] = s;
  } else if (op == kChannel) {
    Channel ch;
    ch.id = c.u16();
    ch.schema_id = c.u16();
    ch.topic = c.str();
    ch.message_encoding = c.str();
    channels_[ch.id] = ch;
  } else if (op == kMessage) {
    Message m;
    m.channel = c.u16();
    c.u32();  // sequence
    m.log_time = c.u64();
    c.u64();  // publish_time
    m.data = c.rest();
    if (!channels_.count(m.channel)) {
      throw FormatError(where + ": a message on channel " + std::to_string(m.channel) + ", which no channel record defines");
    }
    m.ref = {chunk_at, body_at + 22, m.data.size()};
    fn(m);
  } else {
    return false;
  }
  return true;
}

void Reader::forEachMessage(const std::function<void(const Message&)>& fn) {
  if (indexed()) {
    for (uint64_t at : chunk_offsets_) {
      const auto records = chunk(at);
      chunkRecords(at, *records, fn);
    }
    return;
  }
  // No chunk index: the data section, record by record, with its CRC. A truncated file ends at
  // the first record the cut left incomplete.
  uint64_t pos = 8;
  uint32_t crc = crc32(std::span<const uint8_t>(kMagic, 8));
  messages_read_ = 0;
  const auto counted = [&](const Message& m) {
    ++messages_read_;
    fn(m);
  };
  while (true) {
    if (size_ - pos < kRecordHead) {
      if (!truncated_) fail(pos, "the file ends inside a record (truncated?)");
      intact_bytes_ = pos;
      break;
    }
    uint8_t head[kRecordHead];
    readBytes(pos, kRecordHead, head);
    Cursor hc(head, path_.string() + ": " + offsetText(pos));
    const uint8_t op = hc.u8();
    const uint64_t len = hc.u64();
    if (op == kFooter) break;  // no data end record: an older writer
    if (len > size_ - pos - kRecordHead) {
      if (!truncated_) fail(pos, "the record's length runs past the end of the file (truncated?)");
      intact_bytes_ = pos;
      break;
    }
    if (op == kDataEnd) {
      const std::vector<uint8_t> body = readVector(pos + kRecordHead, len);
      Cursor c(body, path_.string() + ": data end at " + offsetText(pos));
      const uint32_t stated = c.u32();
      if (stated != 0 && stated != crc) fail(pos, "the data section's CRC does not match");
      intact_bytes_ = pos + kRecordHead + len;
      data_whole_ = true;
      break;
    }
    crc = crc32(head, crc);
    const uint64_t at = pos;
    const std::vector<uint8_t> body = readVector(pos + kRecordHead, len);
    crc = crc32(body, crc);
    pos += kRecordHead + len;
    const std::string where = path_.string() + ": " + offsetText(at);
    if (record(op, body, where, MessageRef::kNoChunk, at + kRecordHead, counted)) continue;
    if (op == kChunk) {
      const auto records = chunk(at);
      chunkRecords(at, *records, counted);
    } else if (op == kHeader && at != 8) {
      fail(at, "a second header record");
    }
  }
}

std::string Reader::truncationNote() const {
  if (!truncated_) return {};
  if (intact_bytes_ == 0) return "cut short (no MCAP magic at its end): not read yet";
  if (data_whole_) {
    return "cut short (no MCAP magic at its end) after its data section: all " + std::to_string(messages_read_) +
           " message(s) read; only the index after them (the last " + std::to_string(size_ - intact_bytes_) +
           " bytes) is lost";
  }
  return "cut short (no MCAP magic at its end): " + std::to_string(messages_read_) +
         " message(s) read from its first " + std::to_string(intact_bytes_) + " bytes; the last " +
         std::to_string(size_ - intact_bytes_) + " bytes (an incomplete record) are lost";
}

MessageBytes Reader::message(const MessageRef& ref) const {
  if (ref.chunk == MessageRef::kNoChunk) {
    auto bytes = std::make_shared<std::vector<uint8_t>>(readVector(ref.offset, ref.size));
    return {std::span<const uint8_t>(*bytes), bytes};
  }
  std::shared_ptr<const std::vector<uint8_t>> records;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (cached_at_ != ref.chunk) {
      cached_ = chunk(ref.chunk);
      cached_at_ = ref.chunk;
    }
    records = cached_;
  }
  if (ref.offset > records->size() || ref.size > records->size() - ref.offset) {
    fail(ref.chunk, "a message lies outside its chunk");
  }
  return {std::span<const uint8_t>(*records).subspan(ref.offset, ref.size), records};
}

}  // namespace chronomap::mcap
