// Integration speed, memory and file size: chronomap against OctoMap, Bonxai and UFOMap on the
// same frames, in the same run. Inputs are those of integrate_vs_octomap: a synthetic 640x480
// sequence of 30 frames (benchmarkSequence) and the five real 3DMatch frames, limited to
// 3 m; frames are decoded before timing and every peer gets the same points in the map frame,
// converted to its own point type before its clock starts.
//
//   chronomap        exact and fast mode, with and without hit positions, 1 and 2 threads; fast
//                    mode with its default carve level (auto: 2 at 0.02 m, 0 at 0.05 m) and with
//                    coarse carving off (level 0) and at level 2 by hand
//   OctoMap          ColorOcTree::insertPointCloud, plain and discretized (Debian's liboctomap)
//   Bonxai           ProbabilisticMap::insertPointCloud
//   UFOMap           OccupancyMapColor::insertPointCloudDiscrete, depth 0 and depth 2 (free
//                    space carved two levels coarser, its fastest)
//
// Bonxai and UFOMap are the unmodified copies in ../shared/peers, compiled C++17 -O3
// -march=native in peers.cpp; chronomap's libraries have the project's Release flags (-O3,
// no -march; its fast mode picks AVX2 code at run time where the CPU has it). Memory is what
// each map reports of itself; disk is the map written in its own format: chronomap .cmap,
// OctoMap .bt (and .ot), Bonxai's Serialize, UFOMap's LZ4-compressed write.
//
// Times: wall and the process's CPU time. On a shared machine the CPU time of a single-threaded
// run is the steadier measure (time slices lost to other processes do not count), so rows with
// one thread (every peer's) keep their best CPU time over the rounds and are compared by it;
// the two-thread rows keep their best wall time. On an idle machine the two agree. UFOMap
// inserts a cloud's hits on a second thread of its own while its caller carves free space, so its
// CPU time exceeds its wall time; a second comparison therefore sets chronomap's fast mode on two
// threads (the command line's default: all cores) against every row's wall time: the time a
// user waits for, each program using the cores as it does by default.
//
// Usage: integrate_vs_peers [--quick] [--rounds N] [--data DIR] [--fast-only] [--only K] [--res R]
//                           [--3dmatch-only]
//   --quick: 8 synthetic frames, one round. The last line is one JSON object (issue 27's keys).
//   --fast-only: chronomap's fast-mode rows on the synthetic frames only (no peers, no ratios),
//   for comparing builds of chronomap.
//   --only K: row K of the Row enumeration alone (for profiling); --res R: resolution R alone;
//   --3dmatch-only: the 3DMatch frames alone.

#include <octomap/ColorOcTree.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "chronomap/integrate/integrator.h"
#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/sim/box_room.h"
#include "peers.h"

using namespace chronomap;
namespace peers = chronomap::bench::peers;

