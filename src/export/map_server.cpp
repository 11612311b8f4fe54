#include "chronomap/export/map_server.h"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "chronomap/core/file.h"

namespace chronomap {

std::filesystem::path writeMapServer(const std::filesystem::path& yaml_path, const Costmap& m) {
  std::filesystem::path pgm = yaml_path;
  pgm.replace_extension(".pgm");
  std::string header("P5\n");
  header.append(std::to_string(m.width)).append(" ").append(std::to_string(m.height)).append("\n255\n");
  std::vector<uint8_t> bytes(header.begin(), header.end());
  bytes.reserve(bytes.size() + m.cost.size());
  for (int j = m.height - 1; j >= 0; --j) {  // the image's first row is the map's highest y
    for (int i = 0; i < m.width; ++i) {
      const int8_t c = m.at(i, j);
      bytes.push_back(c < 0 ? uint8_t{205} : static_cast<uint8_t>(254 - std::lround(c * 254.0 / 100.0)));
    }
  }
  char yaml[512];
  std::snprintf(yaml, sizeof yaml,
                "image: %s\nresolution: %.6f\norigin: [%.6f, %.6f, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
                "free_thresh: 0.196\nmode: scale\n",
                pgm.filename().string().c_str(), m.resolution_m, m.origin_m.x(), m.origin_m.y());
  writeFileAtomic(pgm, bytes);
  const std::string text(yaml);
  writeFileAtomic(yaml_path, std::vector<uint8_t>(text.begin(), text.end()));
  return pgm;
}

}  // namespace chronomap
