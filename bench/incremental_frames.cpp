// Frame-by-frame integration from decoded images, the C++ side of bench/python_integration.py:
// the frames of a TUM folder (depth.txt order, each with the nearest pose and colour image) are
// read and decoded first; then, timed, each depth image is turned into a cloud (depthToCloud)
// and added to an IncrementalIntegrator on one thread, and finish() compresses the map. This is
// what chronomap.Integrator.add_frame does for numpy arrays, so the Python script compares the two.
//
// Usage: incremental_frames FOLDER [--resolution M] [--fast] [--frames N] [--rounds R]
// Prints one JSON object: frames, points, best seconds over the rounds, milliseconds a frame.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "chronomap/integrate/incremental.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

struct DecodedFrame {
  ImageU16 depth;
  ImageRgb rgb;
  Eigen::Isometry3d pose;
};

template <class T>
const T& nearest(const std::vector<T>& rows, double t) {
  return *std::min_element(rows.begin(), rows.end(),
                           [t](const T& a, const T& b) { return std::abs(a.t - t) < std::abs(b.t - t); });
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: incremental_frames FOLDER [--resolution M] [--fast] [--frames N] [--rounds R]\n");
    return 2;
  }
  const fs::path folder = argv[1];
  double resolution = 0.05;
  bool fast = false;
  size_t max_frames = std::numeric_limits<size_t>::max();
  int rounds = 3;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--fast") fast = true;
    else if (a == "--resolution" && i + 1 < argc) resolution = std::stod(argv[++i]);
    else if (a == "--frames" && i + 1 < argc) max_frames = std::stoul(argv[++i]);
    else if (a == "--rounds" && i + 1 < argc) rounds = std::stoi(argv[++i]);
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  const auto depths = parseStampedList(readTextFile(folder / "depth.txt"), "depth.txt");
  const auto colours = parseStampedList(readTextFile(folder / "rgb.txt"), "rgb.txt");
  const fs::path traj = fs::exists(folder / "trajectory.txt") ? folder / "trajectory.txt" : folder / "groundtruth.txt";
  const auto poses = parseTumTrajectory(readTextFile(traj), traj.string());
  const CameraIntrinsics k = readIntrinsicsFile(folder / "camera-intrinsics.txt");
  std::vector<DecodedFrame> frames;
  for (const auto& d : depths) {
    if (frames.size() >= max_frames) break;
    frames.push_back({readPngU16(folder / d.name), readPngRgb(folder / nearest(colours, d.t).name),
                      nearest(poses, d.t).pose});
  }
  IntegratorSettings settings;
  settings.fast = fast;
  settings.threads = 1;
  double best = std::numeric_limits<double>::infinity();
  uint64_t points = 0;
  for (int r = 0; r < rounds; ++r) {
    const auto start = std::chrono::steady_clock::now();
    IncrementalIntegrator integrator(resolution, settings);
    for (const DecodedFrame& f : frames) {
      Frame frame;
      frame.T_world_sensor = f.pose;
      frame.cloud = depthToCloud(f.depth, &f.rgb, k, 5000.0, "bench");
      integrator.add(frame);
    }
    points = integrator.stats().points;
    const SessionMap map = integrator.finish();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (map.empty()) return 1;
  }
  const nlohmann::json out = {{"frames", frames.size()},
                              {"points", points},
                              {"seconds", best},
                              {"ms_per_frame", 1000.0 * best / static_cast<double>(frames.size())}};
  std::printf("%s\n", out.dump().c_str());
  return 0;
}
