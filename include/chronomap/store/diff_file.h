#pragma once
/// @file
/// Diffs in the .cmap container (docs/file-format.md, kind "diff") and as PLY clouds.

#include <filesystem>
#include <span>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "chronomap/analysis/diff.h"
#include "chronomap/store/cmap.h"

namespace chronomap {

/// Writes a diff atomically; `meta` (a JSON object) is stored as is.
void writeDiffMap(const std::filesystem::path& path, const DiffMap& diff, const nlohmann::json& meta);
/// Reads a diff. @throw IoError, FormatError naming the file.
DiffMap readDiffMap(const std::filesystem::path& path);
/// The diff stored in a decoded file. @throw FormatError naming `source`.
DiffMap diffMapFrom(const CmapFile& file, const std::string& source);

}  // namespace chronomap
