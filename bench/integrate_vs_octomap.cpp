// Integration speed and memory: chronomap (exact and fast mode, 1 and 2 threads) against
// OctoMap's ColorOcTree::insertPointCloud (plain and discretized), on the same frames, in the
// same run. Inputs are fixed: the five real 3DMatch frames and a synthetic 640x480 sequence of
// 30 frames (benchmarkSequence). Frames are decoded before timing; OctoMap gets the same
// points in the map frame, already limited to the same maximum range.
//
// Usage: integrate_vs_octomap [--quick] [--data DIR]   (--quick: 8 synthetic frames, one round)
// The last line of output is one JSON object with the factors at 0.05 m on the synthetic sequence.

#include <octomap/ColorOcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "chronomap/integrate/integrator.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/sim/box_room.h"

using namespace chronomap;

namespace {

constexpr double kMaxRange = 3.0;

struct Input {
  std::string name;
  std::vector<Frame> frames;
  std::vector<octomap::Pointcloud> world;  // per frame, in the map frame, within kMaxRange
  std::vector<octomap::point3d> origins;
  uint64_t points = 0;
};

Input prepare(std::string name, std::vector<Frame> frames) {
  Input in;
  in.name = std::move(name);
  for (auto& f : frames) {
    octomap::Pointcloud pc;
    const Eigen::Vector3d o = f.T_world_sensor.translation();
    PointCloud kept;
    for (size_t i = 0; i < f.cloud.size(); ++i) {
      const Eigen::Vector3f& p = f.cloud.points[i];
      if (!p.allFinite() || p.norm() > kMaxRange || p.norm() == 0.0f) continue;
      const Eigen::Vector3d w = f.T_world_sensor * p.cast<double>();
      pc.push_back(static_cast<float>(w.x()), static_cast<float>(w.y()), static_cast<float>(w.z()));
      kept.points.push_back(p);
      if (f.cloud.hasColours()) kept.colours.push_back(f.cloud.colours[i]);
    }
    kept.width = static_cast<uint32_t>(kept.points.size());
    in.points += kept.points.size();
    f.cloud = std::move(kept);
    in.world.push_back(std::move(pc));
    in.origins.emplace_back(static_cast<float>(o.x()), static_cast<float>(o.y()), static_cast<float>(o.z()));
  }
  in.frames = std::move(frames);
  return in;
}

double seconds(const std::function<void()>& fn) {
  const auto t0 = std::chrono::steady_clock::now();
  fn();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct Result {
  std::string method;
  double seconds = 0;
  double bytes = 0;
};

/// One timed run of chronomap; bytes are those of the compressed map.
Result runChronomap(const Input& in, double res, bool fast, int threads, bool positions = true) {
  IntegratorSettings s;
  s.max_range_m = kMaxRange;
  s.fast = fast;
  s.threads = threads;
  s.hit_positions = positions;
  const FrameVector frames(in.frames);
  Result r;
  r.method = std::string("chronomap ") + (fast ? "fast" : "exact") + ", " + std::to_string(threads) + " thread" +
             (threads > 1 ? "s" : "") + (positions ? "" : ", no positions");
  SessionMap map(res);
  r.seconds = seconds([&] { integrate(frames, map, s); });
  r.bytes = static_cast<double>(map.memoryBytes());
  return r;
}

/// One timed run of OctoMap; bytes as OctoMap reports them (memoryUsage()).
Result runOctomap(const Input& in, double res, bool discretize) {
  Result r;
  r.method = std::string("OctoMap ColorOcTree ") + (discretize ? "discretized" : "plain");
  octomap::ColorOcTree tree(res);
  r.seconds = seconds([&] {
    for (size_t i = 0; i < in.world.size(); ++i) {
      tree.insertPointCloud(in.world[i], in.origins[i], kMaxRange, false, discretize);
    }
  });
  r.bytes = static_cast<double>(tree.memoryUsage());
  return r;
}

/// Runs every method once per round and keeps each one's best time, so that slow drifts of the
/// machine's speed hit all methods alike. Runs longer than 10 s are not repeated.
std::vector<Result> measure(const Input& in, double res, int rounds) {
  std::vector<std::function<Result()>> methods = {
      [&] { return runOctomap(in, res, false); },        [&] { return runOctomap(in, res, true); },
      [&] { return runChronomap(in, res, false, 1); },   [&] { return runChronomap(in, res, false, 2); },
      [&] { return runChronomap(in, res, true, 1); },    [&] { return runChronomap(in, res, true, 2); },
      [&] { return runChronomap(in, res, true, 1, false); }};
  std::vector<Result> best(methods.size());
  for (int round = 0; round < rounds; ++round) {
    for (size_t m = 0; m < methods.size(); ++m) {
      if (round > 0 && best[m].seconds > 10.0) continue;
      const Result r = methods[m]();
      if (round == 0 || r.seconds < best[m].seconds) best[m] = r;
    }
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::filesystem::path data = CHRONOMAP_DEFAULT_DATA_DIR;
  if (const char* env = std::getenv("CHRONOMAP_DATA_DIR")) data = env;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--data") && i + 1 < argc) data = argv[++i];
    else {
      std::fprintf(stderr, "usage: integrate_vs_octomap [--quick] [--data DIR]\n");
      return 2;
    }
  }
  std::printf("machine: %u hardware threads; max range %.1f m; times exclude file decoding\n",
              std::thread::hardware_concurrency(), kMaxRange);

  std::vector<Input> inputs;
  const size_t synthetic_frames = quick ? 8 : 30;
  inputs.push_back(prepare("synthetic 640x480 x " + std::to_string(synthetic_frames),
                           benchmarkSequence(synthetic_frames)));
  try {
    auto ds = openDataset(data / "3dmatch" / "3dmatch");
    std::vector<Frame> frames;
    for (size_t i = 0; i < ds->size(); ++i) frames.push_back(ds->load(i));
    inputs.push_back(prepare("3dmatch study room x 5", std::move(frames)));
  } catch (const std::exception& e) {
    std::printf("skipping 3dmatch frames: %s\n", e.what());
  }

  nlohmann::json summary;
  for (const Input& in : inputs) {
    for (double res : {0.05, 0.02}) {
      const double nframes = static_cast<double>(in.frames.size());
      std::printf("\n== %s at %.2f m: %.0f points per frame (best of %d rounds) ==\n", in.name.c_str(), res,
                  static_cast<double>(in.points) / nframes, quick ? 1 : 5);
      const std::vector<Result> results = measure(in, res, quick ? 1 : 5);
      const Result& plain = results[0];
      const Result& disc = results[1];
      std::printf("%-34s %10s %10s %11s %9s %9s %8s\n", "method", "ms/frame", "Mpts/s", "memory MiB", "vs plain",
                  "vs discr.", "mem vs");
      for (const Result& r : results) {
        std::printf("%-34s %10.2f %10.2f %11.2f %8.1fx %8.1fx %8.2f\n", r.method.c_str(), 1e3 * r.seconds / nframes,
                    static_cast<double>(in.points) / r.seconds / 1e6, r.bytes / 1048576.0, plain.seconds / r.seconds,
                    disc.seconds / r.seconds, r.bytes / plain.bytes);
      }
      if (in.name.rfind("synthetic", 0) == 0 && res == 0.05) {
        const Result& exact1 = results[2];
        const Result& exact2 = results[3];
        const Result& fast1 = results[4];
        const Result& fast2 = results[5];
        const Result& fast_bare = results[6];
        summary = {{"fast_no_positions_vs_octomap_discretized", disc.seconds / fast_bare.seconds},
                   {"fast_no_positions_ms_per_frame", 1e3 * fast_bare.seconds / nframes},
                   {"fast_vs_octomap_plain", plain.seconds / fast1.seconds},
                   {"fast_vs_octomap_discretized", disc.seconds / fast1.seconds},
                   {"exact_vs_octomap_plain", plain.seconds / exact1.seconds},
                   {"memory_vs_octomap", exact1.bytes / plain.bytes},
                   {"exact_two_threads_speedup", exact1.seconds / exact2.seconds},
                   {"fast_two_threads_speedup", fast1.seconds / fast2.seconds},
                   {"octomap_plain_ms_per_frame", 1e3 * plain.seconds / nframes},
                   {"fast_ms_per_frame", 1e3 * fast1.seconds / nframes}};
      }
    }
  }
  std::printf("\nnote: OctoMap's insertPointCloud integrates no colour or hit positions; chronomap's times include\n"
              "colour sums and, except in the rows marked \"no positions\", where in each voxel the rays ended.\n");
  std::printf("%s\n", summary.dump().c_str());
  return 0;
}
