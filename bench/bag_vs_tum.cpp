// Reading a bag (ROS 1, or ROS 2: MCAP, .db3 or a bag folder) against reading the same frames
// from a TUM folder: opening the recording and loading every frame (depth and colour decoded,
// back-projected into clouds), the best of several rounds, frames loaded on 1 thread and on all
// threads as the integrator loads them. The 1-thread figures are also taken as the thread's
// processor time (cpu columns), which a loaded shared machine disturbs far less than the clock.
// The bags hold the folder's frames (tests/ingest/ros/make_ros1_bags.py, make_ros2_bags.mjs); nothing
// is integrated.
//
// Usage: bag_vs_tum TUM_FOLDER BAG [BAG...] [--rounds N] [--depth-scale S] [--fixed-frame F]
// (--fixed-frame applies to the bags that have /tf.)
// The last line of output is one JSON object with the seconds and each bag's ratio to the folder.

#include <tbb/parallel_for.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/rosbag.h"

using namespace chronomap;

namespace {

struct Timing {
  double open_s = 1e30;  ///< opening: index files (TUM) or the bag's check, index and small topics
  double load_1_s = 1e30;
  double load_all_s = 1e30;
  double open_cpu_s = 1e30, load_1_cpu_s = 1e30;  ///< the calling thread's processor time
  size_t frames = 0, points = 0;
};

double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

Timing measure(const std::filesystem::path& path, const DatasetSettings& settings, int rounds) {
  Timing t;
  for (int r = 0; r < rounds; ++r) {
    auto start = std::chrono::steady_clock::now();
    double cpu = threadCpuSeconds();
    const auto dataset = openDataset(path, settings);
    t.open_s = std::min(t.open_s, seconds(start));
    t.open_cpu_s = std::min(t.open_cpu_s, threadCpuSeconds() - cpu);
    t.frames = dataset->size();
    start = std::chrono::steady_clock::now();
    cpu = threadCpuSeconds();
    size_t points = 0;
    for (size_t i = 0; i < dataset->size(); ++i) points += dataset->load(i).cloud.size();
    t.load_1_s = std::min(t.load_1_s, seconds(start));
    t.load_1_cpu_s = std::min(t.load_1_cpu_s, threadCpuSeconds() - cpu);
    t.points = points;
    start = std::chrono::steady_clock::now();
    tbb::parallel_for(size_t{0}, dataset->size(), [&](size_t i) { (void)dataset->load(i).cloud.size(); });
    t.load_all_s = std::min(t.load_all_s, seconds(start));
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> paths;
  int rounds = 5;
  DatasetSettings bag_settings;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--rounds" && i + 1 < argc) {
      rounds = std::max(1, std::stoi(argv[++i]));
    } else if (a == "--depth-scale" && i + 1 < argc) {
      bag_settings.depth_scale = std::stod(argv[++i]);
    } else if (a == "--fixed-frame" && i + 1 < argc) {
      bag_settings.bag.fixed_frame = argv[++i];
    } else {
      paths.push_back(a);
    }
  }
  if (paths.size() < 2) {
    std::fprintf(stderr,
                 "usage: bag_vs_tum TUM_FOLDER BAG [BAG...] [--rounds N] [--depth-scale S] [--fixed-frame F]\n");
    return 2;
  }
  const Timing tum = measure(paths[0], {}, rounds);
  std::printf("%-28s %6s %9s %9s %9s %7s %7s %9s %9s %7s\n", "recording", "frames", "open s", "load 1 s",
              "load N s", "ratio1", "ratioN", "open cpu", "load cpu", "ratioC");
  const auto cpuRatio = [&](const Timing& t) {
    return (t.open_cpu_s + t.load_1_cpu_s) / (tum.open_cpu_s + tum.load_1_cpu_s);
  };
  const auto line = [&](const std::string& name, const Timing& t) {
    const double total_1 = t.open_s + t.load_1_s, total_n = t.open_s + t.load_all_s;
    std::printf("%-28s %6zu %9.4f %9.4f %9.4f %7.3f %7.3f %9.4f %9.4f %7.3f\n", name.c_str(), t.frames, t.open_s,
                t.load_1_s, t.load_all_s, total_1 / (tum.open_s + tum.load_1_s), total_n / (tum.open_s + tum.load_all_s),
                t.open_cpu_s, t.load_1_cpu_s, cpuRatio(t));
  };
  line(std::filesystem::path(paths[0]).filename().string() + " (TUM)", tum);
  nlohmann::json out = {{"tum",
                         {{"open_s", tum.open_s},
                          {"load_1_s", tum.load_1_s},
                          {"load_all_s", tum.load_all_s},
                          {"open_cpu_s", tum.open_cpu_s},
                          {"load_1_cpu_s", tum.load_1_cpu_s}}},
                        {"bags", nlohmann::json::object()}};
  for (size_t b = 1; b < paths.size(); ++b) {
    // --fixed-frame for the bags with /tf; the others take their pose topic.
    DatasetSettings settings = bag_settings;
    const auto topics = listBag(paths[b]);
    if (std::none_of(topics.begin(), topics.end(), [](const BagTopic& t) { return t.name == "/tf"; })) {
      settings.bag.fixed_frame.clear();
    }
    const Timing t = measure(paths[b], settings, rounds);
    if (t.frames != tum.frames || t.points != tum.points) {
      std::fprintf(stderr, "%s: %zu frames, %zu points; the folder has %zu, %zu\n", paths[b].c_str(), t.frames,
                   t.points, tum.frames, tum.points);
      return 1;
    }
    const std::string name = std::filesystem::path(paths[b]).lexically_normal().filename().string().empty()
                                 ? std::filesystem::path(paths[b]).parent_path().filename().string()
                                 : std::filesystem::path(paths[b]).filename().string();
    line(name, t);
    out["bags"][name] = {{"open_s", t.open_s},
                         {"load_1_s", t.load_1_s},
                         {"load_all_s", t.load_all_s},
                         {"open_cpu_s", t.open_cpu_s},
                         {"load_1_cpu_s", t.load_1_cpu_s},
                         {"ratio_1_thread_cpu", cpuRatio(t)},
                         {"ratio_1_thread", (t.open_s + t.load_1_s) / (tum.open_s + tum.load_1_s)},
                         {"ratio_all_threads", (t.open_s + t.load_all_s) / (tum.open_s + tum.load_all_s)}};
  }
  std::printf("%s\n", out.dump().c_str());
  return 0;
}