namespace {

constexpr double kMaxRange = 3.0;

struct Input {
  std::string name;
  std::vector<Frame> frames;
  std::vector<octomap::Pointcloud> world;  // per frame, in the map frame, within kMaxRange
  std::vector<octomap::point3d> origins;
  std::vector<peers::PeerFrame> peer;  // the same points with colours
  uint64_t points = 0;
};

Input prepare(std::string name, std::vector<Frame> frames) {
  Input in;
  in.name = std::move(name);
  for (auto& f : frames) {
    octomap::Pointcloud pc;
    peers::PeerFrame pf;
    const Eigen::Vector3d o = f.T_world_sensor.translation();
    PointCloud kept;
    for (size_t i = 0; i < f.cloud.size(); ++i) {
      const Eigen::Vector3f& p = f.cloud.points[i];
      if (!p.allFinite() || p.norm() > kMaxRange || p.norm() == 0.0f) continue;
      const Eigen::Vector3d w = f.T_world_sensor * p.cast<double>();
      const float x = static_cast<float>(w.x()), y = static_cast<float>(w.y()), z = static_cast<float>(w.z());
      pc.push_back(x, y, z);
      pf.xyz.insert(pf.xyz.end(), {x, y, z});
      kept.points.push_back(p);
      if (f.cloud.hasColours()) {
        kept.colours.push_back(f.cloud.colours[i]);
        const Rgb& c = f.cloud.colours[i];
        pf.rgb.insert(pf.rgb.end(), {c.r, c.g, c.b});
      } else {
        pf.rgb.insert(pf.rgb.end(), 3, 128);
      }
    }
    kept.width = static_cast<uint32_t>(kept.points.size());
    in.points += kept.points.size();
    f.cloud = std::move(kept);
    in.world.push_back(std::move(pc));
    in.origins.emplace_back(static_cast<float>(o.x()), static_cast<float>(o.y()), static_cast<float>(o.z()));
    for (int c = 0; c < 3; ++c) pf.origin[c] = static_cast<float>(o[c]);
    in.peer.push_back(std::move(pf));
  }
  in.frames = std::move(frames);
  return in;
}

double cpuNow() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

struct Result {
  std::string method;
  int threads = 1;
  double seconds = 0;      // wall
  double cpu_seconds = 0;  // the process's CPU time
  /// The time rows are compared by: CPU time for one thread, wall time for two.
  double time() const { return threads == 1 ? cpu_seconds : seconds; }
  double memory = 0;  // bytes, as the map reports them
  double disk = 0;    // bytes of the map in its own format
  std::string disk_note;
};

Result runChronomap(const Input& in, double res, bool fast, int threads, bool positions,
                    int carve_level = kCarveAuto) {
  IntegratorSettings s;
  s.carve_level = carve_level;
  s.max_range_m = kMaxRange;
  s.fast = fast;
  s.threads = threads;
  s.hit_positions = positions;
  const FrameVector frames(in.frames);
  Result r;
  r.method = std::string("chronomap ") + (fast ? "fast" : "exact") + ", " + std::to_string(threads) + " thread" +
             (threads > 1 ? "s" : "") + (positions ? "" : ", no positions") +
             (carve_level != kCarveAuto                ? ", carve level " + std::to_string(carve_level)
              : carveLevelFor(s, res) > 0 ? " (carve level auto: " + std::to_string(carveLevelFor(s, res)) + ")"
                                          : "");
  r.threads = threads;
  SessionMap map(res);
  const double c0 = cpuNow();
  const auto t0 = std::chrono::steady_clock::now();
  integrate(frames, map, s);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpu_seconds = cpuNow() - c0;
  r.memory = static_cast<double>(map.memoryBytes());
  r.disk = static_cast<double>(encodeSessionMap(map, nlohmann::json::object()).size());
  r.disk_note = ".cmap";
  return r;
}

Result runOctomap(const Input& in, double res, bool discretize) {
  Result r;
  r.method = std::string("OctoMap ColorOcTree ") + (discretize ? "discretized" : "plain");
  octomap::ColorOcTree tree(res);
  const double c0 = cpuNow();
  const auto t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < in.world.size(); ++i) {
    tree.insertPointCloud(in.world[i], in.origins[i], kMaxRange, false, discretize);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpu_seconds = cpuNow() - c0;
  r.memory = static_cast<double>(tree.memoryUsage());
  std::ostringstream ot(std::ios::binary), bt(std::ios::binary);
  tree.write(ot);        // .ot: full log-odds and colour
  tree.writeBinary(bt);  // .bt: two bits a node (turns the tree into maximum likelihood: last)
  r.disk = static_cast<double>(bt.str().size());
  char note[64];
  std::snprintf(note, sizeof note, ".bt (.ot %.2f MiB)", static_cast<double>(ot.str().size()) / 1048576.0);
  r.disk_note = note;
  return r;
}

Result fromPeer(std::string method, const peers::PeerResult& p, std::string note) {
  Result r;
  r.method = std::move(method);
  r.seconds = p.seconds;
  r.cpu_seconds = p.cpu_seconds;
  r.memory = p.memory_bytes;
  r.disk = p.disk_bytes;
  r.disk_note = std::move(note);
  return r;
}

// Row indices of measure()'s results.
enum Row : size_t {
  kOctoPlain, kOctoDisc, kExact1, kExact2, kExact1Bare, kExact2Bare, kFast1, kFast2, kFast1Bare, kFast2Bare,
  kBonxai, kUfo0, kUfo2, kFast1Carve0, kFast2Carve0, kFast1Carve2, kRows
};

/// Runs every method once per round and keeps each one's best time, so that slow drifts of the
/// machine's speed hit all methods alike (see time()). Runs longer than 10 s are not repeated.
std::vector<Result> measure(const Input& in, double res, int rounds, bool fast_only, int only) {
  std::vector<std::function<Result()>> methods(kRows);
  methods[kOctoPlain] = [&] { return runOctomap(in, res, false); };
  methods[kOctoDisc] = [&] { return runOctomap(in, res, true); };
  methods[kExact1] = [&] { return runChronomap(in, res, false, 1, true); };
  methods[kExact2] = [&] { return runChronomap(in, res, false, 2, true); };
  methods[kExact1Bare] = [&] { return runChronomap(in, res, false, 1, false); };
  methods[kExact2Bare] = [&] { return runChronomap(in, res, false, 2, false); };
  methods[kFast1] = [&] { return runChronomap(in, res, true, 1, true); };
  methods[kFast2] = [&] { return runChronomap(in, res, true, 2, true); };
  methods[kFast1Bare] = [&] { return runChronomap(in, res, true, 1, false); };
  methods[kFast2Bare] = [&] { return runChronomap(in, res, true, 2, false); };
  methods[kFast1Carve0] = [&] { return runChronomap(in, res, true, 1, true, 0); };
  methods[kFast2Carve0] = [&] { return runChronomap(in, res, true, 2, true, 0); };
  methods[kFast1Carve2] = [&] { return runChronomap(in, res, true, 1, true, 2); };
  methods[kBonxai] = [&] {
    return fromPeer("Bonxai ProbabilisticMap", peers::runBonxai(in.peer, res, kMaxRange), "Serialize");
  };
  methods[kUfo0] = [&] {
    return fromPeer("UFOMap OccupancyMapColor, depth 0", peers::runUfomap(in.peer, res, kMaxRange, 0), "LZ4 write");
  };
  methods[kUfo2] = [&] {
    return fromPeer("UFOMap OccupancyMapColor, depth 2", peers::runUfomap(in.peer, res, kMaxRange, 2), "LZ4 write");
  };
  std::vector<Result> best(kRows);
  for (int round = 0; round < rounds; ++round) {
    for (size_t m = 0; m < kRows; ++m) {
      if (round > 0 && best[m].seconds > 10.0) continue;
      const bool fast_row = m == kFast1 || m == kFast2 || m == kFast1Bare || m == kFast2Bare || m >= kFast1Carve0;
      if (only >= 0 ? m != static_cast<size_t>(only) : fast_only && !fast_row) continue;
      const Result r = methods[m]();
      if (round == 0 || r.time() < best[m].time()) best[m] = r;
    }
    std::fprintf(stderr, "  round %d/%d done\n", round + 1, rounds);
  }
  return best;
}

double mib(double bytes) { return bytes / 1048576.0; }

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, fast_only = false;
  int only = -1;  // --only K: row K alone (for profiling)
  double only_res = 0;  // --res R: that resolution alone
  bool real_only = false;  // --3dmatch-only
  int rounds = 5;
  std::filesystem::path data = CHRONOMAP_DEFAULT_DATA_DIR;
  if (const char* env = std::getenv("CHRONOMAP_DATA_DIR")) data = env;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
      rounds = 1;
    } else if (!std::strcmp(argv[i], "--rounds") && i + 1 < argc) {
      rounds = std::max(1, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--data") && i + 1 < argc) {
      data = argv[++i];
    } else if (!std::strcmp(argv[i], "--res") && i + 1 < argc) {
      only_res = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--3dmatch-only")) {
      real_only = true;
    } else if (!std::strcmp(argv[i], "--only") && i + 1 < argc) {
      only = std::atoi(argv[++i]);
      fast_only = true;
    } else if (!std::strcmp(argv[i], "--fast-only")) {
      fast_only = true;
    } else {
      std::fprintf(stderr,
                   "usage: integrate_vs_peers [--quick] [--rounds N] [--data DIR] [--fast-only] [--only K] [--res R] "
                   "[--3dmatch-only]\n");
      return 2;
    }
  }
  std::printf("machine: %u hardware threads; max range %.1f m; times exclude file decoding\n",
              std::thread::hardware_concurrency(), kMaxRange);
  std::printf("flags: Bonxai and UFOMap C++17 -O3 -march=native; chronomap and OctoMap as built (chronomap "
              "Release -O3 without -march, AVX2 picked at run time; OctoMap Debian's package)\n");

  std::vector<Input> inputs;
  const size_t synthetic_frames = quick ? 8 : 30;
  if (!real_only) {
    inputs.push_back(prepare("synthetic 640x480 x " + std::to_string(synthetic_frames),
                             benchmarkSequence(synthetic_frames)));
  }
  try {
    if (fast_only && only < 0) throw std::runtime_error("--fast-only");
    auto ds = openDataset(data / "3dmatch" / "3dmatch");
    std::vector<Frame> frames;
    for (size_t i = 0; i < ds->size(); ++i) frames.push_back(ds->load(i));
    inputs.push_back(prepare("3dmatch study room x 5", std::move(frames)));
  } catch (const std::exception& e) {
    std::printf("skipping 3dmatch frames: %s\n", e.what());
  }

  nlohmann::json summary = {
      {"timing", "CPU time of single-threaded runs, best of rounds; fast2_wall_*: fast mode on two threads against "
                 "each row's wall time"},
      {"rounds", rounds}};
  for (const Input& in : inputs) {
    const bool synthetic = in.name.rfind("synthetic", 0) == 0;
    for (double res : {0.05, 0.02}) {
      if (only_res > 0 && std::abs(res - only_res) > 1e-9) continue;
      const double nframes = static_cast<double>(in.frames.size());
      std::printf("\n== %s at %.2f m: %.0f points per frame (best of %d rounds) ==\n", in.name.c_str(), res,
                  static_cast<double>(in.points) / nframes, rounds);
      std::fflush(stdout);
      const std::vector<Result> results = measure(in, res, rounds, fast_only, only);
      const Result& fast = results[kFast1];
      if (fast_only) {
        for (const Result& r : results) {
          if (r.method.empty()) continue;  // not run
          std::printf("| %s | %.2f ms wall | %.2f CPU ms/frame | %.2f MiB | %.2f MiB .cmap |\n", r.method.c_str(),
                      1e3 * r.seconds / nframes, 1e3 * r.cpu_seconds / nframes, mib(r.memory), mib(r.disk));
        }
        summary["fast_ms_per_frame_" + std::string(res == 0.05 ? "5cm" : "2cm")] = 1e3 * fast.time() / nframes;
        summary["fast_carve0_ms_per_frame_" + std::string(res == 0.05 ? "5cm" : "2cm")] =
            1e3 * results[kFast1Carve0].time() / nframes;
        summary["fast2_wall_ms_per_frame_" + std::string(res == 0.05 ? "5cm" : "2cm")] =
            1e3 * results[kFast2].seconds / nframes;
        continue;
      }
      const Result& fast2 = results[kFast2];
      std::printf("| %s | %s | %s | %s | %s | %s | %s | %s |\n|---|---:|---:|---:|---:|---:|---:|---:|\n", "method",
                  "ms/frame (wall)", "CPU ms/frame", "M points/s", "memory MiB", "disk MiB (format)",
                  "chronomap fast, 1 thread, vs this", "fast, 2 threads, wall vs wall");
      for (const Result& r : results) {
        std::printf("| %s | %.2f | %.2f | %.2f | %.2f | %.2f (%s) | %.2fx | %.2fx |\n", r.method.c_str(),
                    1e3 * r.seconds / nframes, 1e3 * r.cpu_seconds / nframes,
                    static_cast<double>(in.points) / r.time() / 1e6, mib(r.memory), mib(r.disk), r.disk_note.c_str(),
                    r.time() / fast.time(), r.seconds / fast2.seconds);
      }
      double best_peer_memory = results[kBonxai].memory;
      for (size_t k : {kOctoPlain, kOctoDisc, kUfo0, kUfo2}) best_peer_memory = std::min(best_peer_memory, results[k].memory);
      double slowest_ratio = 1e30, slowest_wall_ratio = 1e30;  // fast vs the fastest peer
      for (size_t k : {kOctoPlain, kOctoDisc, kBonxai, kUfo0, kUfo2}) {
        slowest_ratio = std::min(slowest_ratio, results[k].time() / fast.time());
        slowest_wall_ratio = std::min(slowest_wall_ratio, results[k].seconds / fast2.seconds);
      }
      std::printf("fast (positions) vs the fastest peer: %.2fx on one thread (CPU time), %.2fx on two (wall time); "
                  "memory vs the smallest peer: %.2f; .cmap vs UFOMap depth 0 file: %.2f\n",
                  slowest_ratio, slowest_wall_ratio, fast.memory / best_peer_memory, fast.disk / results[kUfo0].disk);
      const std::string cm = res == 0.05 ? "5cm" : "2cm";
      const std::string key = (synthetic ? "" : "3dmatch_") + cm;
      summary["fast_vs_bonxai_" + key] = results[kBonxai].time() / fast.time();
      summary["fast_vs_ufomap_" + key] = results[kUfo0].time() / fast.time();
      summary["fast_vs_ufomap_d2_" + key] = results[kUfo2].time() / fast.time();
      summary["fast_vs_every_peer_" + key] = slowest_ratio;
      summary["disk_vs_ufomap_" + key] = fast.disk / results[kUfo0].disk;
      summary["disk_vs_ufomap_d2_" + key] = fast.disk / results[kUfo2].disk;
      summary["memory_vs_best_peer_" + key] = fast.memory / best_peer_memory;
      summary["fast_vs_octomap_discretized_" + key] = results[kOctoDisc].time() / fast.time();
      summary["fast_ms_per_frame_" + key] = 1e3 * fast.time() / nframes;
      // Both cores, wall time against wall time (see the head of this file).
      summary["fast2_wall_vs_bonxai_" + key] = results[kBonxai].seconds / fast2.seconds;
      summary["fast2_wall_vs_ufomap_" + key] = results[kUfo0].seconds / fast2.seconds;
      summary["fast2_wall_vs_ufomap_d2_" + key] = results[kUfo2].seconds / fast2.seconds;
      summary["fast2_wall_vs_octomap_discretized_" + key] = results[kOctoDisc].seconds / fast2.seconds;
      summary["fast2_wall_vs_every_peer_" + key] = slowest_wall_ratio;
      summary["fast2_wall_ms_per_frame_" + key] = 1e3 * fast2.seconds / nframes;
      // Two threads against one, both wall time, the map the same bytes (issue 46: >= 1.7x on the
      // five 3DMatch frames; the plain key is the lower of the two resolutions run).
      const double two_vs_one = fast.seconds / fast2.seconds;
      summary["fast2_vs_fast1_" + key] = two_vs_one;
      if (!synthetic) {
        const char* five = "fast2_vs_fast1_5frames";
        summary[five] = summary.contains(five) ? std::min(summary[five].get<double>(), two_vs_one) : two_vs_one;
      }
      std::printf("fast mode on two threads against one (wall time): %.2fx\n", two_vs_one);
      // Coarse carving off (carve level 0, docs/integration.md) against the peers.
      const Result& flat = results[kFast1Carve0];
      summary["fast_carve0_vs_bonxai_" + key] = results[kBonxai].time() / flat.time();
      summary["fast_carve0_vs_ufomap_d2_" + key] = results[kUfo2].time() / flat.time();
      summary["fast_carve0_ms_per_frame_" + key] = 1e3 * flat.time() / nframes;
      summary["disk_carve0_vs_ufomap_" + key] = flat.disk / results[kUfo0].disk;
      if (synthetic && res == 0.05) {
        summary["fast_vs_octomap_discretized"] = results[kOctoDisc].time() / fast.time();
        summary["memory_vs_best_peer"] = fast.memory / best_peer_memory;
        summary["fast_no_positions_vs_bonxai_5cm"] = results[kBonxai].time() / results[kFast1Bare].time();
      }
      std::fflush(stdout);
    }
  }
  std::printf("\nnotes: \"vs this\" > 1 means chronomap's fast mode (1 thread, hit positions on, carve level auto) "
              "took less time (CPU time against one-thread rows, wall time against two-thread rows); \"wall vs wall\" "
              "is fast mode on two threads against the row's wall time (UFOMap inserts hits on a second thread). "
              "OctoMap and Bonxai integrate no colour; UFOMap and chronomap do. chronomap's times include the final "
              "free-space compression and, except in the rows marked \"no positions\", where in each voxel the rays "
              "ended.\n");
  std::printf("%s\n", summary.dump().c_str());
  return 0;
}
