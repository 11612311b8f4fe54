#include "chronomap/export/map_server.h"

#include <cstdio>
#include <string>
#include <vector>

#include "chronomap/core/file.h"

namespace chronomap {

namespace {

/// The grey level of a cost in map_server's `raw` mode: the cost itself, 255 for unknown.
uint8_t rawGrey(int8_t cost) { return cost < 0 ? uint8_t{255} : static_cast<uint8_t>(cost); }

}  // namespace

// Raw mode is the one in which ROS map_server (ROS 1 image_loader) and nav2_map_server (map_io)
// both load chronomap's costs as they are: each hands a grey pixel's value to the grid unchanged
// (ROS 1 as a signed byte, so 255 reads -1; nav2 keeps 0..100 and reads anything above as
// unknown). `scale` cannot: a PGM has no alpha, the only unknown there (so 205 loaded as free or
// cost 1), and its loaders round differently (99 r, 1 + 98 r, rint(100 r)), so no grey level
// gives every cost exactly in all three. Both loaders require the thresholds, unused in raw mode.
std::filesystem::path writeMapServer(const std::filesystem::path& yaml_path, const Costmap& m) {
  std::filesystem::path pgm = yaml_path;
  pgm.replace_extension(".pgm");
  std::string header("P5\n");
  header.append(std::to_string(m.width)).append(" ").append(std::to_string(m.height)).append("\n255\n");
  std::vector<uint8_t> bytes(header.begin(), header.end());
  bytes.reserve(bytes.size() + m.cost.size());
  for (int j = m.height - 1; j >= 0; --j) {  // the image's first row is the map's highest y
    for (int i = 0; i < m.width; ++i) {
      bytes.push_back(rawGrey(m.at(i, j)));
    }
  }
  char yaml[512];
  std::snprintf(yaml, sizeof yaml,
                "image: %s\nresolution: %.6f\norigin: [%.6f, %.6f, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
                "free_thresh: 0.196\nmode: raw\n",
                pgm.filename().string().c_str(), m.resolution_m, m.origin_m.x(), m.origin_m.y());
  writeFileAtomic(pgm, bytes);
  const std::string text(yaml);
  writeFileAtomic(yaml_path, std::vector<uint8_t>(text.begin(), text.end()));
  return pgm;
}

}  // namespace chronomap
