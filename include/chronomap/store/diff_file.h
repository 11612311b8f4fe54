#pragma once
/// @file
/// Diffs in the .cmap container (docs/file-format.md, kind "diff") and as PLY clouds.

#include <filesystem>
#include <span>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/store/cmap.h"

namespace chronomap {

/// Writes a diff atomically; `meta` (a JSON object) is stored as is.
void writeDiffMap(const std::filesystem::path& path, const DiffMap& diff, const nlohmann::json& meta);
/// Writes the diff of `changes` atomically, and in its metadata under "changes" the settings
/// that made it ("settings": changeSettingsJson(), "preset": `preset`) and its objects
/// ("objects": changedObjectsJson()), so that a reader has the objects without segmenting again.
void writeDiffMap(const std::filesystem::path& path, const Changes& changes, const ChangeSettings& settings,
                  const std::string& preset, const nlohmann::json& meta);
/// The "changes" metadata writeDiffMap() stored with a diff's objects; null for a diff written
/// without them. @throw FormatError naming `source` when the file is not a diff.
nlohmann::json diffChangesOf(const CmapFile& file, const std::string& source);
/// Reads a diff. @throw IoError, FormatError naming the file.
DiffMap readDiffMap(const std::filesystem::path& path);
/// The diff stored in a decoded file. @throw FormatError naming `source`.
DiffMap diffMapFrom(const CmapFile& file, const std::string& source);

}  // namespace chronomap
