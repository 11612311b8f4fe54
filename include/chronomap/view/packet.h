#pragma once
/// @file
/// The binary answers of the viewer: a JSON header followed by little-endian typed arrays, so
/// that the page reads millions of voxels without parsing text (docs/viewer.md, "Protocol").

#include <bit>
#include <cstdint>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

namespace chronomap {

/// Magic of a packet: "CMV1" (chronomap view, version 1).
inline constexpr char kPacketMagic[4] = {'C', 'M', 'V', '1'};

/// Builds one packet: "CMV1", the header's length (u32), the JSON header (padded with spaces
/// to a multiple of 8 bytes from the start), then each array in the order added, each starting
/// at a multiple of 8. The header lists the arrays as {"name", "type", "length"} under
/// "arrays"; types are "u8", "u16", "u32" and "f32", little-endian.
class PacketWriter {
 public:
  void add(const std::string& name, std::span<const uint8_t> values);
  void add(const std::string& name, std::span<const uint16_t> values);
  void add(const std::string& name, std::span<const uint32_t> values);
  void add(const std::string& name, std::span<const float> values);
  /// The packet with `header` (an object; "arrays" is added to it).
  std::string finish(nlohmann::json header) const;

 private:
  void addRaw(const std::string& name, const char* type, size_t length, const void* data, size_t bytes);
  nlohmann::json arrays_ = nlohmann::json::array();
  std::string data_;
};

/// A decoded packet (tests, and tools that read the viewer's answers).
struct Packet {
  nlohmann::json header;
  /// The bytes of the array `name`. @throw FormatError when there is none.
  std::span<const uint8_t> bytes(const std::string& name) const;
  /// The array `name` as values of type T (which must match its type and size).
  template <class T>
  std::vector<T> values(const std::string& name) const;

  std::string payload;
};

/// Decodes a packet. @throw FormatError for a bad magic, header or array table.
Packet readPacket(std::string payload);

template <class T>
std::vector<T> Packet::values(const std::string& name) const {
  const auto b = bytes(name);
  std::vector<T> out(b.size() / sizeof(T));
  for (size_t i = 0; i < out.size(); ++i) {
    if constexpr (std::is_same_v<T, float>) {  // little-endian IEEE 754 bits
      uint32_t bits = 0;
      for (size_t k = 0; k < 4; ++k) bits |= static_cast<uint32_t>(b[i * 4 + k]) << (8 * k);
      out[i] = std::bit_cast<float>(bits);
    } else {
      T v{};
      for (size_t k = 0; k < sizeof(T); ++k) {
        v = static_cast<T>(v | static_cast<T>(static_cast<uint64_t>(b[i * sizeof(T) + k]) << (8 * k)));
      }
      out[i] = v;
    }
  }
  return out;
}

}  // namespace chronomap
