#include "chronomap/io/depth_image.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "chronomap/core/error.h"
#include "text_util.h"

namespace chronomap::io {

namespace {

void checkSizes(size_t depth_pixels, uint32_t width, uint32_t height, const ImageRgb* rgb, const std::string& source) {
  std::ostringstream msg;
  if (depth_pixels != size_t{width} * height) {
    msg << source << ": depth image holds " << depth_pixels << " pixels, not " << width << "x" << height;
  } else if (rgb && (rgb->width != width || rgb->height != height)) {
    msg << source << ": colour image is " << rgb->width << "x" << rgb->height << " but the depth image is " << width
        << "x" << height;
  }
  if (!msg.str().empty()) throw DataError(msg.str());
}

}  // namespace

PointCloud depthMetresToCloud(std::span<const float> depth_m, uint32_t width, uint32_t height, const ImageRgb* rgb,
                              const CameraIntrinsics& k, const std::string& source) {
  checkSizes(depth_m.size(), width, height, rgb, source);
  PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  cloud.points.resize(depth_m.size());
  if (rgb) cloud.colors = rgb->pixels;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (uint32_t v = 0; v < height; ++v) {
    for (uint32_t u = 0; u < width; ++u) {
      const size_t i = size_t{v} * width + u;
      const float d = depth_m[i];
      if (!(d > 0.0f) || !std::isfinite(d)) {
        cloud.points[i] = Eigen::Vector3f(nan, nan, nan);
        continue;
      }
      const double z = d;
      cloud.points[i] = Eigen::Vector3f(toFloat((u - k.cx) * z / k.fx), toFloat((v - k.cy) * z / k.fy), toFloat(z));
    }
  }
  return cloud;
}

}  // namespace chronomap::io
