// A cloud file by its extension: PCD (pcd.cpp), PLY (ply.cpp), XYZ and .dat (xyz.cpp).

#include "chronomap/ingest/cloud_io.h"

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"

namespace chronomap {

bool isCloudFile(const std::filesystem::path& path) {
  const std::string ext = dataExtension(path);
  return ext == ".pcd" || ext == ".ply" || ext == ".xyz" || ext == ".dat";
}

PointCloud readCloud(const std::filesystem::path& path) {
  const std::string ext = dataExtension(path);
  if (ext == ".pcd") return readPcd(path);
  if (ext == ".ply") return readPly(path);
  if (ext == ".xyz" || ext == ".dat") return readXyz(path);
  throw UsageError(path.string() + ": unknown cloud format '" + ext + "' (expected .pcd, .ply, .xyz or .dat)");
}

}  // namespace chronomap
