// Runs the peers (see peers.h). Compiled C++17, -O3 -march=native, against the unmodified
// copies in ../shared/peers.

#include "peers.h"

#include <bonxai/serialization.hpp>
#include <bonxai_map/probabilistic_map.hpp>
#include <ufo/map/occupancy_map_color.h>

#include <chrono>
#include <ctime>
#include <sstream>

namespace chronomap::bench::peers {

namespace {

double cpuNow() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// Adds the wall and CPU time of fn() to r.
template <class Fn>
void timed(PeerResult& r, Fn&& fn) {
  const double c0 = cpuNow();
  const auto t0 = std::chrono::steady_clock::now();
  fn();
  r.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpu_seconds += cpuNow() - c0;
}

}  // namespace

PeerResult runBonxai(const std::vector<PeerFrame>& frames, double resolution, double max_range) {
  PeerResult r;
  Bonxai::ProbabilisticMap map(resolution);
  std::vector<Eigen::Vector3f> points;
  for (const PeerFrame& f : frames) {
    points.clear();
    points.reserve(f.xyz.size() / 3);
    for (size_t i = 0; i + 2 < f.xyz.size(); i += 3) points.emplace_back(f.xyz[i], f.xyz[i + 1], f.xyz[i + 2]);
    const Eigen::Vector3f origin(f.origin[0], f.origin[1], f.origin[2]);
    timed(r, [&] { map.insertPointCloud(points, origin, max_range); });
  }
  r.memory_bytes = static_cast<double>(map.grid().memUsage());
  std::ostringstream out(std::ios::binary);
  Bonxai::Serialize(out, map.grid());
  r.disk_bytes = static_cast<double>(out.str().size());
  return r;
}

PeerResult runUfomap(const std::vector<PeerFrame>& frames, double resolution, double max_range, int depth) {
  PeerResult r;
  ufo::map::OccupancyMapColor map(resolution);
  ufo::map::PointCloudColor cloud;
  for (const PeerFrame& f : frames) {
    cloud.clear();
    cloud.reserve(f.xyz.size() / 3);
    for (size_t i = 0, n = f.xyz.size() / 3; i < n; ++i) {
      cloud.push_back(ufo::map::Point3Color(f.xyz[3 * i], f.xyz[3 * i + 1], f.xyz[3 * i + 2], f.rgb[3 * i],
                                            f.rgb[3 * i + 1], f.rgb[3 * i + 2]));
    }
    const ufo::map::Point3 origin(f.origin[0], f.origin[1], f.origin[2]);
    timed(r, [&] { map.insertPointCloudDiscrete(origin, cloud, max_range, static_cast<ufo::map::DepthType>(depth)); });
  }
  r.memory_bytes = static_cast<double>(map.memoryUsage());
  std::ostringstream out(std::ios::binary);
  map.write(out, true);
  r.disk_bytes = static_cast<double>(out.str().size());
  return r;
}

}  // namespace chronomap::bench::peers
