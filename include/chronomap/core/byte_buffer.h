#pragma once
/// @file
/// Plain numbers appended to and read back from a byte buffer, as the saved model files
/// (.rhythm, .colour) store them: each value's bytes as they lie in memory (chronomap builds for
/// little-endian machines only, as the .cmap files assume).

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "chronomap/core/error.h"

namespace chronomap {

/// Appends values.
struct ByteWriter {
  std::vector<uint8_t> bytes;
  template <class T>
  void put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const size_t at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &v, sizeof(T));
  }
};

/// Reads values in order; reading past the end throws FormatError("`source`: `what` ends early
/// (truncated)").
struct ByteReader {
  std::span<const uint8_t> bytes;
  size_t pos = 0;
  const std::string& source;
  const char* what = "the file";
  template <class T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    if (bytes.size() - pos < sizeof(T)) throw FormatError(source + ": " + what + " ends early (truncated)");
    T v;
    std::memcpy(&v, bytes.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
};

}  // namespace chronomap
