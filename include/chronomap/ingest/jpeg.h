#pragma once
/// @file
/// JPEG colour images through libjpeg-turbo, and colour frames in either PNG or JPEG.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/core/image.h"

namespace chronomap {

/// Whether `bytes` start like a JPEG file (SOI marker followed by another marker).
bool looksLikeJpeg(const std::vector<uint8_t>& bytes);

/// Decodes a baseline or progressive JPEG (grey, YCbCr or RGB) to 8-bit RGB. A header whose
/// pixels exceed what the bytes can plausibly hold (4096 bytes of image per byte of file, at
/// least 64 MiB) is refused before anything is allocated; a truncated or corrupt stream, which
/// libjpeg would only warn about and fill with grey, is an error. `name` is used in messages.
/// @throw FormatError naming `name`.
ImageRgb decodeJpegRgb(const std::vector<uint8_t>& bytes, const std::string& name);

/// How encodeJpeg writes: quality 1..100, grey (the red channel only), progressive scans.
struct JpegEncoding {
  int quality = 90;
  bool grey = false;
  bool progressive = false;
};
/// Encodes an image as JPEG (for test recordings and seeds; chronomap's own outputs are PNG).
/// @throw UsageError for a quality outside 1..100 or an empty image.
std::vector<uint8_t> encodeJpeg(const ImageRgb& image, const JpegEncoding& encoding = {});

/// Reads a colour frame, PNG or JPEG, told apart by the file's first bytes (not its name).
/// @throw IoError when unreadable; FormatError naming the file when neither or corrupt.
ImageRgb readColourImage(const std::filesystem::path& path);

}  // namespace chronomap
