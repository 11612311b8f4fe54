// The structural check of ROS 1 bags that runs before librosbag reads one (rosbag1.h). It
// checks record framing only; librosbag still does all the reading and deserialisation.

#include <bzlib.h>
#include <roslz4/lz4s.h>

#include <cstring>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "rosbag1.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr size_t kMagicBytes = sizeof(kMagic) - 1;
constexpr uint8_t kOpMessage = 0x02, kOpBagHeader = 0x03, kOpIndex = 0x04, kOpChunk = 0x05, kOpChunkInfo = 0x06,
                  kOpConnection = 0x07;
/// Larger headers mean a broken length: real ones hold a few named fields and a message definition.
constexpr uint32_t kMaxHeaderBytes = 16u << 20;
/// librosbag holds a chunk in memory; real recorders write chunks of about 768 KiB.
constexpr uint32_t kMaxChunkBytes = 1u << 30;

uint32_t u32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

[[noreturn]] void fail(const fs::path& path, uint64_t offset, const std::string& what) {
  std::ostringstream msg;
  msg << path.string() << ": not a readable ROS 1 bag: at byte " << offset << ", " << what;
  throw FormatError(msg.str());
}

/// The fields of a record header ("name=value" with a length each).
struct Fields {
  std::optional<uint8_t> op;
  std::string compression;
  std::optional<uint32_t> size, count;
  std::optional<uint64_t> chunk_pos, index_pos;
  std::optional<uint32_t> start_time_at;  ///< where a start_time field's 8 bytes lie in the header
  bool start_time_zero = false;
};

/// Calls `fn(name, value, end)` for every "name=value" field of the `n` bytes at `p` (`end`: where
/// the field ends, from `p`); `what` names them in errors ("a header", "a connection's header").
template <class Fn>
void forEachField(const uint8_t* p, uint32_t n, const fs::path& path, uint64_t offset, const char* what, Fn fn) {
  uint32_t at = 0;
  while (at < n) {
    if (n - at < 4) fail(path, offset, std::string(what) + "'s field length is cut off");
    const uint32_t len = u32(p + at);
    at += 4;
    if (len > n - at) fail(path, offset, std::string(what) + "'s field runs past it");
    const std::string_view field(reinterpret_cast<const char*>(p + at), len);
    at += len;
    const auto eq = field.find('=');
    if (eq == std::string_view::npos) fail(path, offset, std::string(what) + "'s field has no '='");
    fn(field.substr(0, eq), field.substr(eq + 1), at);
  }
}

/// A connection record's data is a header of its own (topic, type, md5sum, message_definition),
/// which librosbag parses without checking its fields' lengths: checked here.
void checkConnectionHeader(const uint8_t* p, uint32_t n, const fs::path& path, uint64_t offset) {
  forEachField(p, n, path, offset, "a connection's header", [](std::string_view, std::string_view, uint32_t) {});
}

Fields parseFields(const uint8_t* p, uint32_t n, const fs::path& path, uint64_t offset) {
  Fields f;
  forEachField(p, n, path, offset, "a record header", [&](std::string_view name, std::string_view value, uint32_t at) {
    if (name == "op") {
      if (value.size() != 1) fail(path, offset, "the op field is not one byte");
      f.op = static_cast<uint8_t>(value[0]);
    } else if (name == "compression") {
      f.compression = std::string(value);
    } else if ((name == "chunk_pos" || name == "index_pos") && value.size() == 8) {
      uint64_t v;
      std::memcpy(&v, value.data(), 8);
      (name == "chunk_pos" ? f.chunk_pos : f.index_pos) = v;
    } else if (name == "start_time" && value.size() == 8) {
      f.start_time_at = static_cast<uint32_t>(at - value.size());
      f.start_time_zero = value.find_first_not_of('\0') == std::string_view::npos;
    } else if ((name == "size" || name == "count") && value.size() == 4) {
      (name == "size" ? f.size : f.count) = u32(reinterpret_cast<const uint8_t*>(value.data()));
    }
  });
  if (!f.op) fail(path, offset, "a record header has no op field");
  return f;
}

/// The records of a decompressed chunk: where each message record starts.
std::set<uint32_t> chunkMessages(const std::vector<uint8_t>& chunk, const fs::path& path, uint64_t offset) {
  std::set<uint32_t> messages;
  size_t at = 0;
  while (at < chunk.size()) {
    const uint32_t start = static_cast<uint32_t>(at);
    if (chunk.size() - at < 4) fail(path, offset, "a record in the chunk is cut off");
    const uint32_t header_len = u32(chunk.data() + at);
    at += 4;
    if (header_len > chunk.size() - at || chunk.size() - at - header_len < 4) {
      fail(path, offset, "a record header in the chunk runs past the chunk");
    }
    const Fields f = parseFields(chunk.data() + at, header_len, path, offset);
    at += header_len;
    const uint32_t data_len = u32(chunk.data() + at);
    at += 4;
    if (data_len > chunk.size() - at) fail(path, offset, "a record's data in the chunk runs past the chunk");
    if (*f.op == kOpConnection) checkConnectionHeader(chunk.data() + at, data_len, path, offset);
    at += data_len;
    if (*f.op == kOpMessage) messages.insert(start);
  }
  return messages;
}

