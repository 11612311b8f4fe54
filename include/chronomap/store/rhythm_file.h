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

/// Serialises fitted models (little-endian, versioned); deserialise is its inverse.
/// @throw FormatError naming `source` for bytes that are not a valid model.
std::vector<uint8_t> serialize(const RhythmModels& models);
RhythmModels deserializeRhythm(std::span<const uint8_t> bytes, const std::string& source);

}  // namespace chronomap
