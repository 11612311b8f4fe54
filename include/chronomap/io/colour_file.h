#pragma once
/// @file
/// Fitted colour models on disk (`.colour`): the bytes of serialize(ColourModel), written
/// atomically, so that a saved model predicts colours without refitting.

#include <filesystem>

#include "chronomap/analysis/colour.h"

namespace chronomap::io {

/// Writes `model` to `path` atomically. @throw IoError naming the file.
void writeColourModel(const std::filesystem::path& path, const ColourModel& model);
/// Reads a model written by writeColourModel. @throw IoError or FormatError naming the file.
ColourModel readColourModel(const std::filesystem::path& path);

}  // namespace chronomap::io
