#include "chronomap/ingest/depth_image.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/dataset.h"
#include "text_util.h"

namespace chronomap {

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
  checkIntrinsicsFit(k, width, height, source);
  PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  cloud.points.resize(depth_m.size());
  if (rgb) cloud.colours = rgb->pixels;
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

ImageRgb colourInDepthView(const ImageRgb& colour, const CameraIntrinsics& colour_k, const CameraIntrinsics& depth_k,
                          uint32_t width, uint32_t height) {
  ImageRgb out{width, height, std::vector<Rgb>(size_t{width} * height, Rgb{0, 0, 0})};
  // A ray's colour pixel does not depend on its depth: u_c = fx_c * (u - cx) / fx + cx_c.
  std::vector<int64_t> columns(width), rows(height);
  for (uint32_t u = 0; u < width; ++u) {
    columns[u] = static_cast<int64_t>(std::floor(colour_k.fx * (u - depth_k.cx) / depth_k.fx + colour_k.cx + 0.5));
  }
  for (uint32_t v = 0; v < height; ++v) {
    rows[v] = static_cast<int64_t>(std::floor(colour_k.fy * (v - depth_k.cy) / depth_k.fy + colour_k.cy + 0.5));
  }
  for (uint32_t v = 0; v < height; ++v) {
    if (rows[v] < 0 || rows[v] >= colour.height) continue;
    for (uint32_t u = 0; u < width; ++u) {
      if (columns[u] < 0 || columns[u] >= colour.width) continue;
      const size_t from = static_cast<size_t>(rows[v]) * colour.width + static_cast<size_t>(columns[u]);
      out.pixels[size_t{v} * width + u] = colour.pixels[from];
    }
  }
  return out;
}

PointCloud depthToCloud(const ImageU16& depth, const ImageRgb* rgb, const CameraIntrinsics& k, double depth_scale,
                        const std::string& source) {
  if (!(depth_scale > 0.0) || !std::isfinite(depth_scale)) {
    throw DataError(source + ": depth scale must be a positive number of units per metre");
  }
  checkIntrinsicsFit(k, depth.width, depth.height, source);
  if (rgb && (rgb->width != depth.width || rgb->height != depth.height)) {
    std::ostringstream msg;
    msg << source << ": colour image is " << rgb->width << "x" << rgb->height << " but the depth image is "
        << depth.width << "x" << depth.height;
    throw DataError(msg.str());
  }
  PointCloud cloud;
  cloud.width = depth.width;
  cloud.height = depth.height;
  const size_t n = size_t{depth.width} * depth.height;
  cloud.points.resize(n);
  if (rgb) cloud.colours = rgb->pixels;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const double inv_scale = 1.0 / depth_scale;
  // Each column's offset from the principal point, the same double the per-pixel expression
  // (u - cx) * z / fx computes first: the same points, bit for bit.
  std::vector<double> columns(depth.width);
  for (uint32_t u = 0; u < depth.width; ++u) columns[u] = u - k.cx;
  for (uint32_t v = 0; v < depth.height; ++v) {
    const double row = v - k.cy;
    const uint16_t* line = depth.pixels.data() + size_t{v} * depth.width;
    Eigen::Vector3f* out = cloud.points.data() + size_t{v} * depth.width;
    for (uint32_t u = 0; u < depth.width; ++u) {
      const uint16_t d = line[u];
      if (d == 0) {
        out[u] = Eigen::Vector3f(nan, nan, nan);
        continue;
      }
      const double z = d * inv_scale;
      out[u] = Eigen::Vector3f(toFloat(columns[u] * z / k.fx), toFloat(row * z / k.fy), toFloat(z));
    }
  }
  return cloud;
}

}  // namespace chronomap
