#pragma once
/// @file
/// Fitted temporal models on disk (`.rhythm`): the bytes of serialize(RhythmModels), written
/// atomically, so that a saved model answers predictions without refitting.

#include <filesystem>

#include "chronomap/analysis/rhythm.h"

namespace chronomap::io {

/// Writes `models` to `path` atomically. @throw IoError naming the file.
void writeRhythmModels(const std::filesystem::path& path, const RhythmModels& models);
/// Reads models written by writeRhythmModels. @throw IoError or FormatError naming the file.
RhythmModels readRhythmModels(const std::filesystem::path& path);

}  // namespace chronomap::io
