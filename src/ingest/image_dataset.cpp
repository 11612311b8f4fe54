#include "image_dataset.h"

#include <cmath>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"

namespace chronomap::readers {

double checkedScale(const DatasetSettings& o, double fallback) {
  const double s = o.depth_scale.value_or(fallback);
  if (!(s > 0.0) || !std::isfinite(s)) throw UsageError("depth scale must be a positive number of units per metre");
  return s;
}

void requireFile(const fs::path& p, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) throw DataError(p.string() + ": " + what + " is missing");
}

Eigen::Matrix4d readMatrix4(const fs::path& path) { return parseMatrix4(readTextFile(path), path.string()); }

}  // namespace chronomap::readers
