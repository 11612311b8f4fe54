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

/// The .colour version chronomap writes: 2 records what the model was fitted on (FittedOn);
/// version 1 still reads, without it (docs/colour.md).
inline constexpr uint32_t kColourVersion = 2;

/// Serialises a colour model (little-endian; docs/colour.md, "Saving a model") in `version`
/// (older ones for tests and seeds): magic "CMCO", version, kind (1: per-voxel weights under
/// shared light curves), the header, what it was fitted on, the curves, then per voxel its key
/// and weights. deserializeColour() is its inverse.
/// @throw UsageError for a version outside 1..kColourVersion.
std::vector<uint8_t> serialize(const ColourModel& model, uint32_t version = kColourVersion);
/// @throw FormatError naming `source` for bytes that are not a valid colour model (wrong magic,
/// a newer version, an unknown kind, a header out of range or announcing more times or voxels
/// than the bytes left hold (refused before anything is allocated), values out of range, voxels
/// out of order, bytes after the last voxel).
ColourModel deserializeColour(std::span<const uint8_t> bytes, const std::string& source);

}  // namespace chronomap
