// bench/scale: a site's sessions built into a tiled 4D map by the streaming build, one night at a
// time under a memory budget (peak RSS per night), then queried; and the first --whole nights
// built whole by one process and by two MPI ranks (issue 28). The nights are what one run
// allows (--sessions), not the preset's year.
//
//   scale [--sessions N] [--whole W] [--floors F] [--scale S] [--memory-limit GIB] [--sim DIR] [--work DIR]
//         [--plot PNG] [--first-night K] [--last-night L] [--earlier OUTPUT] [--tile-windows N]
//         [--layout whole|windows]
//   scale --query DIR
//   scale --plot-from OUTPUT --plot PNG
//
// CHRONOMAP_CLI=PATH runs that chronomap instead of the one built beside it.
// --query measures only the queries on a tiled map folder an earlier run left (DIR/stream).
// --sim reuses simulated sessions (any TUM session folders session_*), else `chronomap simulate
// --preset site` writes them. --whole 0 skips the whole-map builds. Last line: one JSON object.
// --plot draws the nights (peak RSS, processor and wall time, tiles rewritten, bytes on disk) as
// one PNG (docs/scale.md); --plot-from draws it from what an earlier run printed: its last line,
// or, for a run stopped before the end, the night lines it wrote to stderr.
// A long run in pieces (with --sim): --last-night L stops after night L; --first-night K goes on
// from the tiled map DIR/stream that an earlier run left with nights 1..K-1 (the work folder is
// kept); --earlier OUTPUT adds the nights an earlier run printed that this one did not build (for
// night 10's figure, the ratio and the plot; each such night is marked "earlier": true).
// --tile-windows N passes `build --tile-windows N` (sessions per window file; 0: none) each night.
// --layout windows passes `build --windowed-tiles`: the tiles kept as windows, of which a night
// reads and writes the open one only (docs/scale.md, "A tile as its windows").

#include <sys/resource.h>
#include <sys/wait.h>
#include <spawn.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "chronomap/ingest/png.h"
#include "chronomap/pipeline/tiles.h"
#include "chronomap/render/plot.h"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using namespace chronomap;

/// One child process: wall and processor seconds, peak RSS, exit code.
struct Run {
  double wall_s = 0.0, user_s = 0.0, sys_s = 0.0, max_rss_mib = 0.0;
  int exit_code = -1;
  double cpu() const { return user_s + sys_s; }
};

Run run(const std::vector<std::string>& args, const fs::path& out) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = 0;
  Run r;
  if (posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ) != 0) return r;
  posix_spawn_file_actions_destroy(&actions);
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.user_s = static_cast<double>(usage.ru_utime.tv_sec) + static_cast<double>(usage.ru_utime.tv_usec) * 1e-6;
  r.sys_s = static_cast<double>(usage.ru_stime.tv_sec) + static_cast<double>(usage.ru_stime.tv_usec) * 1e-6;
  r.max_rss_mib = static_cast<double>(usage.ru_maxrss) / 1024.0;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string one;
  in >> one;
  return one;
}

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

