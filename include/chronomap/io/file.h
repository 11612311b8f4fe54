#pragma once
/// @file
/// File helpers: whole-file reads with clear errors, and atomic writes.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace chronomap::io {

/// Reads a whole file. Files ending in .bz2 are decompressed.
/// @throw IoError naming the file when it cannot be read; FormatError for a corrupt .bz2.
std::vector<uint8_t> readFileBytes(const std::filesystem::path& path);

/// Reads a whole text file (see readFileBytes).
std::string readTextFile(const std::filesystem::path& path);

/// Writes `bytes` to `path` atomically: into a temporary file in the same folder, flushed to
/// disk, then renamed over `path`. On any failure the temporary file is removed and `path` is
/// left as it was.
/// @throw IoError naming the file (disk full, permission, missing folder).
void writeFileAtomic(const std::filesystem::path& path, const std::vector<uint8_t>& bytes);

/// `path` without a trailing ".bz2", lower-cased extension of what remains (".pcd", ".ply", ...).
std::string dataExtension(const std::filesystem::path& path);

}  // namespace chronomap::io
