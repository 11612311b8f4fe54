#pragma once
/// @file
/// Bytes as text: standard base64 (RFC 4648, with padding), as the viewer's tours embed their
/// data and as JSON messages carry bytes (export/foxglove.h).

#include <string>
#include <string_view>

namespace chronomap {

/// Standard base64 with padding.
std::string base64(std::string_view bytes);

}  // namespace chronomap
