#pragma once
// What a request sent, made safe to quote in a message: the viewer's errors show a parameter or a
// Host header as received, and a NUL or a control byte must neither cut the message short nor
// reach a terminal.

#include <string>
#include <string_view>

namespace chronomap {

/// `text` with every byte outside printable ASCII written as \xNN and a backslash as \\, so that
/// the message shows exactly what was received.
inline std::string printable(std::string_view text) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte == '\\') {
      out += "\\\\";
    } else if (byte >= 0x20 && byte < 0x7f) {
      out += c;
    } else {
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    }
  }
  return out;
}

}  // namespace chronomap
