#include "chronomap/pipeline/clean.h"

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/pipeline/session.h"

namespace chronomap {

CleanResult cleanRecording(const std::filesystem::path& path, const std::filesystem::path& output,
                           const CleanSettings& settings, const Progress& progress) {
  const auto dataset = openRecording(path, settings.dataset);
  progress.say("cleaning " + std::to_string(dataset->size()) + " frame(s) of " + path.string() + " (" +
               dataset->format() + ")");
  CleanResult r;
  r.format = dataset->format();
  r.points = staticPoints(*dataset, settings.points,
                          [&](size_t done, size_t total) { progress.advance("cleaning", done, total); });
  if (r.points.points_in == r.points.points_invalid) {
    throw DataError(path.string() + ": no valid point in " + std::to_string(r.points.frames) +
                    " frame(s); nothing to write");
  }
  writePcd(output, r.points.points, PcdEncoding::Binary);
  r.points.points = {};
  return r;
}

}  // namespace chronomap