/// The queries on a tiled map folder (3.2 m tiles): a cold snapshot of one room of the first
/// floor (office 2 of floor66) at the last session's time (the tiles' latest states) and at the
/// middle session's (their history windows where they have them; then again from the tiles'
/// files alone, "_without_windows"), then voxel histories in it once its tiles are held.
/// "Cold": a new TiledMap, its cache empty (the files may sit in the system's page cache); best
/// and median of five.
void measureQueries(const fs::path& folder, size_t tiles, nlohmann::json& out) {
  out["tiles"] = tiles;
  const Eigen::Vector3d lo(5.1, 2.2, -0.5), hi(9.9, 11.0, 3.0);
  auto best = [](std::vector<double> v) { return *std::min_element(v.begin(), v.end()); };
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  for (const int which : {0, 1, 2}) {  // the latest time; the middle one; the middle one without windows
    const bool last = which == 0;
    std::vector<double> total, open;
    for (int rep = 0; rep < 5; ++rep) {
      const auto start = std::chrono::steady_clock::now();
      TileCacheSettings settings;
      settings.read_windows = which != 2;
      TiledMap map(folder, settings);
      open.push_back(msSince(start));
      const VoxelBox box = voxelBoxOf(map.grid(), lo, hi);
      const auto& sessions = map.sessions();
      const double t = last ? sessions.back().time_s : sessions[(sessions.size() - 1) / 2].time_s;
      const SessionMap room = map.snapshot(t, box);
      total.push_back(msSince(start));
      const std::string key = last ? "" : which == 1 ? "_history" : "_history_without_windows";
      const TileCacheStats& c = map.cacheStats();
      out["snapshot_room_tiles" + key] = c.loads + c.latest_reads + c.time_reads;
      out["snapshot_room_windows" + key] = c.window_reads;
      out["room_nodes" + key] = room.innerCount() + room.leafCount();
    }
    const std::string key = last        ? "snapshot_room_ms_cold"
                            : which == 1 ? "snapshot_room_ms_cold_history"
                                         : "snapshot_room_ms_cold_history_without_windows";
    out[key] = best(total);
    if (which == 1) out["snapshot_mid_ms_cold"] = best(total);  // issue 46's name: the middle session's time
    out[key + "_first"] = total.front();
    out[key + "_median"] = median(total);
    if (last) out["index_open_ms"] = best(open);
  }

  TiledMap map(folder);
  std::vector<VoxelKey> keys;
  std::mt19937 random(1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d p = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(unit(random), unit(random), unit(random)));
    if (const auto k = map.grid().keyOf(p)) keys.push_back(*k);
  }
  for (const VoxelKey& k : keys) map.history(k);  // the tiles held
  size_t entries = 0;
  const auto start = std::chrono::steady_clock::now();
  for (const VoxelKey& k : keys) entries += map.history(k).size();
  out["history_us"] = msSince(start) * 1000.0 / static_cast<double>(keys.size());
  out["history_entries"] = entries;
}

}  // namespace

namespace {

/// The nights in what a run printed: its last line's, or the night lines of a stopped run.
nlohmann::json nightsPrinted(const fs::path& output) {
  std::ifstream in(output);
  std::string line;
  nlohmann::json nights = nlohmann::json::array();
  while (std::getline(in, line)) {
    const nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!j.is_object()) continue;
    if (j.contains("stream_nights")) nights = j["stream_nights"];  // a finished run's last line
    else if (j.contains("night")) nights.push_back(j);               // a night of a stopped run
  }
  return nights;
}

