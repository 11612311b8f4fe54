#pragma once
/// @file
/// What MCAP's reader (ingest/ros/mcap.h) and writer (export/mcap_writer.h) share: the format's
/// magic, the framing of a record and its opcodes, and the CRC-32 its checksums use (the
/// published MCAP specification, major version 0).

#include <cstdint>
#include <span>

namespace chronomap::mcap {

/// The 8 bytes an MCAP file starts and ends with (major version '0').
inline constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};
/// A record's head: its opcode (u8) and the length of its content (u64).
inline constexpr uint64_t kRecordHead = 9;
/// The footer's content: summary_start (u64), summary_offset_start (u64), summary_crc (u32).
inline constexpr uint64_t kFooterContent = 20;

/// Record opcodes.
enum Op : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

/// The CRC-32 (zlib's polynomial, as MCAP uses) of `bytes`, continuing from `crc` (0 to start).
uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc = 0);

}  // namespace chronomap::mcap
