#include <lzf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/core/file.h"
#include "chronomap/core/pose.h"
#include "text_util.h"

namespace chronomap {

namespace {

/// Longest PCD header readPcdViewpoint looks through.
constexpr size_t kPcdHeaderMaxBytes = 64 * 1024;

struct PcdField {
  std::string name;
  int size = 4;
  char type = 'F';
  int count = 1;
  size_t offset = 0;  // within a binary point record
};

struct PcdHeader {
  std::vector<PcdField> fields;
  uint64_t width = 0, height = 1, points = 0;
  std::string data;
  size_t header_bytes = 0;
  size_t point_bytes = 0;
  std::vector<std::string> viewpoint;  // the VIEWPOINT line's values, as written
};

double readScalar(const uint8_t* p, const PcdField& f) {
  switch (f.type) {
    case 'F':
      if (f.size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      } else {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    case 'U': {
      uint64_t v = 0;
      std::memcpy(&v, p, static_cast<size_t>(f.size));
      return static_cast<double>(v);
    }
    default: {  // 'I'
      int64_t v = 0;
      std::memcpy(&v, p, static_cast<size_t>(f.size));
      const int shift = 64 - 8 * f.size;
      return static_cast<double>((v << shift) >> shift);
    }
  }
}

uint32_t readPacked(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

Rgb unpackRgb(uint32_t v) {
  return Rgb{static_cast<uint8_t>((v >> 16) & 0xff), static_cast<uint8_t>((v >> 8) & 0xff),
             static_cast<uint8_t>(v & 0xff)};
}

PcdHeader parseHeader(const std::vector<uint8_t>& bytes, const std::string& name) {
  PcdHeader h;
  size_t pos = 0;
  std::vector<int> sizes, counts;
  std::vector<char> types;
  bool have_data = false;
  while (pos < bytes.size() && !have_data) {
    size_t eol = pos;
    while (eol < bytes.size() && bytes[eol] != '\n') ++eol;
    if (eol == bytes.size()) throw FormatError(name + ": PCD header is truncated (no DATA line)");
    std::string line(bytes.begin() + static_cast<long>(pos), bytes.begin() + static_cast<long>(eol));
    pos = eol + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    std::string key;
    in >> key;
    std::vector<std::string> values;
    for (std::string v; in >> v;) values.push_back(v);
    auto number = [&](const std::string& v) -> uint64_t { return parseUnsigned(v, name + ": PCD " + key); };
    if (key == "VERSION") continue;
    if (key == "FIELDS") {
      for (auto& v : values) h.fields.push_back(PcdField{v});
    } else if (key == "SIZE") {
      for (auto& v : values) sizes.push_back(static_cast<int>(number(v)));
    } else if (key == "TYPE") {
      for (auto& v : values) {
        if (v.size() != 1 || (v[0] != 'F' && v[0] != 'U' && v[0] != 'I')) {
          throw FormatError(name + ": PCD TYPE '" + v + "' is not F, U or I");
        }
        types.push_back(v[0]);
      }
    } else if (key == "COUNT") {
      for (auto& v : values) counts.push_back(static_cast<int>(number(v)));
    } else if (key == "WIDTH" && values.size() == 1) {
      h.width = number(values[0]);
    } else if (key == "HEIGHT" && values.size() == 1) {
      h.height = number(values[0]);
    } else if (key == "POINTS" && values.size() == 1) {
      h.points = number(values[0]);
    } else if (key == "VIEWPOINT") {
      h.viewpoint = values;  // checked by pcdViewpointPose where a reader takes the pose from it
    } else if (key == "DATA" && values.size() == 1) {
      h.data = values[0];
      have_data = true;
    } else {
      throw FormatError(name + ": PCD header line '" + line + "' is not understood");
    }
  }
  if (!have_data) throw FormatError(name + ": PCD header has no DATA line");
  h.header_bytes = pos;
  if (h.fields.empty()) throw FormatError(name + ": PCD header has no FIELDS");
  if (sizes.size() != h.fields.size() || types.size() != h.fields.size()) {
    throw FormatError(name + ": PCD FIELDS, SIZE and TYPE differ in length");
  }
  if (counts.empty()) counts.assign(h.fields.size(), 1);
  if (counts.size() != h.fields.size()) throw FormatError(name + ": PCD FIELDS and COUNT differ in length");
  for (size_t i = 0; i < h.fields.size(); ++i) {
    PcdField& f = h.fields[i];
    f.size = sizes[i];
    f.type = types[i];
    f.count = counts[i];
    const bool ok_size = f.type == 'F' ? (f.size == 4 || f.size == 8) : (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8);
    if (!ok_size || f.count < 1 || f.count > 1024) {
      throw FormatError(name + ": PCD field '" + f.name + "' has an unsupported size or count");
    }
    f.offset = h.point_bytes;
    h.point_bytes += static_cast<size_t>(f.size) * static_cast<size_t>(f.count);
  }
  if (h.points == 0) h.points = h.width * h.height;
  if (h.width * h.height != h.points) throw FormatError(name + ": PCD WIDTH x HEIGHT differs from POINTS");
  if (h.points > (uint64_t{1} << 31)) throw FormatError(name + ": PCD has too many points");
  return h;
}

/// The first `max_bytes` of a file (all of it when compressed: .bz2 is read whole).
std::vector<uint8_t> readPrefix(const std::filesystem::path& path, size_t max_bytes) {
  if (path.extension() == ".bz2") return readFileBytes(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot open for reading");
  std::vector<uint8_t> out(max_bytes);
  in.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(max_bytes));
  out.resize(static_cast<size_t>(in.gcount()));
  return out;
}

const PcdField* findField(const PcdHeader& h, std::initializer_list<const char*> names) {
  for (const char* n : names) {
    for (const auto& f : h.fields) {
      if (f.name == n) return &f;
    }
  }
  return nullptr;
}

}  // namespace

PointCloud readPcd(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return parsePcd(readFileBytes(path), path.string()); });
}

PointCloud readPcd(const std::filesystem::path& path, PcdExtras& extras) {
  return readNamingMemory(path, [&] { return parsePcd(readFileBytes(path), path.string(), &extras); });
}

std::vector<std::string> readPcdViewpoint(const std::filesystem::path& path) {
  // The header only: a sequence's poses are read when it is opened, its points frame by frame.
  std::vector<uint8_t> head = readPrefix(path, kPcdHeaderMaxBytes);
  const std::string text(head.begin(), head.end());
  if (text.find("\nDATA") == std::string::npos && text.rfind("DATA", 0) != 0) {
    throw FormatError(path.string() + ": PCD header has no DATA line in its first " +
                      std::to_string(kPcdHeaderMaxBytes) + " bytes");
  }
  return parseHeader(head, path.string()).viewpoint;
}

Eigen::Isometry3d pcdViewpointPose(const std::vector<std::string>& values, const std::string& name) {
  if (values.empty()) {
    throw DataError(name + ": PCD has no VIEWPOINT line; the sensor pose must be given there as 'VIEWPOINT tx ty tz qw qx qy qz'");
  }
  if (values.size() != 7) {
    throw DataError(name + ": PCD VIEWPOINT has " + std::to_string(values.size()) +
                    " values, expected 7 (tx ty tz qw qx qy qz)");
  }
  double v[7];
  for (size_t i = 0; i < 7; ++i) v[i] = parseDouble(values[i], name + ": PCD VIEWPOINT value " + std::to_string(i + 1));
  return poseFromTranslationQuaternion({v[0], v[1], v[2]}, v[4], v[5], v[6], v[3], name + ": PCD VIEWPOINT");
}

PointCloud parsePcd(const std::vector<uint8_t>& bytes, const std::string& name, PcdExtras* extras) {
  const PcdHeader h = parseHeader(bytes, name);
  if (extras) {
    extras->viewpoint = h.viewpoint;
    extras->intensity.clear();
  }
  const PcdField* fx = findField(h, {"x"});
  const PcdField* fy = findField(h, {"y"});
  const PcdField* fz = findField(h, {"z"});
  if (!fx || !fy || !fz) throw FormatError(name + ": PCD has no x, y and z fields");
  for (const PcdField* f : {fx, fy, fz}) {
    if (f->type != 'F') throw FormatError(name + ": PCD field " + f->name + " is not floating point");
  }
  const PcdField* frgb = findField(h, {"rgb", "rgba"});
  if (frgb && frgb->size != 4) throw FormatError(name + ": PCD rgb field is not 4 bytes");
  const PcdField* flabel = findField(h, {"label"});
  const PcdField* fintensity = extras ? findField(h, {"intensity"}) : nullptr;

  PointCloud cloud;
  const size_t n = static_cast<size_t>(h.points);
  const uint8_t* data = bytes.data() + h.header_bytes;
  const size_t available = bytes.size() - h.header_bytes;
  size_t per_point = 0;
  for (const auto& f : h.fields) per_point += static_cast<size_t>(f.count);
  // The data's layout against the header, before the points are allocated: a header that
  // declares two billion points over a few bytes must not take gigabytes (found by fuzzing).
  // LZF turns 3 bytes into at most 264; ASCII text is allocated for as many points as it can
  // hold (below).
  uint32_t compressed = 0, raw = 0;
  if (h.data == "binary") {
    if (h.point_bytes != 0 && n > available / h.point_bytes) {
      throw FormatError(name + ": PCD binary data is truncated (" + std::to_string(available) + " bytes for " +
                        std::to_string(n) + " points of " + std::to_string(h.point_bytes) + " bytes)");
    }
  } else if (h.data == "binary_compressed") {
    if (available < 8) throw FormatError(name + ": PCD compressed data is truncated");
    compressed = readPacked(data);
    raw = readPacked(data + 4);
    if (raw / 88 > compressed) {
      throw FormatError(name + ": PCD compressed data is corrupt (" + std::to_string(compressed) +
                        " bytes cannot expand to " + std::to_string(raw) + ")");
    }
    if (raw != n * h.point_bytes) throw FormatError(name + ": PCD compressed size does not match the header");
    if (compressed > available - 8) throw FormatError(name + ": PCD compressed data is truncated");
  } else if (h.data != "ascii") {
    throw FormatError(name + ": PCD DATA '" + h.data + "' is not ascii, binary or binary_compressed");
  }
  // An ASCII point takes at least a digit and a separator per value (the last line may lack
  // its newline), so the text holds at most (available + 1) / (2 * values per point) points.
  const size_t capacity =
      h.data == "ascii" && per_point != 0 ? std::min(n, (available + 1) / (2 * per_point)) : n;
  cloud.width = static_cast<uint32_t>(h.width);
  cloud.height = static_cast<uint32_t>(h.height);
  cloud.points.resize(capacity);
  if (frgb) cloud.colours.resize(capacity);
  if (flabel) cloud.labels.resize(capacity);
  if (fintensity) extras->intensity.resize(capacity);

  if (h.data == "ascii") {
    std::string text(reinterpret_cast<const char*>(data), available);
    std::istringstream in(text);
    std::string line;
    size_t i = 0;
    std::vector<std::string> tok;
    while (i < n && std::getline(in, line)) {
      tok = splitWhitespace(line);
      if (tok.empty()) continue;
      if (i == capacity) break;  // more points than the text can hold: impossible, reported below
      if (tok.size() != per_point) {
        throw FormatError(name + ": PCD point " + std::to_string(i) + " has " + std::to_string(tok.size()) +
                          " values, expected " + std::to_string(per_point));
      }
      size_t t = 0;
      for (const auto& f : h.fields) {
        const std::string& v = tok[t];
        auto num = [&]() { return parseDouble(v, name + ": PCD point " + std::to_string(i)); };
        const std::string ctx = name + ": PCD point " + std::to_string(i);
        if (&f == fx) cloud.points[i].x() = toFloat(num());
        if (&f == fy) cloud.points[i].y() = toFloat(num());
        if (&f == fz) cloud.points[i].z() = toFloat(num());
        if (&f == frgb) {
          uint32_t packed;
          if (f.type == 'F') {
            const float fv = toFloat(num());
            std::memcpy(&packed, &fv, 4);
          } else {
            packed = static_cast<uint32_t>(checkedInteger(num(), 0.0, 4294967295.0, ctx + " rgb"));
          }
          cloud.colours[i] = unpackRgb(packed);
        }
        if (&f == flabel) {
          cloud.labels[i] = static_cast<uint32_t>(checkedInteger(num(), 0.0, 4294967295.0, ctx + " label"));
        }
        if (&f == fintensity) extras->intensity[i] = static_cast<float>(num());
        t += static_cast<size_t>(f.count);
      }
      ++i;
    }
    if (i != n) {
      throw FormatError(name + ": PCD is truncated: " + std::to_string(i) + " of " + std::to_string(n) + " points");
    }
    return cloud;
  }

  // Binary layouts: either one record per point (binary) or one array per field (compressed).
  std::vector<uint8_t> soa;
  bool field_major = false;
  const uint8_t* base = data;
  if (h.data == "binary_compressed") {
    soa.resize(raw);
    if (raw > 0) {
      const unsigned got = lzf_decompress(data + 8, compressed, soa.data(), raw);
      if (got != raw) throw FormatError(name + ": PCD compressed data is corrupt");
    }
    base = soa.data();
    field_major = true;
  }
  auto at = [&](const PcdField& f, size_t i) -> const uint8_t* {
    if (field_major) return base + f.offset * n + i * static_cast<size_t>(f.size) * static_cast<size_t>(f.count);
    return base + i * h.point_bytes + f.offset;
  };
  for (size_t i = 0; i < n; ++i) {
    cloud.points[i] = Eigen::Vector3f(toFloat(readScalar(at(*fx, i), *fx)), toFloat(readScalar(at(*fy, i), *fy)),
                                      toFloat(readScalar(at(*fz, i), *fz)));
    if (frgb) cloud.colours[i] = unpackRgb(readPacked(at(*frgb, i)));
    if (fintensity) extras->intensity[i] = static_cast<float>(readScalar(at(*fintensity, i), *fintensity));
    if (flabel) {
      const double label = readScalar(at(*flabel, i), *flabel);
      cloud.labels[i] = static_cast<uint32_t>(
          checkedInteger(label, 0.0, 4294967295.0, name + ": PCD point " + std::to_string(i) + " label"));
    }
  }
  return cloud;
}

void writePcd(const std::filesystem::path& path, const PointCloud& cloud, PcdEncoding encoding,
              const PcdExtras* extras) {
  const size_t n = cloud.points.size();
  const bool rgb = cloud.hasColours();
  const bool label = cloud.hasLabels();
  const bool intensity = extras && !extras->intensity.empty();
  if (intensity && extras->intensity.size() != n) {
    throw UsageError(path.string() + ": " + std::to_string(extras->intensity.size()) + " intensities for " +
                     std::to_string(n) + " points");
  }
  std::string viewpoint = "0 0 0 1 0 0 0";
  if (extras && !extras->viewpoint.empty()) {
    if (extras->viewpoint.size() != 7) throw UsageError(path.string() + ": a PCD VIEWPOINT takes 7 values");
    viewpoint.clear();
    for (const std::string& v : extras->viewpoint) viewpoint += (viewpoint.empty() ? "" : " ") + v;
  }
  const uint32_t width = (cloud.width * cloud.height == n) ? cloud.width : static_cast<uint32_t>(n);
  const uint32_t height = (cloud.width * cloud.height == n) ? cloud.height : 1;
  std::ostringstream hdr;
  hdr << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z" << (intensity ? " intensity" : "")
      << (rgb ? " rgb" : "") << (label ? " label" : "") << "\nSIZE 4 4 4" << (intensity ? " 4" : "")
      << (rgb ? " 4" : "") << (label ? " 4" : "") << "\nTYPE F F F" << (intensity ? " F" : "") << (rgb ? " U" : "")
      << (label ? " U" : "") << "\nCOUNT 1 1 1" << (intensity ? " 1" : "") << (rgb ? " 1" : "") << (label ? " 1" : "")
      << "\nWIDTH " << width << "\nHEIGHT " << height << "\nVIEWPOINT " << viewpoint << "\nPOINTS " << n
      << "\nDATA "
      << (encoding == PcdEncoding::Ascii ? "ascii" : encoding == PcdEncoding::Binary ? "binary" : "binary_compressed")
      << "\n";
  const std::string header = hdr.str();
  std::vector<uint8_t> out(header.begin(), header.end());
  auto packed = [&](size_t i) {
    const Rgb c = cloud.colours[i];
    return (uint32_t{c.r} << 16) | (uint32_t{c.g} << 8) | uint32_t{c.b};
  };
  auto append = [](std::vector<uint8_t>& v, const void* p, size_t bytes) {
    const auto* b = static_cast<const uint8_t*>(p);
    v.insert(v.end(), b, b + bytes);
  };
  if (encoding == PcdEncoding::Ascii) {
    std::ostringstream body;
    body.precision(9);
    for (size_t i = 0; i < n; ++i) {
      const auto& p = cloud.points[i];
      body << p.x() << ' ' << p.y() << ' ' << p.z();
      if (intensity) body << ' ' << extras->intensity[i];
      if (rgb) body << ' ' << packed(i);
      if (label) body << ' ' << cloud.labels[i];
      body << '\n';
    }
    const std::string s = body.str();
    out.insert(out.end(), s.begin(), s.end());
  } else if (encoding == PcdEncoding::Binary) {
    for (size_t i = 0; i < n; ++i) {
      append(out, cloud.points[i].data(), 12);
      if (intensity) append(out, &extras->intensity[i], 4);
      if (rgb) {
        const uint32_t v = packed(i);
        append(out, &v, 4);
      }
      if (label) append(out, &cloud.labels[i], 4);
    }
  } else {
    std::vector<uint8_t> soa;
    for (int a = 0; a < 3; ++a) {
      for (size_t i = 0; i < n; ++i) append(soa, &cloud.points[i][a], 4);
    }
    if (intensity) append(soa, extras->intensity.data(), 4 * n);
    if (rgb) {
      for (size_t i = 0; i < n; ++i) {
        const uint32_t v = packed(i);
        append(soa, &v, 4);
      }
    }
    if (label) append(soa, cloud.labels.data(), 4 * n);
    std::vector<uint8_t> comp(soa.size() + soa.size() / 16 + 64);
    unsigned csize = soa.empty() ? 0 : lzf_compress(soa.data(), static_cast<unsigned>(soa.size()), comp.data(),
                                                   static_cast<unsigned>(comp.size()));
    if (!soa.empty() && csize == 0) throw IoError(path.string() + ": LZF compression failed");
    const uint32_t sizes[2] = {csize, static_cast<uint32_t>(soa.size())};
    append(out, sizes, 8);
    out.insert(out.end(), comp.begin(), comp.begin() + csize);
  }
  writeFileAtomic(path, out);
}

}  // namespace chronomap
