#pragma once
// The peers of bench/integrate_vs_peers, behind a plain interface: Bonxai's ProbabilisticMap and
// UFOMap's OccupancyMapColor. peers.cpp, the only file that includes their headers, is compiled
// as they are meant to be built (C++17, -O3 -march=native) from the unmodified copies in
// ../shared/peers; chronomap never links them.

#include <cstdint>
#include <vector>

namespace chronomap::bench::peers {

/// One frame in the map frame: points already limited to the maximum range.
struct PeerFrame {
  std::vector<float> xyz;     // x, y, z per point
  std::vector<uint8_t> rgb;   // r, g, b per point
  float origin[3] = {0, 0, 0};  // the sensor's position
};

struct PeerResult {
  double seconds = 0;      // wall time of the insertion calls only (conversion to the peer's types excluded)
  double cpu_seconds = 0;  // the process's CPU time over the same calls
  double memory_bytes = 0;  // as the peer reports it
  double disk_bytes = 0;    // the map written in the peer's own format
};

/// Bonxai ProbabilisticMap::insertPointCloud per frame; disk: Bonxai::Serialize of its grid.
PeerResult runBonxai(const std::vector<PeerFrame>& frames, double resolution, double max_range);
/// UFOMap OccupancyMapColor::insertPointCloudDiscrete per frame with free space carved `depth`
/// levels coarser; disk: its LZ4-compressed write.
PeerResult runUfomap(const std::vector<PeerFrame>& frames, double resolution, double max_range, int depth);

}  // namespace chronomap::bench::peers
