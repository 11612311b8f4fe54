#pragma once
/// @file
/// Fitted temporal models on disk (`.rhythm`): the bytes of serialize(RhythmModels), written
/// atomically, so that a saved model answers predictions without refitting.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "chronomap/analysis/rhythm.h"

namespace chronomap {

/// Writes `models` to `path` atomically. @throw IoError naming the file.
void writeRhythmModels(const std::filesystem::path& path, const RhythmModels& models);
/// Reads models written by writeRhythmModels. @throw IoError or FormatError naming the file.
RhythmModels readRhythmModels(const std::filesystem::path& path);

/// The .rhythm version chronomap writes: 4 records what the models were fitted on (FittedOn);
/// versions 1 to 3 still read, without it (docs/rhythm.md).
inline constexpr uint32_t kRhythmVersion = 4;

/// Serialises fitted models (little-endian) in `version` (older ones for tests and seeds: what
/// they cannot hold is left out); deserializeRhythm() is its inverse.
/// @throw UsageError for a version outside 1..kRhythmVersion.
std::vector<uint8_t> serialize(const RhythmModels& models, uint32_t version = kRhythmVersion);
/// @throw FormatError naming `source` for bytes that are not a valid model: a wrong magic, a
/// newer version, a header out of range (resolution, learning times, the fingerprint's times) or
/// announcing more times, voxels or groups than the bytes left hold (refused before anything is
/// allocated), values out of range, voxels out of order, bytes after the last.
RhythmModels deserializeRhythm(std::span<const uint8_t> bytes, const std::string& source);

}  // namespace chronomap