/// The nights of a streaming run as four plots stacked: peak RSS (with the 1 GiB target),
/// processor and wall seconds, tiles rewritten and held, and the map's MiB on disk.
chronomap::ImageRgb plotNights(const nlohmann::json& nights) {
  using chronomap::PlotSeries;
  std::vector<double> n, rss, cpu, wall, rewritten, tiles, mib, target;
  for (const auto& night : nights) {
    n.push_back(night.at("night").get<double>());
    rss.push_back(night.at("peak_rss_mib").get<double>());
    cpu.push_back(night.at("cpu_s").get<double>());
    wall.push_back(night.at("wall_s").get<double>());
    rewritten.push_back(night.at("tiles_rewritten").get<double>());
    tiles.push_back(night.at("tiles").get<double>());
    mib.push_back(night.at("bytes").get<double>() / 1048576.0);
    target.push_back(1024.0);
  }
  const auto plot = [&](std::vector<PlotSeries> series, const std::string& title, const std::string& y) {
    chronomap::PlotSettings settings;
    settings.title = title;
    settings.x_label = "night";
    settings.y_label = y;
    settings.height = 300;
    return chronomap::renderLinePlot(series, settings);
  };
  const std::vector<chronomap::ImageRgb> panels = {
      plot({{"peak RSS", {31, 119, 180}, n, rss}, {"target 1 GiB", {214, 39, 40}, n, target}},
           "Peak resident memory of each night's build", "MiB"),
      plot({{"processor", {44, 160, 44}, n, cpu}, {"wall", {127, 127, 127}, n, wall}}, "Time of each night's build",
           "seconds"),
      plot({{"rewritten", {255, 127, 14}, n, rewritten}, {"in the map", {0, 0, 0}, n, tiles}},
           "Tiles rewritten by each night", "tiles"),
      plot({{"on disk", {148, 103, 189}, n, mib}}, "The tiled map's size after each night", "MiB")};
  chronomap::ImageRgb out;
  out.width = panels[0].width;
  for (const auto& p : panels) out.height += p.height;
  out.pixels.reserve(static_cast<size_t>(out.width) * out.height);
  for (const auto& p : panels) out.pixels.insert(out.pixels.end(), p.pixels.begin(), p.pixels.end());
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  int sessions = 4, floors = 3, whole = 4, first_night = 1, last_night = 0;
  double scale = 0.5;
  std::string memory_limit = "0.25", tile_windows, layout = "whole";
  fs::path sim, query, plot, plot_from, earlier, work = fs::temp_directory_path() / "chronomap_bench_scale";
  for (int i = 1; i < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help" || i + 1 == argc) {
      std::cerr << "usage: scale [--sessions N] [--whole W] [--floors F] [--scale S] [--memory-limit GIB] [--sim DIR] "
                   "[--work DIR] [--plot PNG] [--first-night K] [--last-night L] [--earlier OUTPUT] [--tile-windows N] [--layout whole|windows] | --query DIR | --plot-from OUTPUT --plot PNG (bench/scale.cpp says more)\n";
      return a == "-h" || a == "--help" ? 0 : 2;
    }
    if (a == "--sessions") sessions = std::atoi(argv[i + 1]);
    else if (a == "--floors") floors = std::atoi(argv[i + 1]);
    else if (a == "--whole") whole = std::atoi(argv[i + 1]);
    else if (a == "--memory-limit") memory_limit = argv[i + 1];
    else if (a == "--scale") scale = std::atof(argv[i + 1]);
    else if (a == "--sim") sim = argv[i + 1];
    else if (a == "--work") work = argv[i + 1];
    else if (a == "--query") query = argv[i + 1];
    else if (a == "--plot") plot = argv[i + 1];
    else if (a == "--plot-from") plot_from = argv[i + 1];
    else if (a == "--first-night") first_night = std::atoi(argv[i + 1]);
    else if (a == "--last-night") last_night = std::atoi(argv[i + 1]);
    else if (a == "--earlier") earlier = argv[i + 1];
    else if (a == "--tile-windows") tile_windows = argv[i + 1];
    else if (a == "--layout") layout = argv[i + 1];
    else {
      std::cerr << "unknown option " << a << "\n";
      return 2;
    }
  }
  if (layout != "whole" && layout != "windows") {
    std::cerr << "--layout is whole or windows\n";
    return 2;
  }
  if (!plot_from.empty()) {  // the picture of an earlier run: its last line's nights, or its night lines
    if (plot.empty()) {
      std::cerr << "--plot-from needs --plot PNG\n";
      return 2;
    }
    const nlohmann::json nights = nightsPrinted(plot_from);
    if (nights.empty()) {
      std::cerr << plot_from.string() << " holds no night of bench/scale\n";
      return 2;
    }
    try {
      chronomap::writePng(plot, plotNights(nights));
    } catch (const std::exception& e) {
      std::cerr << plot_from.string() << ": " << e.what() << "\n";
      return 1;
    }
    return 0;
  }
  if (!query.empty()) {
    nlohmann::json out;
    measureQueries(query, TiledMap(query).index().tiles.size(), out);
    out["load_average"] = loadAverage();
    std::cout << out.dump() << "\n";
    return 0;
  }
  // CHRONOMAP_CLI: another chronomap to run (a copy, so that a long run survives rebuilds).
  const char* cli_env = std::getenv("CHRONOMAP_CLI");
  const std::string cli = cli_env && *cli_env ? cli_env : CHRONOMAP_CLI_PATH, mpirun = CHRONOMAP_MPIEXEC;
  if ((first_night != 1 || last_night != 0) && sim.empty()) {
    std::cerr << "--first-night and --last-night need --sim (the nights of one simulation)\n";
    return 2;
  }
  if (first_night < 1 || last_night < 0 || (last_night && last_night < first_night)) {
    std::cerr << "--first-night must be 1 or more, and --last-night at least --first-night\n";
    return 2;
  }
  if (first_night == 1) fs::remove_all(work);  // else the earlier run's DIR/stream goes on
  fs::create_directories(work);
  const fs::path log = work / "log.txt";
  nlohmann::json out;
  if (sim.empty()) {
    sim = work / "sim";
    const Run r = run({cli, "simulate", "--preset", "site", "--floors", std::to_string(floors), "--sessions",
                       std::to_string(sessions), "--resolution-scale", std::to_string(scale), "-o", sim.string()},
                      log);
    if (r.exit_code != 0) return 1;
    out["simulate_cpu_s"] = r.cpu();
  }
  std::vector<std::string> folders;
  for (const auto& e : fs::directory_iterator(sim)) {
    const bool session = e.path().filename().string().rfind("session_", 0) == 0;
    if (e.is_directory() && session) folders.push_back(e.path().string());
  }
  std::sort(folders.begin(), folders.end());
  if (last_night) folders.resize(std::min<size_t>(folders.size(), static_cast<size_t>(last_night)));
  out["sessions"] = folders.size();
  const std::string load_before = loadAverage();

  // The streaming build: one `chronomap build --tiles` a night, as a site would run it.
  nlohmann::json nights = nlohmann::json::array();
  double stream_peak = 0.0, stream_cpu = 0.0;
  const fs::path stream_folder = work / "stream";
  if (first_night > 1) {
    const size_t held = isTiledMap(stream_folder) ? TiledMap(stream_folder).sessions().size() : 0;
    if (held != static_cast<size_t>(first_night - 1)) {
      std::cerr << stream_folder.string() << " holds " << held << " nights, not the " << first_night - 1
                << " before --first-night " << first_night << "\n";
      return 2;
    }
    out["first_night"] = first_night;
  }
  for (size_t k = static_cast<size_t>(first_night - 1); k < folders.size(); ++k) {
    std::vector<std::string> a = {cli, "build", stream_folder.string(), folders[k], "--tiles", "--tile-size", "3.2",
                                  "--memory-limit", memory_limit, "--threads", "1", "--json"};
    if (!tile_windows.empty()) a.insert(a.end(), {"--tile-windows", tile_windows});
    if (layout == "windows") a.push_back("--windowed-tiles");
    const Run r = run(a, work / "night.json");
    if (r.exit_code != 0) return 1;
    std::ifstream in(work / "night.json");
    const nlohmann::json j = nlohmann::json::parse(in);
    nights.push_back({{"night", k + 1}, {"peak_rss_mib", r.max_rss_mib}, {"cpu_s", r.cpu()}, {"wall_s", r.wall_s},
                      {"tiles", j["tiles"]}, {"tiles_rewritten", j["tiles_written"]}, {"tiles_kept", j["tiles_kept"]},
                      {"windows_written", j["windows_written"]}, {"bytes", j["index_bytes"].get<uint64_t>() + j["tile_bytes"].get<uint64_t>()},
                      {"peak_parts_mib", j["peak_parts_bytes"].get<double>() / 1048576.0},
                      {"peak_group_mib", j["peak_group_bytes"].get<double>() / 1048576.0}, {"spills", j["spills"]}});
    std::cerr << nights.back().dump() << "\n";
    stream_peak = std::max(stream_peak, r.max_rss_mib);
    stream_cpu += r.cpu();
  }
  if (!earlier.empty()) {  // an earlier piece's nights that this run did not build
    for (nlohmann::json night : nightsPrinted(earlier)) {
      const auto number = night.at("night").get<size_t>();
      if (number >= static_cast<size_t>(first_night)) continue;  // this run's, or past its last
      night["earlier"] = true;
      nights.push_back(std::move(night));
    }
    std::stable_sort(nights.begin(), nights.end(), [](const nlohmann::json& a, const nlohmann::json& b) {
      return a.at("night").get<size_t>() < b.at("night").get<size_t>();
    });
  }
  for (const auto& night : nights) stream_peak = std::max(stream_peak, night.at("peak_rss_mib").get<double>());
  out["stream_nights"] = nights;
  if (!plot.empty() && !nights.empty()) chronomap::writePng(plot, plotNights(nights));
  out["stream_memory_limit_gib"] = memory_limit;
  out["peak_rss_mib"] = stream_peak;
  out["stream_cpu_s"] = stream_cpu;  // the nights this run built
  out["bytes_on_disk"] = nights.empty() ? 0 : nights.back()["bytes"].get<uint64_t>();
  // Only the tiles a night's sessions reach are rewritten (the others keep their files).
  out["tiles_rewritten_last_night"] = nights.empty() ? 0 : nights.back()["tiles_rewritten"].get<size_t>();
  // Night N's processor time against night 10's (issue 46: night 365's at most 1.2x night 10's).
  const auto night10 = std::find_if(nights.begin(), nights.end(),
                                    [](const nlohmann::json& n) { return n.at("night").get<size_t>() == 10; });
  if (night10 != nights.end() && nights.back()["night"].get<size_t>() >= 10) {
    out["night_cpu_ratio_" + std::to_string(nights.back()["night"].get<size_t>()) + "_10"] =
        nights.back()["cpu_s"].get<double>() / (*night10)["cpu_s"].get<double>();
  }
  // The same from medians, less at the mercy of one night: the last ten nights' against nights 6-15's.
  if (nights.size() >= 25 && nights.front()["night"].get<size_t>() == 1) {
    auto median = [&](size_t from, size_t to) {  // nights [from, to) by position
      std::vector<double> v;
      for (size_t i = from; i < to; ++i) v.push_back(nights[i]["cpu_s"].get<double>());
      std::sort(v.begin(), v.end());
      return (v[v.size() / 2 - 1] + v[v.size() / 2]) / 2.0;
    };
    out["night_cpu_median_ratio_last10_6to15"] = median(nights.size() - 10, nights.size()) / median(5, 15);
  }
  out["stream_layout"] = layout;
  folders.resize(std::min<size_t>(folders.size(), static_cast<size_t>(std::max(whole, 0))));

  // One process, one thread; then two ranks of one thread each (the same file). An earlier
  // piece's files (--first-night keeps the work folder) go first.
  for (const char* name : {"one.cmap", "two.cmap", "ranks.txt"}) fs::remove(work / name);
  auto buildArgs = [&](const fs::path& map) {
    std::vector<std::string> a = {cli, "build", map.string(), "--threads", "1", "--json"};
    a.insert(a.end(), folders.begin(), folders.end());
    return a;
  };
  Run one;
  if (!folders.empty()) {
    one = run(buildArgs(work / "one.cmap"), work / "one.json");
    if (one.exit_code != 0) return 1;
    out["whole_nights"] = folders.size();
    out["build_1rank"] = {{"wall_s", one.wall_s}, {"cpu_s", one.cpu()}, {"peak_rss_mib", one.max_rss_mib}};
    out["whole_bytes_on_disk"] = fs::file_size(work / "one.cmap");
  }
  if (!mpirun.empty() && !folders.empty()) {
    std::vector<std::string> a = {mpirun, "--allow-run-as-root", "-np", "2", "/usr/bin/time", "-a", "-o",
                                  (work / "ranks.txt").string(), "-f", "%e %U %S %M"};
    const std::vector<std::string> b = buildArgs(work / "two.cmap");
    a.insert(a.end(), b.begin(), b.end());
    const Run two = run(a, work / "two.json");
    if (two.exit_code != 0) return 1;
    std::ifstream ranks(work / "ranks.txt");
    double wall = 0, user = 0, sys = 0, rss = 0, largest = 0;
    while (ranks >> wall >> user >> sys >> rss) largest = std::max(largest, user + sys);
    const bool same = fs::file_size(work / "one.cmap") == fs::file_size(work / "two.cmap") &&
                      std::system(("cmp -s " + (work / "one.cmap").string() + " " + (work / "two.cmap").string())
                                      .c_str()) == 0;
    out["build_2ranks"] = {{"wall_s", two.wall_s}, {"cpu_s", two.cpu()}, {"largest_rank_cpu_s", largest},
                           {"same_bytes", same}};
    out["mpi2_speedup"] = one.wall_s / two.wall_s;
    out["mpi2_speedup_cpu_bound"] = largest > 0 ? one.cpu() / largest : 0.0;
  }
  out["load_average"] = {load_before, loadAverage()};

  measureQueries(stream_folder, nights.empty() ? 0 : nights.back()["tiles"].get<size_t>(), out);
  std::cout << out.dump() << "\n";
  return 0;
}