std::vector<uint8_t> decompress(const std::string& compression, std::vector<uint8_t>& data, uint32_t size,
                                const fs::path& path, uint64_t offset) {
  if (compression == "none") {
    if (data.size() != size) fail(path, offset, "an uncompressed chunk's size field does not match its data");
    return std::move(data);
  }
  std::vector<uint8_t> out(size);
  unsigned int produced = size;
  if (compression == "bz2") {
    if (BZ2_bzBuffToBuffDecompress(reinterpret_cast<char*>(out.data()), &produced, reinterpret_cast<char*>(data.data()),
                                   static_cast<unsigned int>(data.size()), 0, 0) != BZ_OK) {
      fail(path, offset, "a bz2 chunk does not decompress to its stated size");
    }
  } else if (compression == "lz4") {
    if (roslz4_buffToBuffDecompress(reinterpret_cast<char*>(data.data()), static_cast<unsigned int>(data.size()),
                                    reinterpret_cast<char*>(out.data()), &produced) != ROSLZ4_OK) {
      fail(path, offset, "an lz4 chunk does not decompress to its stated size");
    }
  } else {
    fail(path, offset, "unknown chunk compression '" + compression + "'");
  }
  if (produced != size) fail(path, offset, "a chunk decompresses to another size than it states");
  return out;
}

}  // namespace

BagStructure checkBagStructure(const fs::path& path) {
  BagStructure out;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot open");
  in.seekg(0, std::ios::end);
  const uint64_t file_size = static_cast<uint64_t>(in.tellg());
  in.seekg(0);
  char magic[kMagicBytes];
  if (!in.read(magic, kMagicBytes) || std::memcmp(magic, kMagic, kMagicBytes) != 0) {
    fail(path, 0, "the file does not start with '#ROSBAG V2.0'");
  }
  uint64_t at = kMagicBytes;
  std::vector<uint8_t> header, data;
  std::set<uint32_t> last_chunk;  // message records of the last chunk, for its index records
  std::set<uint64_t> chunks;      // where chunk records start, for the chunk infos
  std::set<uint64_t> records;     // where top-level records start, for the bag header's index_pos
  std::optional<uint64_t> index_pos;
  const auto read = [&](std::vector<uint8_t>& into, uint64_t n, const char* what) {
    if (n > file_size - at) fail(path, at, std::string(what) + " runs past the end of the file (truncated?)");
    into.resize(n);
    in.read(reinterpret_cast<char*>(into.data()), static_cast<std::streamsize>(n));
    if (!in) throw IoError(path.string() + ": read failed");
    at += n;
  };
  std::vector<uint8_t> len(4);
  while (at < file_size) {
    const uint64_t record = at;
    read(len, 4, "a record length");
    const uint32_t header_len = u32(len.data());
    if (header_len > kMaxHeaderBytes)
      fail(path, record, "a record header claims " + std::to_string(header_len) + " bytes");
    read(header, header_len, "a record header");
    const Fields f = parseFields(header.data(), header_len, path, record);
    if (*f.op == kOpChunkInfo && f.start_time_zero) out.zero_times.push_back(record + 4 + *f.start_time_at);
    records.insert(record);
    if (*f.op == kOpBagHeader) {
      if (!f.index_pos) fail(path, record, "the bag header has no index_pos");
      index_pos = f.index_pos;
    }
    read(len, 4, "a record's data length");
    const uint32_t data_len = u32(len.data());
    if (*f.op == kOpChunkInfo && (!f.chunk_pos || !chunks.count(*f.chunk_pos))) {
      fail(path, record, "a chunk info points at no chunk record");
    }
    if (*f.op == kOpChunk) {
      chunks.insert(record);
      if (!f.size || *f.size > kMaxChunkBytes) fail(path, record, "a chunk has no plausible size field");
      read(data, data_len, "a chunk");
      last_chunk = chunkMessages(decompress(f.compression, data, *f.size, path, record), path, record);
    } else if (*f.op == kOpIndex) {
      const uint64_t data_at = at;
      read(data, data_len, "an index record");
      if (!f.count || uint64_t{*f.count} * 12 != data_len)
        fail(path, record, "an index record's count does not match its data");
      for (uint32_t i = 0; i < *f.count; ++i) {
        if (!last_chunk.count(u32(data.data() + 12 * i + 8))) {
          fail(path, record, "an index entry points at no message record of its chunk");
        }
        if (u32(data.data() + 12 * i) == 0 && u32(data.data() + 12 * i + 4) == 0) {
          out.zero_times.push_back(data_at + 12 * i);
          ++out.zero_time_messages;
        }
      }
    } else if (*f.op == kOpConnection) {
      read(data, data_len, "a connection record");
      checkConnectionHeader(data.data(), data_len, path, record);
    } else {
      if (data_len > file_size - at) fail(path, record, "a record's data runs past the end of the file (truncated?)");
      in.seekg(static_cast<std::streamoff>(data_len), std::ios::cur);
      at += data_len;
    }
  }
  // librosbag starts reading at index_pos; an unindexed bag (index_pos 0) it refuses itself.
  if (!index_pos) fail(path, kMagicBytes, "the bag has no bag header record");
  if (*index_pos != 0 && !records.count(*index_pos))
    fail(path, kMagicBytes, "the bag header's index_pos points at no record");
  return out;
}

}  // namespace chronomap
