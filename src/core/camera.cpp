#include "chronomap/core/camera.h"

#include <cmath>
#include <sstream>

#include "chronomap/core/error.h"

namespace chronomap {

bool intrinsicsValid(const CameraIntrinsics& k) {
  return k.fx > 0 && k.fy > 0 && std::isfinite(k.fx) && std::isfinite(k.fy) && std::isfinite(k.cx) &&
         std::isfinite(k.cy);
}

void checkIntrinsics(const CameraIntrinsics& k, const std::string& context) {
  if (intrinsicsValid(k)) return;
  std::ostringstream msg;
  msg << context << ": intrinsics fx " << k.fx << ", fy " << k.fy << ", cx " << k.cx << ", cy " << k.cy
      << ": focal lengths must be positive and all values finite";
  throw DataError(msg.str());
}

void checkIntrinsicsFit(const CameraIntrinsics& k, uint32_t width, uint32_t height, const std::string& context) {
  checkIntrinsics(k, context);
  if (k.cx >= 0 && k.cx <= width && k.cy >= 0 && k.cy <= height) return;
  std::ostringstream msg;
  msg << context << ": the principal point (" << k.cx << ", " << k.cy << ") lies outside the " << width << " x "
      << height << " image: the intrinsics are for another image size (give the camera's intrinsics for "
      << width << " x " << height << ")";
  throw DataError(msg.str());
}

}  // namespace chronomap
