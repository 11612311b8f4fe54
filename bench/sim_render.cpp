// The simulator's speed: seconds per session of `chronomap simulate` (rendering, PNG writing,
// truth voxels) and the renderer alone in frames per second, on the office, floor66 and weeks
// presets, with one and two threads.
//
// For each preset: simulate() writes --sessions sessions into a temporary folder with 1 and
// then 2 threads (s/session = wall time / sessions); then the frames of its first session
// (the poses of groundtruth.txt) are rendered again on one thread from the preset's first
// scene state, without writing anything (frames/s, rays/s).
//
// Usage: sim_render [--sessions N] [--scale S] [--presets office,floor66,weeks]
// The last line of output is one JSON object.

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <sys/resource.h>
#include <vector>

#include "chronomap/ingest/dataset.h"
#include "chronomap/core/file.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/render.h"
#include "chronomap/sim/scene.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Processor seconds (user and system) used by this process so far.
double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace

int main(int argc, char** argv) {
  int sessions = 2;
  double scale = 0.5;
  std::string presets = "office,floor66,weeks";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sessions" && i + 1 < argc) {
      sessions = std::atoi(argv[++i]);
    } else if (a == "--scale" && i + 1 < argc) {
      scale = std::atof(argv[++i]);
    } else if (a == "--presets" && i + 1 < argc) {
      presets = argv[++i];
    } else {
      std::fprintf(stderr, "usage: sim_render [--sessions N] [--scale S] [--presets office,floor66,weeks]\n");
      return 2;
    }
  }
  if (sessions < 1 || !(scale > 0.0)) {
    std::fprintf(stderr, "sim_render: --sessions must be at least 1 and --scale positive\n");
    return 2;
  }
  const fs::path tmp = fs::temp_directory_path() / ("chronomap_sim_render_" + std::to_string(::getpid()));
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // progress shows line by line in a log
  nlohmann::json out;
  out["sessions"] = sessions;
  out["scale"] = scale;
  std::stringstream list(presets);
  std::string preset;
  while (std::getline(list, preset, ',')) {
    nlohmann::json r;
    for (int threads : {1, 2}) {
      SimulationSettings s;
      s.preset = preset;
      s.sessions = sessions;
      s.resolution_scale = scale;
      s.threads = threads;
      const fs::path dir = tmp / (preset + "_" + std::to_string(threads));
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = cpuSeconds();
      const SimulationSummary summary = chronomap::simulate(s, dir);
      const double sec = since(t0);
      const double cpu = (cpuSeconds() - c0) / sessions;
      const double per = sec / sessions;
      std::printf("%-8s %d thread(s): %d sessions, %zu frames in %.2f s: %.2f s/session (%.2f processor s/session)\n",
                  preset.c_str(), threads, sessions, summary.frames, sec, per, cpu);
      r["s_per_session_" + std::to_string(threads) + "t"] = per;
      r["cpu_s_per_session_" + std::to_string(threads) + "t"] = cpu;
      r["frames"] = summary.frames;
    }
    // The renderer alone: session 0's poses, the first scene state, one thread.
    const SceneState state = makeScene(preset, 1);
    const auto poses = parseTumTrajectory(readTextFile(tmp / (preset + "_1") / "session_00" / "groundtruth.txt"),
                                              "groundtruth.txt");
    const Camera cam = kinectCamera(scale);
    const SensorModel sensor;
    const auto t0 = std::chrono::steady_clock::now();
    const Renderer renderer(state);
    const double build_s = since(t0);
    const auto t1 = std::chrono::steady_clock::now();
    const double c1 = cpuSeconds();
    size_t hits = 0;
    for (size_t i = 0; i < poses.size(); ++i) {
      const RenderedFrame f = renderer.render(cam, poses[i].pose, sensor, 12.0, i);
      for (float z : f.true_depth_m) hits += z > 0.0f;
    }
    const double render_s = since(t1);
    const double render_cpu = cpuSeconds() - c1;
    const double fps = static_cast<double>(poses.size()) / render_s;
    const double rays = fps * cam.width * cam.height;
    std::printf("%-8s renderer alone: %zu frames of %ux%u in %.2f s (%.2f processor s): %.1f frames/s, %.2f Mrays/s "
                "(build %.1f ms, %zu hits)\n",
                preset.c_str(), poses.size(), cam.width, cam.height, render_s, render_cpu, fps, rays / 1e6, build_s * 1e3,
                hits);
    r["render_fps_1t_processor"] = static_cast<double>(poses.size()) / render_cpu;
    r["render_fps_1t"] = fps;
    r["render_mrays_per_s_1t"] = rays / 1e6;
    out[preset] = r;
  }
  std::error_code ec;
  fs::remove_all(tmp, ec);
  std::printf("%s\n", out.dump().c_str());
  std::fflush(stdout);
  return 0;
}
