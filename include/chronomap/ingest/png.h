#pragma once
/// @file
/// PNG images through libpng: 8-bit colour and 16-bit depth.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/core/image.h"

namespace chronomap {

/// Largest width or height accepted when reading, to refuse decompression bombs.
inline constexpr uint32_t kMaxImageSide = 1u << 15;

/// Reads any PNG as 8-bit RGB (grey, palette and alpha are converted; 16-bit is reduced).
/// @throw IoError when unreadable, FormatError naming the file when not a valid PNG.
ImageRgb readPngRgb(const std::filesystem::path& path);
/// Reads a 16-bit greyscale PNG (a depth image) without any conversion.
/// @throw FormatError when the PNG is not 16-bit single-channel.
ImageU16 readPngU16(const std::filesystem::path& path);

/// The same readers on a file's bytes already in memory; `name` is used in messages.
ImageRgb decodePngRgb(const std::vector<uint8_t>& bytes, const std::string& name);
ImageU16 decodePngU16(const std::vector<uint8_t>& bytes, const std::string& name);

/// The PNG file's bytes of an 8-bit RGB image (what writePng writes), for callers that write
/// them their own way. @throw IoError when encoding fails, UsageError when the size is wrong.
std::vector<uint8_t> encodePng(const ImageRgb& image);
/// The PNG file's bytes of a 16-bit greyscale image (what writePng writes).
std::vector<uint8_t> encodePng(const ImageU16& image);
/// Writes an 8-bit RGB PNG atomically.
void writePng(const std::filesystem::path& path, const ImageRgb& image);
/// Writes a 16-bit greyscale PNG atomically.
void writePng(const std::filesystem::path& path, const ImageU16& image);

}  // namespace chronomap
