// XYZ text clouds: "x y z" or "x y z r g b" per line (also OctoMap's scan .dat point lists).

#include <algorithm>
#include <cmath>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/cloud_io.h"
#include "text_util.h"

namespace chronomap {

PointCloud readXyz(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return parseXyz(readTextFile(path), path.string()); });
}

PointCloud parseXyz(const std::string& text, const std::string& name) {
  PointCloud cloud;
  for (const auto& [number, line] : contentLines(text)) {
    const auto tok = splitWhitespace(line);
    const std::string ctx = name + ":" + std::to_string(number);
    if (tok.size() != 3 && tok.size() != 6) {
      throw FormatError(ctx + ": expected 'x y z' or 'x y z r g b', found " + std::to_string(tok.size()) + " values");
    }
    cloud.points.emplace_back(toFloat(parseDouble(tok[0], ctx)), toFloat(parseDouble(tok[1], ctx)),
                              toFloat(parseDouble(tok[2], ctx)));
    if (tok.size() == 6) {
      if (cloud.colours.size() + 1 != cloud.points.size()) throw FormatError(ctx + ": some lines have colour, some not");
      auto byte = [&](const std::string& t) {
        const double v = parseDouble(t, ctx);
        return static_cast<uint8_t>(v > 0.0 ? std::lround(std::min(v, 255.0)) : 0);
      };
      cloud.colours.push_back(Rgb{byte(tok[3]), byte(tok[4]), byte(tok[5])});
    } else if (!cloud.colours.empty()) {
      throw FormatError(ctx + ": some lines have colour, some not");
    }
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  return cloud;
}

}  // namespace chronomap
