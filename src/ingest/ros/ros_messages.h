#pragma once
// The sensor messages of a robot recording as views of their fields, whatever stored them (a
// ROS 1 bag through librosbag, or a test), and their conversion into chronomap's frames. Kept
// free of ROS headers so that the checks are shared and fuzzed without a bag.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "chronomap/core/camera.h"
#include "chronomap/core/image.h"
#include "chronomap/core/point_cloud.h"

namespace chronomap::rosmsg {

/// sensor_msgs/Image.
struct ImageView {
  uint32_t height = 0, width = 0;
  std::string_view encoding;
  bool big_endian = false;
  uint32_t step = 0;  ///< bytes per row
  std::span<const uint8_t> data;
};

/// One field of sensor_msgs/PointField.
struct PointField {
  std::string_view name;
  uint32_t offset = 0;
  uint8_t datatype = 0;  ///< 1..8: INT8 UINT8 INT16 UINT16 INT32 UINT32 FLOAT32 FLOAT64
  uint32_t count = 0;
};

/// sensor_msgs/PointCloud2.
struct CloudView {
  uint32_t height = 0, width = 0;
  std::vector<PointField> fields;
  bool big_endian = false;
  uint32_t point_step = 0, row_step = 0;
  std::span<const uint8_t> data;
};

/// sensor_msgs/CompressedImage, as image_transport's plugins write it.
struct CompressedView {
  /// "jpeg", "png", "rgb8; jpeg compressed bgr8" (the compressed transport: a JPEG or PNG file)
  /// or "16UC1; compressedDepth png", "32FC1; compressedDepth" (the compressedDepth transport: a
  /// 12-byte header, then a 16-bit PNG).
  std::string_view format;
  std::span<const uint8_t> data;
};

/// A decoded image that owns its bytes (`view` points into `bytes`); move it, never copy it.
struct OwnedImage {
  std::vector<uint8_t> bytes;
  ImageView view;
  OwnedImage() = default;
  OwnedImage(OwnedImage&&) = default;
  OwnedImage& operator=(OwnedImage&&) = default;
  OwnedImage(const OwnedImage&) = delete;
  OwnedImage& operator=(const OwnedImage&) = delete;
};

/// True for the compressed colour formats read: a JPEG or PNG (not compressedDepth).
bool isCompressedColourFormat(std::string_view format);
/// True for compressedDepth formats (whether their compression is read or not: RVL is refused
/// when decoded, with a message that says so).
bool isCompressedDepthFormat(std::string_view format);

/// The colour image in a JPEG or PNG CompressedImage. @throw DataError or FormatError naming
/// `source` for another compression or a corrupt file.
ImageRgb compressedColourImage(const CompressedView& image, const std::string& source);

/// The depth image in a compressedDepth CompressedImage, as a little-endian 16UC1 image (its
/// units as written) or, for 32FC1, metres from the inverse-depth quantisation (a stored value
/// v is depth A / (v - B), with A and B from the header; 0 is no measurement, NaN).
/// @throw DataError or FormatError naming `source`.
OwnedImage compressedDepthImage(const CompressedView& image, const std::string& source);

/// True for the depth encodings read (16UC1, 32FC1, and "mono16" as some drivers write 16UC1).
bool isDepthEncoding(std::string_view encoding);
/// True for the colour encodings read (rgb8, bgr8, mono8, rgba8, bgra8).
bool isColourEncoding(std::string_view encoding);

/// A colour image. @throw DataError naming `source` for an unknown encoding or a short buffer.
ImageRgb colourImage(const ImageView& image, const std::string& source);

/// A depth image back-projected with `k`: 16UC1 divided by `depth_scale` (units per metre;
/// 1000 for millimetres), 32FC1 in metres. `rgb`, when given, has the depth image's size.
/// @throw DataError naming `source` for an unknown encoding or a short buffer.
PointCloud depthCloud(const ImageView& depth, const ImageRgb* rgb, const CameraIntrinsics& k, double depth_scale,
                      const std::string& source);

/// The points of a PointCloud2 (fields x, y, z as FLOAT32 or FLOAT64; rgb or rgba, packed, when
/// present). @throw DataError naming `source` for missing fields or a short buffer.
PointCloud pointCloud(const CloudView& cloud, const std::string& source);

}  // namespace chronomap::rosmsg
