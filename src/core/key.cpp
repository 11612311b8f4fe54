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

std::optional<VoxelKey> KeyGrid::keyOf(const Eigen::Vector3d& p_m) const {
  const Eigen::Vector3d u = toKeySpace(p_m);
  VoxelKey key;
  uint16_t* out[3] = {&key.x, &key.y, &key.z};
  for (int a = 0; a < 3; ++a) {
    const double f = std::floor(u[a]);
    if (!(f >= 0.0 && f < kKeysPerAxis)) return std::nullopt;  // also rejects NaN
    *out[a] = static_cast<uint16_t>(f);
  }
  return key;
}

Eigen::Vector3d KeyGrid::cornerOf(const VoxelKey& key) const {
  return Eigen::Vector3d(static_cast<double>(key.x) - kKeyOrigin, static_cast<double>(key.y) - kKeyOrigin,
                         static_cast<double>(key.z) - kKeyOrigin) *
         resolution_m_;
}

Eigen::Vector3d KeyGrid::centerOf(const VoxelKey& key, int level) const {
  const double half = 0.5 * static_cast<double>(1 << level);
  return cornerOf(key) + Eigen::Vector3d::Constant(half * resolution_m_);
}

}  // namespace chronomap
