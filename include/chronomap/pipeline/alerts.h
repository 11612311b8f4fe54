#pragma once
/// @file
/// The alerts workflow: a session's changed objects ranked by unusualness (analysis/alerts.h) as
/// JSON, and written as pictures and PLYs for a person to look at.
#include <cstddef>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "chronomap/analysis/alerts.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// The first `top` alerts of `report` (all when `top` is 0) as JSON: rank, score in bits,
/// probability, reason, the evidence counts and the object's component fields.
nlohmann::json alertsJson(const AlertReport& report, size_t top);

/// Writes into `folder` (replacing what an earlier run wrote there): alerts.json (alertsJson),
/// alerts.png (the map at the session's time seen from above, faded, with the first `top`
/// objects drawn and framed, labelled with their rank) and, per ranked object NN,
/// alert_NN.png (a top view of the map within a metre of it, the object framed) and
/// alert_NN.ply (its changed voxels). `source` is the map's path, never overwritten.
/// @throw UsageError when a file to write is the map; IoError when writing fails.
void writeAlerts(const std::filesystem::path& folder, const TemporalMap& map, const AlertReport& report, size_t top,
                 const std::string& source);

}  // namespace chronomap
