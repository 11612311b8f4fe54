#include "ros_messages.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/depth_image.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"

namespace chronomap::rosmsg {

namespace {

/// Bytes per pixel of the encodings read.
uint32_t bytesPerPixel(std::string_view e) {
  if (e == "16UC1" || e == "mono16") return 2;
  if (e == "32FC1") return 4;
  if (e == "rgb8" || e == "bgr8") return 3;
  if (e == "rgba8" || e == "bgra8") return 4;
  if (e == "mono8" || e == "8UC1") return 1;
  return 0;
}

/// Checks the image's geometry against its buffer. @return bytes per pixel.
uint32_t checkImage(const ImageView& im, const std::string& source) {
  const uint32_t bpp = bytesPerPixel(im.encoding);
  if (bpp == 0) {
    throw DataError(source + ": image encoding '" + std::string(im.encoding) +
                    "' is not read (depth: 16UC1, 32FC1; colour: rgb8, bgr8, mono8, rgba8, bgra8)");
  }
  if (im.width == 0 || im.height == 0) throw DataError(source + ": the image is empty");
  if (uint64_t{im.step} < uint64_t{im.width} * bpp || uint64_t{im.step} * im.height > im.data.size()) {
    std::ostringstream msg;
    msg << source << ": a " << im.width << "x" << im.height << " " << im.encoding << " image with rows of " << im.step
        << " bytes does not fit its " << im.data.size() << " bytes of data";
    throw DataError(msg.str());
  }
  return bpp;
}

template <class T>
T readScalar(const uint8_t* p, bool swap) {
  uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, p, sizeof(T));
  if (swap) std::reverse(bytes, bytes + sizeof(T));
  T v;
  std::memcpy(&v, bytes, sizeof(T));
  return v;
}

constexpr bool kHostBigEndian = false;  // chronomap builds for little-endian machines only

}  // namespace

