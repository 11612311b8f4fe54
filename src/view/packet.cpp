// The viewer's binary answers: a JSON header, then little-endian arrays.

#include "chronomap/view/packet.h"

#include <bit>
#include <cstring>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

static_assert(std::endian::native == std::endian::little, "packets are written in the machine's byte order");

constexpr size_t kAlign = 8;

void padTo(std::string& s, size_t base, char fill) {
  while ((base + s.size()) % kAlign != 0) s.push_back(fill);
}

uint32_t readU32(const std::string& s, size_t at) {
  uint32_t v = 0;
  for (int k = 0; k < 4; ++k) v |= static_cast<uint32_t>(static_cast<uint8_t>(s[at + k])) << (8 * k);
  return v;
}

size_t typeSize(const std::string& type) {
  if (type == "u8") return 1;
  if (type == "u16") return 2;
  if (type == "u32" || type == "f32") return 4;
  throw FormatError("viewer packet: unknown array type '" + type + "'");
}

}  // namespace

void PacketWriter::addRaw(const std::string& name, const char* type, size_t length, const void* data, size_t bytes) {
  arrays_.push_back({{"name", name}, {"type", type}, {"length", length}});
  padTo(data_, 0, '\0');
  data_.append(static_cast<const char*>(data), bytes);
}

void PacketWriter::add(const std::string& name, std::span<const uint8_t> v) {
  addRaw(name, "u8", v.size(), v.data(), v.size_bytes());
}
void PacketWriter::add(const std::string& name, std::span<const uint16_t> v) {
  addRaw(name, "u16", v.size(), v.data(), v.size_bytes());
}
void PacketWriter::add(const std::string& name, std::span<const uint32_t> v) {
  addRaw(name, "u32", v.size(), v.data(), v.size_bytes());
}
void PacketWriter::add(const std::string& name, std::span<const float> v) {
  addRaw(name, "f32", v.size(), v.data(), v.size_bytes());
}

std::string PacketWriter::finish(nlohmann::json header) const {
  header["arrays"] = arrays_;
  // Names (of maps, sessions) need not be UTF-8: such bytes become U+FFFD.
  std::string text = header.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  padTo(text, 8, ' ');
  std::string out(kPacketMagic, sizeof kPacketMagic);
  const auto n = static_cast<uint32_t>(text.size());
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((n >> (8 * k)) & 0xff));
  out.append(text);
  out.append(data_);
  return out;
}

Packet readPacket(std::string payload) {
  if (payload.size() < 8 || std::memcmp(payload.data(), kPacketMagic, 4) != 0) {
    throw FormatError("viewer packet: no CMV1 magic");
  }
  const size_t header_bytes = readU32(payload, 4);
  if (header_bytes > payload.size() - 8) throw FormatError("viewer packet: header runs past the end");
  Packet p;
  try {
    p.header = nlohmann::json::parse(payload.substr(8, header_bytes));
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(std::string("viewer packet: bad header: ") + e.what());
  }
  size_t at = 8 + header_bytes;
  if (!p.header.is_object() || !p.header.contains("arrays") || !p.header["arrays"].is_array()) {
    throw FormatError("viewer packet: the header lists no arrays");
  }
  for (auto& a : p.header["arrays"]) {
    at = (at + kAlign - 1) / kAlign * kAlign;
    const size_t bytes = a.at("length").get<size_t>() * typeSize(a.at("type").get<std::string>());
    if (at > payload.size() || bytes > payload.size() - at) throw FormatError("viewer packet: an array runs past the end");
    a["offset"] = at;
    at += bytes;
  }
  p.payload = std::move(payload);
  return p;
}

std::span<const uint8_t> Packet::bytes(const std::string& name) const {
  for (const auto& a : header["arrays"]) {
    if (a["name"] == name) {
      const size_t bytes = a["length"].get<size_t>() * typeSize(a["type"].get<std::string>());
      return {reinterpret_cast<const uint8_t*>(payload.data()) + a["offset"].get<size_t>(), bytes};
    }
  }
  throw FormatError("viewer packet: no array '" + name + "'");
}

}  // namespace chronomap
