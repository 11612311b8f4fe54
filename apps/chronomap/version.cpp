// chronomap --version: the version, the commit, the file formats this build reads and writes,
// and the optional parts it was built with.

#include <sstream>
#include <string>

#include "chronomap/store/cmap.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/version.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

/// "reads 1 to 3, writes 3" (or "reads and writes 1" when only one exists).
std::string readsWrites(uint32_t oldest, uint32_t newest) {
  if (oldest == newest) return "reads and writes " + std::to_string(newest);
  return "reads " + std::to_string(oldest) + " to " + std::to_string(newest) + ", writes " + std::to_string(newest);
}

const char* yesNo(bool built) { return built ? "yes" : "no"; }

}  // namespace

std::string versionText() {
  std::ostringstream out;
  // The first line is what help2man and scripts read as the version.
  out << "chronomap " << kVersion << "\n"
      << "commit: " << buildCommit() << "\n"
      << "file formats:\n"
      << "  .cmap (session, 4D, diff and tiled maps): " << readsWrites(1, kCmapFormatVersion) << "\n"
      << "  tiled map tile table (index.cmap): " << readsWrites(kOldestTileTableVersion, kTileTableVersion) << "\n"
      << "  .rhythm (rhythm models): " << readsWrites(1, kRhythmVersion) << "\n"
      << "  .colour (colour models): " << readsWrites(1, kColourVersion) << "\n"
      << "built with:\n"
      << "  ROS 1 bags (librosbag): " << yesNo(kBuiltWithRos1) << "\n"
      << "  ROS 2 bags (MCAP and SQLite .db3 storage): " << yesNo(kBuiltWithRos2Storage) << "\n"
      << "  MPI (mpirun -np N chronomap build): " << yesNo(kBuiltWithMpi) << "\n"
      << "  Python module: " << yesNo(kBuiltWithPython);
  return out.str();
}

}  // namespace chronomap::cli
