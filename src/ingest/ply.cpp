#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/core/file.h"
#include "text_util.h"

namespace chronomap {

namespace {

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

int typeSize(PlyType t) {
  switch (t) {
    case PlyType::Int8:
    case PlyType::UInt8:
      return 1;
    case PlyType::Int16:
    case PlyType::UInt16:
      return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32:
      return 4;
    case PlyType::Float64:
      return 8;
  }
  return 0;
}

bool parseType(const std::string& s, PlyType& t) {
  static const std::pair<const char*, PlyType> names[] = {
      {"char", PlyType::Int8},     {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
      {"uint8", PlyType::UInt8},   {"short", PlyType::Int16},     {"int16", PlyType::Int16},
      {"ushort", PlyType::UInt16}, {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
      {"int32", PlyType::Int32},   {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
      {"float", PlyType::Float32}, {"float32", PlyType::Float32}, {"double", PlyType::Float64},
      {"float64", PlyType::Float64}};
  for (auto& [n, v] : names) {
    if (s == n) {
      t = v;
      return true;
    }
  }
  return false;
}

double readBinary(const uint8_t* p, PlyType t, bool big_endian) {
  uint8_t buf[8];
  const int n = typeSize(t);
  std::memcpy(buf, p, static_cast<size_t>(n));
  if (big_endian) std::reverse(buf, buf + n);
  switch (t) {
    case PlyType::Int8: return static_cast<int8_t>(buf[0]);
    case PlyType::UInt8: return buf[0];
    case PlyType::Int16: { int16_t v; std::memcpy(&v, buf, 2); return v; }
    case PlyType::UInt16: { uint16_t v; std::memcpy(&v, buf, 2); return v; }
    case PlyType::Int32: { int32_t v; std::memcpy(&v, buf, 4); return v; }
    case PlyType::UInt32: { uint32_t v; std::memcpy(&v, buf, 4); return v; }
    case PlyType::Float32: { float v; std::memcpy(&v, buf, 4); return v; }
    case PlyType::Float64: { double v; std::memcpy(&v, buf, 8); return v; }
  }
  return 0;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;
  bool is_list = false;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> props;
};

uint8_t toColourByte(double v, PlyType t) {
  if (t == PlyType::Float32 || t == PlyType::Float64) v *= 255.0;
  if (!(v > 0.0)) return 0;  // also NaN
  return static_cast<uint8_t>(std::lround(std::min(v, 255.0)));
}

}  // namespace

PointCloud readPly(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return parsePly(readFileBytes(path), path.string()); });
}

PointCloud parsePly(const std::vector<uint8_t>& bytes, const std::string& name) {
  size_t pos = 0;
  auto nextLine = [&]() -> std::string {
    size_t eol = pos;
    while (eol < bytes.size() && bytes[eol] != '\n') ++eol;
    if (eol >= bytes.size()) throw FormatError(name + ": PLY header is truncated (no end_header)");
    std::string line(bytes.begin() + static_cast<long>(pos), bytes.begin() + static_cast<long>(eol));
    pos = eol + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return line;
  };
  if (bytes.size() < 4 || std::memcmp(bytes.data(), "ply", 3) != 0) throw FormatError(name + ": not a PLY file");
  nextLine();
  std::string format;
  std::vector<PlyElement> elements;
  while (true) {
    const std::string line = nextLine();
    const auto tok = splitWhitespace(line);
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "end_header") break;
    if (tok[0] == "format" && tok.size() >= 2) {
      format = tok[1];
    } else if (tok[0] == "element" && tok.size() == 3) {
      elements.push_back(PlyElement{tok[1], parseUnsigned(tok[2], name + ": PLY element count"), {}});
    } else if (tok[0] == "property" && !elements.empty()) {
      PlyProperty p;
      if (tok.size() == 5 && tok[1] == "list") {
        p.is_list = true;
        p.name = tok[4];
      } else if (tok.size() == 3) {
        if (!parseType(tok[1], p.type)) throw FormatError(name + ": PLY property type '" + tok[1] + "' is unknown");
        p.name = tok[2];
      } else {
        throw FormatError(name + ": PLY header line '" + line + "' is malformed");
      }
      elements.back().props.push_back(p);
    } else {
      throw FormatError(name + ": PLY header line '" + line + "' is not understood");
    }
  }
  if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian") {
    throw FormatError(name + ": PLY format '" + format + "' is not supported");
  }
  const bool ascii = format == "ascii";
  const bool big = format == "binary_big_endian";

