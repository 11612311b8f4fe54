#pragma once
/// @file
/// Fitted colour models on disk (`.colour`): the bytes of serialize(ColourModel), written
/// atomically, so that a saved model predicts colours without refitting.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "chronomap/analysis/colour.h"

namespace chronomap {

/// Writes `model` to `path` atomically. @throw IoError naming the file.
void writeColourModel(const std::filesystem::path& path, const ColourModel& model);
/// Reads a model written by writeColourModel. @throw IoError or FormatError naming the file.
ColourModel readColourModel(const std::filesystem::path& path);

/// Serialises a colour model (little-endian, versioned; docs/colour.md, "Saving a model"): magic
/// "CMCO", version, kind (1: per-voxel weights under shared light curves), the curves, then per
/// voxel its key and weights. deserializeColour() is its inverse.
std::vector<uint8_t> serialize(const ColourModel& model);
/// @throw FormatError naming `source` for bytes that are not a valid colour model (wrong magic,
/// a newer version, an unknown kind, truncated, values out of range, voxels out of order, bytes
/// after the last voxel).
ColourModel deserializeColour(std::span<const uint8_t> bytes, const std::string& source);

}  // namespace chronomap
