#include "chronomap/core/key.h"

#include <sstream>
#include <string>

#include "chronomap/core/error.h"

namespace chronomap {

KeyGrid::KeyGrid(double resolution_m) : resolution_m_(resolution_m), inv_resolution_(1.0 / resolution_m) {
  if (!(resolution_m >= kMinResolution_m && resolution_m <= kMaxResolution_m)) {
    std::ostringstream msg;
    msg << "resolution must lie in [" << kMinResolution_m << ", " << kMaxResolution_m << "] m (a map spans "
        << kKeysPerAxis << " voxels per axis), got " << resolution_m;
    throw UsageError(msg.str());
  }
}

}  // namespace chronomap