  PointCloud cloud;
  std::string text;
  std::istringstream lines;
  if (ascii) {
    text.assign(bytes.begin() + static_cast<long>(pos), bytes.end());
    lines.str(text);
  }
  for (const PlyElement& el : elements) {
    const bool is_vertex = el.name == "vertex";
    int ix = -1, iy = -1, iz = -1, ir = -1, ig = -1, ib = -1;
    size_t record = 0;
    std::vector<size_t> offsets;
    for (size_t i = 0; i < el.props.size(); ++i) {
      const auto& p = el.props[i];
      if (p.is_list && (is_vertex || !ascii)) {
        throw FormatError(name + ": PLY list property '" + p.name + "' before or in the vertices is not supported");
      }
      offsets.push_back(record);
      record += p.is_list ? 0 : static_cast<size_t>(typeSize(p.type));
      const int idx = static_cast<int>(i);
      if (p.name == "x") ix = idx;
      if (p.name == "y") iy = idx;
      if (p.name == "z") iz = idx;
      if (p.name == "red" || p.name == "r") ir = idx;
      if (p.name == "green" || p.name == "g") ig = idx;
      if (p.name == "blue" || p.name == "b") ib = idx;
    }
    if (!is_vertex) {
      if (ascii) {
        std::string skip;
        for (uint64_t i = 0; i < el.count; ++i) {
          // Stop at the end of the text: a huge declared count must not spin (found by fuzz_ply).
          if (!std::getline(lines, skip)) throw FormatError(name + ": PLY element '" + el.name + "' is truncated");
        }
      } else {
        // Division, not multiplication: a huge count must not overflow the check.
        if (record != 0 && el.count > (bytes.size() - pos) / record) {
          throw FormatError(name + ": PLY element '" + el.name + "' is truncated");
        }
        pos += static_cast<size_t>(el.count) * record;
      }
      continue;
    }
    if (ix < 0 || iy < 0 || iz < 0) throw FormatError(name + ": PLY vertices have no x, y and z");
    if (el.count > (uint64_t{1} << 31)) throw FormatError(name + ": PLY has too many vertices");
    // The data must be able to hold the declared vertices before they are allocated (a header
    // that declares a billion vertices must not take gigabytes; found by fuzz_ply): a binary
    // record has `record` bytes, an ASCII vertex at least a digit and a separator per property
    // (the last line may lack its newline).
    const size_t min_bytes = ascii ? 2 * el.props.size() : record;
    const size_t room = bytes.size() - pos + (ascii ? 1 : 0);
    if (min_bytes != 0 && el.count > room / min_bytes) {
      throw FormatError(name + ": PLY is truncated: the header declares " + std::to_string(el.count) +
                        " vertices, the file holds at most " + std::to_string(room / min_bytes));
    }
    const bool colour = ir >= 0 && ig >= 0 && ib >= 0;
    const size_t n = static_cast<size_t>(el.count);
    cloud.points.resize(n);
    if (colour) cloud.colours.resize(n);
    cloud.width = static_cast<uint32_t>(n);
    cloud.height = 1;
    if (ascii) {
      std::string line;
      for (size_t i = 0; i < n; ++i) {
        do {
          if (!std::getline(lines, line)) {
            throw FormatError(name + ": PLY is truncated: " + std::to_string(i) + " of " + std::to_string(n) +
                              " vertices");
          }
        } while (splitWhitespace(line).empty());
        const auto tok = splitWhitespace(line);
        if (tok.size() < el.props.size()) throw FormatError(name + ": PLY vertex " + std::to_string(i) + " is short");
        const std::string ctx = name + ": PLY vertex " + std::to_string(i);
        cloud.points[i] = Eigen::Vector3f(toFloat(parseDouble(tok[ix], ctx)), toFloat(parseDouble(tok[iy], ctx)),
                                          toFloat(parseDouble(tok[iz], ctx)));
        if (colour) {
          cloud.colours[i] = Rgb{toColourByte(parseDouble(tok[ir], ctx), el.props[ir].type),
                                toColourByte(parseDouble(tok[ig], ctx), el.props[ig].type),
                                toColourByte(parseDouble(tok[ib], ctx), el.props[ib].type)};
        }
      }
    } else {
      if (record == 0 || n > (bytes.size() - pos) / record) {
        throw FormatError(name + ": PLY vertex data is truncated");
      }
      for (size_t i = 0; i < n; ++i) {
        const uint8_t* rec = bytes.data() + pos + i * record;
        auto get = [&](int k) { return readBinary(rec + offsets[k], el.props[k].type, big); };
        cloud.points[i] = Eigen::Vector3f(toFloat(get(ix)), toFloat(get(iy)), toFloat(get(iz)));
        if (colour) {
          cloud.colours[i] = Rgb{toColourByte(get(ir), el.props[ir].type), toColourByte(get(ig), el.props[ig].type),
                                toColourByte(get(ib), el.props[ib].type)};
        }
      }
      pos += n * record;
    }
    return cloud;
  }
  throw FormatError(name + ": PLY has no vertex element");
}

void writePly(const std::filesystem::path& path, const PointCloud& cloud) {
  std::ostringstream hdr;
  hdr << "ply\nformat binary_little_endian 1.0\ncomment written by chronomap\nelement vertex " << cloud.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
         "property uchar blue\nend_header\n";
  const std::string h = hdr.str();
  std::vector<uint8_t> out(h.begin(), h.end());
  out.reserve(out.size() + cloud.size() * 15);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto* p = reinterpret_cast<const uint8_t*>(cloud.points[i].data());
    out.insert(out.end(), p, p + 12);
    const Rgb c = cloud.hasColours() ? cloud.colours[i] : Rgb{200, 200, 200};
    out.push_back(c.r);
    out.push_back(c.g);
    out.push_back(c.b);
  }
  writeFileAtomic(path, out);
}

}  // namespace chronomap