namespace {

std::string lowered(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

bool contains(const std::string& s, const char* part) { return s.find(part) != std::string::npos; }

/// The part of an image_transport format before ';' (the original encoding), trimmed.
std::string_view encodingOf(std::string_view format) {
  std::string_view e = format.substr(0, format.find(';'));
  while (!e.empty() && e.front() == ' ') e.remove_prefix(1);
  while (!e.empty() && e.back() == ' ') e.remove_suffix(1);
  return e;
}

bool isPng(std::span<const uint8_t> d) {
  static constexpr uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  return d.size() >= 8 && std::equal(kSignature, kSignature + 8, d.begin());
}

/// compressedDepth's header before the PNG: the compression (an int32) and the two floats of
/// the inverse-depth quantisation (compressed_depth_image_transport's ConfigHeader).
constexpr size_t kDepthHeaderBytes = 12;

}  // namespace

bool isCompressedColourFormat(std::string_view format) {
  const std::string f = lowered(format);
  return !contains(f, "compresseddepth") && (contains(f, "jpeg") || contains(f, "jpg") || contains(f, "png"));
}

bool isCompressedDepthFormat(std::string_view format) { return contains(lowered(format), "compresseddepth"); }

ImageRgb compressedColourImage(const CompressedView& im, const std::string& source) {
  if (isCompressedDepthFormat(im.format)) {
    throw DataError(source + ": a compressedDepth image ('" + std::string(im.format) + "') is not a colour image");
  }
  const std::vector<uint8_t> bytes(im.data.begin(), im.data.end());
  if (looksLikeJpeg(bytes)) return decodeJpegRgb(bytes, source);
  if (isPng(im.data)) return decodePngRgb(bytes, source);
  throw DataError(source + ": compressed image of format '" + std::string(im.format) +
                  "' is neither a JPEG nor a PNG (the compressions read)");
}

OwnedImage compressedDepthImage(const CompressedView& im, const std::string& source) {
  const std::string f = lowered(im.format);
  if (!contains(f, "compresseddepth")) {
    throw DataError(source + ": compressed image of format '" + std::string(im.format) +
                    "' is not compressedDepth (a depth topic of sensor_msgs/CompressedImage must be)");
  }
  if (contains(f, "rvl")) {
    throw DataError(source + ": compressedDepth with RVL compression ('" + std::string(im.format) +
                    "') is not read (PNG only)");
  }
  const std::string_view encoding = encodingOf(im.format);
  const bool metres = encoding == "32FC1";
  if (!metres && encoding != "16UC1" && encoding != "mono16") {
    throw DataError(source + ": compressedDepth of encoding '" + std::string(encoding) + "' is not read (16UC1, 32FC1)");
  }
  if (im.data.size() < kDepthHeaderBytes || !isPng(im.data.subspan(kDepthHeaderBytes))) {
    throw FormatError(source + ": compressedDepth data is not a 12-byte header followed by a PNG");
  }
  const std::vector<uint8_t> png(im.data.begin() + kDepthHeaderBytes, im.data.end());
  const ImageU16 units = decodePngU16(png, source);
  OwnedImage out;
  out.view.width = units.width;
  out.view.height = units.height;
  out.view.big_endian = false;
  const size_t n = units.pixels.size();
  if (!metres) {
    out.bytes.resize(2 * n);
    std::memcpy(out.bytes.data(), units.pixels.data(), 2 * n);  // little-endian host
    out.view.encoding = "16UC1";
    out.view.step = 2 * units.width;
  } else {
    float a = 0.0f, b = 0.0f;
    std::memcpy(&a, im.data.data() + 4, 4);
    std::memcpy(&b, im.data.data() + 8, 4);
    if (!std::isfinite(a) || !std::isfinite(b) || a == 0.0f) {
      throw FormatError(source + ": compressedDepth's quantisation parameters are not finite and non-zero");
    }
    std::vector<float> depth(n);
    for (size_t i = 0; i < n; ++i) {
      const float v = static_cast<float>(units.pixels[i]);
      depth[i] = units.pixels[i] == 0 ? std::numeric_limits<float>::quiet_NaN() : a / (v - b);
    }
    out.bytes.resize(4 * n);
    std::memcpy(out.bytes.data(), depth.data(), 4 * n);
    out.view.encoding = "32FC1";
    out.view.step = 4 * units.width;
  }
  out.view.data = std::span<const uint8_t>(out.bytes.data(), out.bytes.size());
  return out;
}

bool isDepthEncoding(std::string_view e) { return e == "16UC1" || e == "mono16" || e == "32FC1"; }
bool isColourEncoding(std::string_view e) {
  return e == "rgb8" || e == "bgr8" || e == "mono8" || e == "rgba8" || e == "bgra8";
}

ImageRgb colourImage(const ImageView& im, const std::string& source) {
  if (!isColourEncoding(im.encoding)) {
    throw DataError(source + ": colour encoding '" + std::string(im.encoding) +
                    "' is not read (rgb8, bgr8, mono8, rgba8, bgra8)");
  }
  const uint32_t bpp = checkImage(im, source);
  ImageRgb out{im.width, im.height, std::vector<Rgb>(size_t{im.width} * im.height)};
  const bool bgr = im.encoding == "bgr8" || im.encoding == "bgra8";
  for (uint32_t v = 0; v < im.height; ++v) {
    const uint8_t* row = im.data.data() + size_t{v} * im.step;
    Rgb* dst = out.pixels.data() + size_t{v} * im.width;
    for (uint32_t u = 0; u < im.width; ++u) {
      const uint8_t* p = row + size_t{u} * bpp;
      if (bpp == 1) {
        dst[u] = {p[0], p[0], p[0]};
      } else if (bgr) {
        dst[u] = {p[2], p[1], p[0]};
      } else {
        dst[u] = {p[0], p[1], p[2]};
      }
    }
  }
  return out;
}

PointCloud depthCloud(const ImageView& im, const ImageRgb* rgb, const CameraIntrinsics& k, double depth_scale,
                      const std::string& source) {
  if (!isDepthEncoding(im.encoding)) {
    throw DataError(source + ": depth encoding '" + std::string(im.encoding) + "' is not read (16UC1, 32FC1)");
  }
  checkImage(im, source);
  checkIntrinsicsFit(k, im.width, im.height, source);
  const bool swap = im.big_endian != kHostBigEndian;
  if (im.encoding == "32FC1") {
    std::vector<float> metres(size_t{im.width} * im.height);
    for (uint32_t v = 0; v < im.height; ++v) {
      const uint8_t* row = im.data.data() + size_t{v} * im.step;
      for (uint32_t u = 0; u < im.width; ++u) metres[size_t{v} * im.width + u] = readScalar<float>(row + 4 * u, swap);
    }
    return depthMetresToCloud(metres, im.width, im.height, rgb, k, source);
  }
  ImageU16 units{im.width, im.height, std::vector<uint16_t>(size_t{im.width} * im.height)};
  for (uint32_t v = 0; v < im.height; ++v) {
    const uint8_t* row = im.data.data() + size_t{v} * im.step;
    for (uint32_t u = 0; u < im.width; ++u)
      units.pixels[size_t{v} * im.width + u] = readScalar<uint16_t>(row + 2 * u, swap);
  }
  return depthToCloud(units, rgb, k, depth_scale, source);
}

namespace {

/// Reads a field of one of the numeric PointField types as a double.
double readField(const uint8_t* p, uint8_t datatype, bool swap) {
  switch (datatype) {
    case 1:
      return static_cast<int8_t>(p[0]);
    case 2:
      return p[0];
    case 3:
      return readScalar<int16_t>(p, swap);
    case 4:
      return readScalar<uint16_t>(p, swap);
    case 5:
      return readScalar<int32_t>(p, swap);
    case 6:
      return readScalar<uint32_t>(p, swap);
    case 7:
      return readScalar<float>(p, swap);
    case 8:
      return readScalar<double>(p, swap);
    default:
      return std::numeric_limits<double>::quiet_NaN();
  }
}

uint32_t fieldBytes(uint8_t datatype) {
  static constexpr uint32_t kBytes[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
  return datatype <= 8 ? kBytes[datatype] : 0;
}

}  // namespace

PointCloud pointCloud(const CloudView& c, const std::string& source) {
  const auto find = [&](std::string_view name) -> std::optional<PointField> {
    for (const PointField& f : c.fields) {
      if (f.name == name) {
        const uint32_t bytes = fieldBytes(f.datatype);
        if (bytes == 0 || uint64_t{f.offset} + bytes > c.point_step) {
          throw DataError(source + ": field '" + std::string(name) + "' has an unknown type or lies past the point");
        }
        return f;
      }
    }
    return std::nullopt;
  };
  const auto x = find("x"), y = find("y"), z = find("z");
  if (!x || !y || !z) throw DataError(source + ": the point cloud has no x, y and z fields");
  auto colour = find("rgb");
  if (!colour) colour = find("rgba");
  if (colour && fieldBytes(colour->datatype) != 4) throw DataError(source + ": the rgb field is not 4 bytes");
  if (uint64_t{c.row_step} < uint64_t{c.width} * c.point_step || uint64_t{c.row_step} * c.height > c.data.size()) {
    std::ostringstream msg;
    msg << source << ": a " << c.width << "x" << c.height << " cloud with points of " << c.point_step
        << " bytes and rows of " << c.row_step << " bytes does not fit its " << c.data.size() << " bytes of data";
    throw DataError(msg.str());
  }
  const bool swap = c.big_endian != kHostBigEndian;
  PointCloud out;
  out.width = c.width;
  out.height = c.height;
  const size_t n = size_t{c.width} * c.height;
  // An empty cloud: no rows to walk (4 billion rows of width 0 took fuzz_cdr past its timeout).
  if (n == 0) return out;
  out.points.resize(n);
  if (colour) out.colours.resize(n);
  for (uint32_t v = 0; v < c.height; ++v) {
    for (uint32_t u = 0; u < c.width; ++u) {
      const uint8_t* p = c.data.data() + size_t{v} * c.row_step + size_t{u} * c.point_step;
      const size_t i = size_t{v} * c.width + u;
      out.points[i] =
          Eigen::Vector3d(readField(p + x->offset, x->datatype, swap), readField(p + y->offset, y->datatype, swap),
                          readField(p + z->offset, z->datatype, swap))
              .cast<float>();
      if (colour) {
        // PCL packs 0x00RRGGBB into the four bytes, whether the field says FLOAT32 or UINT32.
        const uint32_t packed = readScalar<uint32_t>(p + colour->offset, swap);
        out.colours[i] = {static_cast<uint8_t>(packed >> 16), static_cast<uint8_t>(packed >> 8),
                         static_cast<uint8_t>(packed)};
      }
    }
  }
  return out;
}

}  // namespace chronomap::rosmsg
