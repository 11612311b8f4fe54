// CDR (XCDR1) decoding of the ROS 2 messages chronomap reads.

#include "cdr.h"

#include <cstring>

#include "chronomap/core/error.h"

namespace chronomap::cdr {

namespace {

/// The fields of one CDR message, after its encapsulation header.
class Reader {
 public:
  Reader(std::span<const uint8_t> msg, const std::string& source) : source_(source) {
    if (msg.size() < 4) fail("shorter than the 4-byte CDR encapsulation header");
    if (msg[0] != 0 || (msg[1] != 0 && msg[1] != 1)) {
      fail("unknown CDR encapsulation " + std::to_string(msg[0]) + "," + std::to_string(msg[1]) +
           " (read: plain CDR, big- or little-endian)");
    }
    little_ = msg[1] == 1;
    b_ = msg.subspan(4);
  }

  uint8_t u8() { return static_cast<uint8_t>(prim(1)); }
  uint32_t u32() { return static_cast<uint32_t>(prim(4)); }
  int32_t i32() { return static_cast<int32_t>(u32()); }
  double f64() {
    const uint64_t v = prim(8);
    double d;
    std::memcpy(&d, &v, 8);
    return d;
  }
  std::string_view str() {
    const uint32_t n = u32();
    const auto s = bytes(n, "string");
    // CDR strings hold their terminating NUL in the length.
    if (n == 0) return {};
    if (s[n - 1] != 0) fail("a string without its terminating NUL");
    return {reinterpret_cast<const char*>(s.data()), n - 1};
  }
  std::span<const uint8_t> bytes(uint64_t n, const char* what) {
    if (n > b_.size() - pos_) {
      fail(std::string("a ") + what + " of " + std::to_string(n) + " bytes, " + std::to_string(b_.size() - pos_) +
           " left");
    }
    auto out = b_.subspan(pos_, n);
    pos_ += n;
    return out;
  }
  /// A sequence's element count, checked against the bytes left (each element at least `least`).
  uint32_t count(uint64_t least, const char* what) {
    const uint32_t n = u32();
    if (least > 0 && n > (b_.size() - pos_) / least) {
      fail(std::string("a sequence of ") + std::to_string(n) + " " + what + " in " + std::to_string(b_.size() - pos_) +
           " bytes");
    }
    return n;
  }
  Header header() {
    Header h;
    const int32_t sec = i32();
    const uint32_t nsec = u32();
    h.stamp = static_cast<double>(sec) + 1e-9 * static_cast<double>(nsec);
    h.frame_id = str();
    return h;
  }
  bool little() const { return little_; }
  [[noreturn]] void fail(const std::string& problem) const { throw FormatError(source_ + ": CDR: " + problem); }

 private:
  uint64_t prim(size_t n) {
    pos_ = (pos_ + n - 1) / n * n;  // aligned to its size
    if (pos_ > b_.size() || n > b_.size() - pos_) fail("the message ends inside a field (truncated?)");
    uint64_t v = 0;
    for (size_t i = 0; i < n; ++i) {
      const uint64_t byte = b_[pos_ + (little_ ? i : n - 1 - i)];
      v |= byte << (8 * i);
    }
    pos_ += n;
    return v;
  }
  std::span<const uint8_t> b_;
  size_t pos_ = 0;
  bool little_ = true;
  const std::string& source_;
};

void pose(Reader& r, Transform& t) {
  for (double& v : t.xyz) v = r.f64();
  for (double& v : t.q) v = r.f64();
}

}  // namespace

Header header(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  return r.header();
}

Image image(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  Image im;
  im.header = r.header();
  im.view.height = r.u32();
  im.view.width = r.u32();
  im.view.encoding = r.str();
  im.view.big_endian = r.u8() != 0;
  im.view.step = r.u32();
  im.view.data = r.bytes(r.u32(), "image");
  return im;
}

CompressedImage compressedImage(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  CompressedImage im;
  im.header = r.header();
  im.view.format = r.str();
  im.view.data = r.bytes(r.u32(), "compressed image");
  return im;
}

Cloud cloud(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  Cloud c;
  c.header = r.header();
  c.view.height = r.u32();
  c.view.width = r.u32();
  const uint32_t n = r.count(13, "point fields");  // name (4 + 1), offset, datatype, count
  c.view.fields.reserve(n);
  for (uint32_t i = 0; i < n; ++i) {
    rosmsg::PointField f;
    f.name = r.str();
    f.offset = r.u32();
    f.datatype = r.u8();
    f.count = r.u32();
    c.view.fields.push_back(f);
  }
  c.view.big_endian = r.u8() != 0;
  c.view.point_step = r.u32();
  c.view.row_step = r.u32();
  c.view.data = r.bytes(r.u32(), "cloud");
  r.u8();  // is_dense
  return c;
}

CameraInfo cameraInfo(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  CameraInfo info;
  info.header = r.header();
  info.height = r.u32();
  info.width = r.u32();
  r.str();  // distortion_model
  const uint32_t d = r.count(8, "distortion coefficients");
  for (uint32_t i = 0; i < d; ++i) r.f64();
  for (double& v : info.k) v = r.f64();
  return info;
}

std::vector<Transform> tfMessage(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  // header (4 + 4 + 4) + child (4) + 7 doubles.
  const uint32_t n = r.count(72, "transforms");
  std::vector<Transform> out(n);
  for (Transform& t : out) {
    t.header = r.header();
    t.child = r.str();
    pose(r, t);
  }
  return out;
}

Transform odometry(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  Transform t;
  t.header = r.header();
  t.child = r.str();
  pose(r, t);
  return t;
}

Transform poseStamped(std::span<const uint8_t> msg, const std::string& source) {
  Reader r(msg, source);
  Transform t;
  t.header = r.header();
  pose(r, t);
  return t;
}

}  // namespace chronomap::cdr
