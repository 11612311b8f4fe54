#pragma once
/// @file
/// 4D maps in the .cmap container (docs/file-format.md, kind "4d").

#include <filesystem>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "chronomap/io/cmap.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap::io {

/// Writes a 4D map atomically (temporary file, then rename): a crash leaves the previous
/// file as it was. Compacts a copy of the map first; `meta` (a JSON object) is stored as is.
void writeTemporalMap(const std::filesystem::path& path, const TemporalMap& map, const nlohmann::json& meta);
/// Reads a 4D map. @throw IoError, FormatError naming the file.
TemporalMap readTemporalMap(const std::filesystem::path& path);
/// The 4D map stored in a decoded file. @throw FormatError naming `source`.
TemporalMap temporalMapFrom(const CmapFile& file, const std::string& source);

}  // namespace chronomap::io
