#pragma once
/// @file
/// `chronomap clean`: a recording's static map as points (the dynamic-map benchmark's output):
/// open it with any reader, keep the points that staticPoints judges static, write them as a
/// binary PCD.

#include <filesystem>
#include <string>

#include "chronomap/ingest/dataset.h"
#include "chronomap/integrate/static_points.h"
#include "chronomap/pipeline/progress.h"

namespace chronomap {

/// Settings of cleanRecording.
struct CleanSettings {
  DatasetSettings dataset;        ///< how the recording is read (--format, ...)
  StaticPointSettings points;     ///< when a point is static
};

/// What cleanRecording did.
struct CleanResult {
  StaticPointResult points;  ///< the counts (the points themselves are in the file)
  std::string format;        ///< the reader that read the recording
};

/// Opens the recording at `path`, keeps its static points and writes them to `output` (binary
/// PCD, x y z, world frame) atomically. Reports the two passes as work labelled "cleaning".
/// @throw UsageError for bad settings; DataError when the recording has no valid point;
/// whatever the reader throws for bad input; IoError when the output cannot be written.
CleanResult cleanRecording(const std::filesystem::path& path, const std::filesystem::path& output,
                           const CleanSettings& settings = {}, const Progress& progress = {});

}  // namespace chronomap
