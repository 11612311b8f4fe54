#include "chronomap/ingest/mcap_records.h"

#include <zlib.h>

#include <algorithm>

namespace chronomap::mcap {

uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc) {
  // zlib's crc32 takes at most 4 GiB a call.
  while (!bytes.empty()) {
    const size_t n = std::min<size_t>(bytes.size(), 1u << 30);
    crc = static_cast<uint32_t>(::crc32(crc, bytes.data(), static_cast<uInt>(n)));
    bytes = bytes.subspan(n);
  }
  return crc;
}

}  // namespace chronomap::mcap
