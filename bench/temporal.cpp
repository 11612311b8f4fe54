// The 4D map against storing every session separately (thesis §2.4, Figure 3), on synthetic
// session maps of one floor in which a fixed fraction of the furniture moves between sessions.
// Until the simulator lands, the sessions are built voxel by voxel (no rendering): a floor of
// 9.6 x 9.6 x 1.6 m at 0.05 m with walls, doors that open and close, and boxes (observed as
// shells, their insides unknown) of which a fixed fraction moves each session; each session
// observes a window of 6.4 x 6.4 m at a random place, with 0.05% of its voxels flipped as noise.
//
// Measures after each session: nodes and bytes stored separately (chronomap session maps and
// OctoMap OcTrees, both in the same run) vs the 4D map; snapshot time after 8, 33 and 66
// sessions; history latency per voxel; add time per session; bytes per stored change.
//
// With --sim DIR the sessions are instead the TUM folders DIR/session_NN written by
// `chronomap simulate` (e.g. the floor66 preset), each integrated in fast mode with its
// estimated poses and added at its recorded time: the thesis' storage study replayed.
//
// Usage: temporal [--sessions N] [--move F] [--plot storage.png] [--quick] [--sim DIR] [--octomap-every N]
// [--surface-shift VOXELS] (the 4D map's ChangeCriterion::surface_shift_voxels; default 0.5, 0 off)
// [--rounds N] (--rounds: rounds of the interleaved snapshot timing, best of each; 9 by default)
// [--file-nights K] (each session also added as a night of the streaming build adds it to a tile:
// the whole history's file read, added to, compacted and written again, against the history kept
// as windows of K sessions, temporal/window.h, of which a night reads and writes the open one;
// processor time per night, and the windows joined at the end compared with the whole file, bit
// for bit)
// (--octomap-every N: convert only every Nth session to OctoMap, reusing its size for the others;
// 0 never, for long runs such as --sessions 365 whose OctoMap figures are then not measured)
// The last line of output is one JSON object.

#include <octomap/OcTree.h>
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "chronomap/integrate/integrator.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/render/plot.h"
#include "chronomap/ingest/png.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/temporal/temporal_map.h"
#include "chronomap/temporal/window.h"

using namespace chronomap;

namespace {

constexpr int kX = 192, kY = 192, kZ = 32;  // voxels
constexpr int kWindow = 128;
constexpr double kResolution = 0.05;

struct Box {
  int x, y, sx, sy, sz;
  Rgb colour;
};

struct World {
  std::vector<uint8_t> cell;  // 0 free, 1 occupied, 2 unobservable (inside a box)
  std::vector<Rgb> colour;
  std::vector<Box> boxes;
  std::vector<bool> door_open;
  uint8_t at(int x, int y, int z) const { return cell[(static_cast<size_t>(z) * kY + y) * kX + x]; }
};

const int kDoorX[] = {20, 84, 150, 40, 110, 170};
const int kDoorY[] = {64, 64, 64, 128, 128, 128};

void rasterise(World& w) {
  w.cell.assign(static_cast<size_t>(kX) * kY * kZ, 0);
  w.colour.assign(w.cell.size(), Rgb{});
  auto set = [&](int x, int y, int z, uint8_t v, Rgb c) {
    if (x < 0 || y < 0 || z < 0 || x >= kX || y >= kY || z >= kZ) return;
    const size_t i = (static_cast<size_t>(z) * kY + y) * kX + x;
    w.cell[i] = v;
    w.colour[i] = c;
  };
  for (int y = 0; y < kY; ++y) {
    for (int x = 0; x < kX; ++x) set(x, y, 0, 1, Rgb{120, 110, 100});  // floor
  }
  // Two walls along x at y = 64 and y = 128, each with three doors of 10 voxels.
  for (int wall = 0; wall < 2; ++wall) {
    const int y = wall == 0 ? 64 : 128;
    for (int x = 0; x < kX; ++x) {
      bool in_door = false;
      for (int d = 0; d < 3; ++d) {
        const int i = wall * 3 + d;
        if (x >= kDoorX[i] && x < kDoorX[i] + 10) in_door = w.door_open[static_cast<size_t>(i)] ? true : in_door;
      }
      for (int z = 1; z < kZ; ++z) {
        if (!in_door || z >= 24) set(x, y, z, 1, Rgb{200, 200, 190});
        set(x, y + 1, z, 2, Rgb{});
      }
    }
  }
  for (const Box& b : w.boxes) {
    for (int z = 1; z <= b.sz; ++z) {
      for (int y = b.y; y < b.y + b.sy; ++y) {
        for (int x = b.x; x < b.x + b.sx; ++x) {
          const bool shell = z == b.sz || y == b.y || y == b.y + b.sy - 1 || x == b.x || x == b.x + b.sx - 1;
          set(x, y, z, shell ? 1 : 2, b.colour);
        }
      }
    }
  }
}

Box randomBox(std::mt19937_64& rng) {
  Box b;
  b.sx = 4 + static_cast<int>(rng() % 10);
  b.sy = 4 + static_cast<int>(rng() % 10);
  b.sz = 4 + static_cast<int>(rng() % 14);
  b.x = static_cast<int>(rng() % static_cast<uint64_t>(kX - b.sx));
  b.y = static_cast<int>(rng() % static_cast<uint64_t>(kY - b.sy));
  b.colour = Rgb{static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng())};
  return b;
}

SessionMap observe(const World& w, std::mt19937_64& rng) {
  const int x0 = static_cast<int>(rng() % (kX - kWindow + 1)), y0 = static_cast<int>(rng() % (kY - kWindow + 1));
  SessionMap m(kResolution);
  std::vector<VoxelKey> keys;
  std::vector<VoxelCounters> values;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int z = 0; z < kZ; ++z) {
    for (int y = y0; y < y0 + kWindow; ++y) {
      for (int x = x0; x < x0 + kWindow; ++x) {
        uint8_t c = w.at(x, y, z);
        if (c == 2) continue;
        if (u(rng) < 0.0005) c = c ? 0 : 1;  // sensor noise
        VoxelCounters v;
        if (c == 1) {
          const Rgb col = w.colour[(static_cast<size_t>(z) * kY + y) * kX + x];
          v.hits = 3;
          v.length_m = 0.1f;
          v.red = 3u * col.r;
          v.green = 3u * col.g;
          v.blue = 3u * col.b;
        } else {
          v.length_m = 0.15f;
        }
        keys.push_back(VoxelKey{static_cast<uint16_t>(kKeyOrigin + x), static_cast<uint16_t>(kKeyOrigin + y),
                                static_cast<uint16_t>(kKeyOrigin + z)});
        values.push_back(v);
      }
    }
  }
  m.addMany(keys, values);
  m.compressFree();
  return m;
}

// An OctoMap OcTree holding the same session (occupied and free voxels), pruned.
size_t octomapBytes(const SessionMap& m) {
  octomap::OcTree tree(kResolution);
  const float occ = tree.getClampingThresMaxLog(), fre = tree.getClampingThresMinLog();
  m.forEachLeaf([&](const LeafView& leaf) {
    const int side = 1 << leaf.level;
    const float v = leaf.counters.state() == VoxelState::Occupied ? occ : fre;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          tree.setNodeValue(octomap::OcTreeKey(static_cast<octomap::key_type>(leaf.key.x + dx),
                                               static_cast<octomap::key_type>(leaf.key.y + dy),
                                               static_cast<octomap::key_type>(leaf.key.z + dz)),
                            v, true);
        }
      }
    }
  });
  tree.updateInnerOccupancy();
  tree.prune();
  return tree.memoryUsage();
}

double seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// Processor time of this thread, in seconds (robust to other jobs on the machine).
double threadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Minor page faults of the process so far.
long minorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

// One snapshot of the latest time, in seconds; prints what it holds and visited when `describe`;
// adds the page faults it took to `faults`.
double snapshotOnce(const TemporalMap& map, bool describe, long* faults = nullptr) {
  TemporalMap::SnapshotVisits visits;
  const long f0 = minorFaults();
  const auto a = std::chrono::steady_clock::now();
  const SessionMap s = map.snapshot(map.times().back(), &visits);
  const auto b = std::chrono::steady_clock::now();
  if (faults) *faults += minorFaults() - f0;
  if (describe) {
    const SessionMapCounts c = s.counts();
    std::printf("  snapshot: %zu leaves (%zu compressed), %llu voxels known; 4D map: %zu slot lists, %zu inner nodes; "
                "visited %zu inner nodes, %zu lists, %zu coarse entries\n",
                c.leaves, c.compressed_leaves, static_cast<unsigned long long>(c.occupied_voxels + c.free_voxels),
                map.counts().slots, map.counts().inner_nodes, visits.inner, visits.lists, visits.coarse);
  }
  return seconds(a, b);
}

double timeSnapshot(const TemporalMap& map) {
  double best = 1e9;
  for (int r = 0; r < 3; ++r) best = std::min(best, snapshotOnce(map, r == 0));
  return best;
}

// One tile's nights through files, two ways (--file-nights): the whole history, or windows.
class FileNights {
 public:
  FileNights(uint32_t window_sessions, const ChangeCriterion& criterion)
      : k_(window_sessions), whole_(encodeTemporalMap(TemporalMap(kResolution, criterion), {})),
        open_(encodeTemporalMapAsItIs(TemporalMap(kResolution, criterion), {})) {}

  void night(double time_s, const SessionMap& session) {
    double cpu0 = threadCpuSeconds();
    TemporalMap whole = decode(whole_);
    whole.add(time_s, session);
    whole.compact(TemporalMap::Relayout::kWhenMerged);
    whole_ = encodeTemporalMap(whole, {});
    whole_cpu_.push_back(threadCpuSeconds() - cpu0);

    cpu0 = threadCpuSeconds();
    TemporalMap open = decode(open_);
    open.add(time_s, session);
    open.compact(TemporalMap::Relayout::kWhenMerged);
    if (++own_ == k_) {
      closed_.push_back(encodeTemporalMapAsItIs(open, {}));
      open = continuedWindow(open);
      own_ = 0;
    }
    open_ = encodeTemporalMapAsItIs(open, {});
    windows_cpu_.push_back(threadCpuSeconds() - cpu0);
    whole_lists_ = whole.counts().slots;
    open_lists_ = open.counts().slots;
  }

  /// Prints the figures; adds them to `out`. @return false when the windows do not join to the
  /// whole file.
  bool report(nlohmann::json& out) const {
    std::vector<TemporalMap> windows;
    for (const auto& w : closed_) windows.push_back(decode(w));
    if (own_ > 0 || closed_.empty()) windows.push_back(decode(open_));
    const TemporalMap joined = joinWindows(windows), whole = decode(whole_);
    const TemporalMap::Parts a = joined.parts(), b = whole.parts();
    const bool same = a.inner == b.inner && a.list_sizes == b.list_sizes && a.entries == b.entries &&
                      joined.times() == whole.times();
    size_t window_bytes = open_.size();
    for (const auto& w : closed_) window_bytes += w.size();
    const size_t n = whole_cpu_.size();
    auto median = [&](const std::vector<double>& v, size_t from, size_t to) {
      std::vector<double> part(v.begin() + static_cast<std::ptrdiff_t>(from), v.begin() + static_cast<std::ptrdiff_t>(to));
      std::sort(part.begin(), part.end());
      return part.empty() ? 0.0 : part[part.size() / 2];
    };
    // Nights 6-15 and the last ten (as bench/scale's night_cpu_ratio_365_10 takes its medians).
    const size_t early_to = std::min<size_t>(n, 15), late_from = n >= 10 ? n - 10 : 0;
    const double whole_early = median(whole_cpu_, std::min<size_t>(5, n), early_to);
    const double whole_late = median(whole_cpu_, late_from, n);
    const double win_early = median(windows_cpu_, std::min<size_t>(5, n), early_to);
    const double win_late = median(windows_cpu_, late_from, n);
    std::printf("\nnights through files (%zu): the whole history %.1f / %.1f ms (nights 6-15 / the last ten, "
                "medians; %.2fx), windows of %u sessions %.1f / %.1f ms (%.2fx); last night %.1f against %.1f ms; "
                "on disk %.2f MiB whole, %.2f MiB in %zu windows; the windows join to the whole file: %s\n",
                n, 1e3 * whole_early, 1e3 * whole_late, whole_late / whole_early, k_, 1e3 * win_early, 1e3 * win_late,
                win_late / win_early, 1e3 * whole_cpu_.back(), 1e3 * windows_cpu_.back(),
                static_cast<double>(whole_.size()) / 1048576.0, static_cast<double>(window_bytes) / 1048576.0,
                closed_.size() + 1, same ? "yes, bit for bit" : "NO");
    std::printf("lists after the last night: %zu in the whole history, %zu in the open window\n", whole_lists_,
                open_lists_);
    out["file_night_ms_whole"] = {1e3 * whole_early, 1e3 * whole_late};
    out["file_night_ms_windows"] = {1e3 * win_early, 1e3 * win_late};
    out["file_night_cpu_ratio_whole"] = whole_late / whole_early;
    out["file_night_cpu_ratio_windows"] = win_late / win_early;
    out["file_window_sessions"] = k_;
    out["file_windows_join_whole"] = same;
    return same;
  }

 private:
  static TemporalMap decode(const std::vector<uint8_t>& bytes) {
    return temporalMapFrom(decodeCmap(bytes, "night"), "night");
  }
  uint32_t k_;
  std::vector<uint8_t> whole_, open_;
  std::vector<std::vector<uint8_t>> closed_;
  uint32_t own_ = 0;
  std::vector<double> whole_cpu_, windows_cpu_;
  size_t whole_lists_ = 0, open_lists_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  int sessions = 66;
  double move = 0.1;
  std::string plot;
  int octomap_every = 1;
  int rounds = 9;
  std::string sim_dir;
  int file_nights = 0;  // --file-nights K
  ChangeCriterion criterion;  // --surface-shift V: ChangeCriterion::surface_shift_voxels
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--sessions") && i + 1 < argc) {
      sessions = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--move") && i + 1 < argc) {
      move = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--plot") && i + 1 < argc) {
      plot = argv[++i];
    } else if (!std::strcmp(argv[i], "--sim") && i + 1 < argc) {
      sim_dir = argv[++i];
    } else if (!std::strcmp(argv[i], "--rounds") && i + 1 < argc) {
      rounds = std::max(1, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--octomap-every") && i + 1 < argc) {
      octomap_every = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--file-nights") && i + 1 < argc) {
      file_nights = std::max(0, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--surface-shift") && i + 1 < argc) {
      criterion.surface_shift_voxels = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--quick")) {
      sessions = 12;
      octomap_every = 4;
    } else {
      std::fprintf(stderr,
                   "usage: temporal [--sessions N] [--move F] [--plot storage.png] [--quick] [--sim DIR] "
                   "[--octomap-every N] [--surface-shift VOXELS] [--rounds N] [--file-nights K]\n");
      return 2;
    }
  }
  std::vector<std::filesystem::path> sim_sessions;
  if (!sim_dir.empty()) {
    for (const auto& e : std::filesystem::directory_iterator(sim_dir)) {
      if (e.is_directory() && e.path().filename().string().rfind("session_", 0) == 0) sim_sessions.push_back(e.path());
    }
    std::sort(sim_sessions.begin(), sim_sessions.end());
    if (sim_sessions.empty()) {
      std::fprintf(stderr, "no session_NN folders in %s\n", sim_dir.c_str());
      return 2;
    }
    sessions = static_cast<int>(sim_sessions.size());
  }
  if (sessions < 1) return 2;
  double integrate_seconds = 0.0;
  std::mt19937_64 rng(42);
  World world;
  world.door_open.assign(6, true);
  for (int i = 0; i < 40; ++i) world.boxes.push_back(randomBox(rng));
  rasterise(world);

  TemporalMap map(kResolution, criterion);
  std::optional<FileNights> file_nights_run;
  if (file_nights > 0) file_nights_run.emplace(static_cast<uint32_t>(file_nights), criterion);
  std::vector<double> sep_nodes, nodes_4d, octo_bytes;
  double separate = 0.0, octomap_total = 0.0, add_seconds = 0.0, add_cpu_seconds = 0.0, octo_last = 0.0;
  uint64_t separate_bytes = 0;
  double snap8 = 0.0, snap33 = 0.0, snap66 = 0.0;
  // The maps after 8 sessions, kept to time their snapshots interleaved with the last one's
  // (this machine's speed drifts over minutes): as built in memory, and compacted (as read
  // from a file: depth-first pools, mergeable lists merged).
  TemporalMap map8(kResolution), map8_compacted(kResolution);
  size_t bytes_after_first = 0, entries_after_first = 0;
  std::printf("session  nodes_separate  nodes_4d  bytes_4d  octomap_separate_MiB  add_ms\n");
  for (int s = 0; s < sessions; ++s) {
    double time_s = 3600.0 * 8 * s;
    SessionMap session(kResolution);
    if (!sim_sessions.empty()) {
      const auto dataset = openDataset(sim_sessions[static_cast<size_t>(s)]);
      IntegratorSettings is;
      is.fast = true;
      const IntegrationStats st = integrate(*dataset, session, is);
      integrate_seconds += st.seconds;
      time_s = dataset->recordedAt().value_or(time_s);
    } else {
      if (s > 0) {
        for (auto& b : world.boxes) {
          if (std::uniform_real_distribution<double>(0, 1)(rng) < move) b = randomBox(rng);
        }
        for (size_t d = 0; d < world.door_open.size(); ++d) {
          if (rng() % 5 == 0) world.door_open[d] = !world.door_open[d];
        }
        rasterise(world);
      }
      session = observe(world, rng);
    }
    separate += static_cast<double>(session.innerCount() + session.leafCount());
    separate_bytes += session.memoryBytes();
    if (octomap_every > 0 && s % octomap_every == 0) octo_last = static_cast<double>(octomapBytes(session));
    octomap_total += octo_last;
    const auto a = std::chrono::steady_clock::now();
    const double cpu0 = threadCpuSeconds();
    map.add(time_s, session);
    add_cpu_seconds += threadCpuSeconds() - cpu0;
    const auto b = std::chrono::steady_clock::now();
    if (file_nights_run) file_nights_run->night(time_s, session);
    add_seconds += seconds(a, b);
    const TemporalCounts c = map.counts();
    if (s == 0) {
      bytes_after_first = map.memoryBytes();
      entries_after_first = c.entries;
    }
    sep_nodes.push_back(separate);
    nodes_4d.push_back(static_cast<double>(c.nodes()));
    octo_bytes.push_back(octomap_total);
    std::printf("%7d  %14.0f  %8zu  %8zu  %20.1f  %6.1f\n", s + 1, separate, c.nodes(), map.memoryBytes(),
                octomap_total / 1048576.0, 1e3 * seconds(a, b));
    if (s + 1 == 8) {
      snap8 = timeSnapshot(map);
      map8 = map;
      map8_compacted = map;
      map8_compacted.compact();
    }
    if (s + 1 == 33) snap33 = timeSnapshot(map);
    if (s + 1 == sessions) snap66 = timeSnapshot(map);
  }
  if (sessions < 8) {
    snap8 = snap66;
    map8 = map;
    map8_compacted = map;
    map8_compacted.compact();
  }
  // Interleaved: 9 rounds of (after 8, last) in memory and compacted; best of each.
  TemporalMap last_compacted = map;
  last_compacted.compact();
  double best[4] = {1e9, 1e9, 1e9, 1e9};
  long faults[4] = {0, 0, 0, 0};
  const TemporalMap* timed[4] = {&map8, &map, &map8_compacted, &last_compacted};
  for (int round = 0; round < rounds; ++round) {
    for (int i = 0; i < 4; ++i) {
      best[i] = std::min(best[i], snapshotOnce(*timed[i], round == 0 && i >= 2, &faults[i]));
    }
  }
  std::printf("page faults per snapshot: in memory %.0f / %.0f, compacted %.0f / %.0f\n",
              static_cast<double>(faults[0]) / rounds, static_cast<double>(faults[1]) / rounds,
              static_cast<double>(faults[2]) / rounds, static_cast<double>(faults[3]) / rounds);
  const double ratio = best[1] / best[0], ratio_compacted = best[3] / best[2];

  // History latency: random voxels inside the map's known region, many times.
  std::vector<VoxelKey> probes;
  {
    const SessionMap latest = map.snapshot(map.times().back());
    VoxelKey lo{65535, 65535, 65535}, hi{0, 0, 0};
    latest.forEachLeaf([&](const LeafView& l) {
      lo = VoxelKey{std::min(lo.x, l.key.x), std::min(lo.y, l.key.y), std::min(lo.z, l.key.z)};
      hi = VoxelKey{std::max(hi.x, l.key.x), std::max(hi.y, l.key.y), std::max(hi.z, l.key.z)};
    });
    for (int i = 0; i < 200000; ++i) {
      probes.push_back(VoxelKey{static_cast<uint16_t>(lo.x + rng() % (hi.x - lo.x + 1u)),
                                static_cast<uint16_t>(lo.y + rng() % (hi.y - lo.y + 1u)),
                                static_cast<uint16_t>(lo.z + rng() % (hi.z - lo.z + 1u))});
    }
  }
  size_t entries_seen = 0;
  const auto h0 = std::chrono::steady_clock::now();
  for (const VoxelKey& k : probes) entries_seen += map.history(k).size();
  const auto h1 = std::chrono::steady_clock::now();
  const double history_us = 1e6 * seconds(h0, h1) / static_cast<double>(probes.size());

  // On disk.
  const auto path = std::filesystem::temp_directory_path() / "chronomap-bench-temporal.cmap";
  const auto w0 = std::chrono::steady_clock::now();
  writeTemporalMap(path, map, {});
  const auto w1 = std::chrono::steady_clock::now();
  const auto file_bytes = std::filesystem::file_size(path);
  const TemporalMap back = readTemporalMap(path);
  const auto w2 = std::chrono::steady_clock::now();
  if (!std::getenv("CHRONOMAP_KEEP_BENCH_MAP")) std::filesystem::remove(path);
  const TemporalCounts c = map.counts();
  TemporalMap compacted = map;
  compacted.compact();
  const double stored_changes = static_cast<double>(c.entries - entries_after_first);
  const double bytes_per_change =
      stored_changes > 0 ? static_cast<double>(map.memoryBytes() - bytes_after_first) / stored_changes : 0.0;

  if (sim_sessions.empty()) {
    std::printf("\n%d sessions, %.0f%% of the boxes moved per session, doors toggled with p = 0.2\n", sessions,
                100.0 * move);
  } else {
    std::printf("\n%d simulated sessions from %s, integrated in fast mode in %.1f s\n", sessions, sim_dir.c_str(),
                integrate_seconds);
  }
  std::printf("nodes: separate %.0f, 4D map %zu (%.1f%% of separate; %.1f%% reduction; thesis: 93 M -> 14 M, 85%%)\n",
              separate, c.nodes(), 100.0 * static_cast<double>(c.nodes()) / separate,
              100.0 * (1.0 - static_cast<double>(c.nodes()) / separate));
  std::printf("after compaction (as written): %zu nodes\n", compacted.counts().nodes());
  std::printf("bytes: 4D map %.1f MiB in memory, %.1f MiB on disk; session maps separately %.1f MiB; "
              "OctoMap OcTrees separately %.1f MiB (4D/OctoMap = %.3f)\n",
              map.memoryBytes() / 1048576.0, static_cast<double>(file_bytes) / 1048576.0,
              static_cast<double>(separate_bytes) / 1048576.0, octomap_total / 1048576.0,
              static_cast<double>(map.memoryBytes()) / octomap_total);
  std::printf("nodes added per session after the first: %.0f on average\n",
              (static_cast<double>(c.nodes()) - nodes_4d.front()) / std::max(1, sessions - 1));
  std::printf("snapshot of the latest time: %.1f ms after 8, %.1f ms after 33, %.1f ms after %d sessions (%.2fx)\n",
              1e3 * snap8, 1e3 * snap33, 1e3 * snap66, sessions, snap66 / snap8);
  std::printf("snapshot interleaved, best of %d: in memory %.2f ms after 8, %.2f ms after %d sessions (%.2fx); "
              "compacted %.2f / %.2f ms (%.2fx)\n",
              rounds, 1e3 * best[0], 1e3 * best[1], sessions, ratio, 1e3 * best[2], 1e3 * best[3], ratio_compacted);
  std::printf("history: %.3f us per voxel (%zu entries over %zu probes)\n", history_us, entries_seen, probes.size());
  std::printf("add: %.1f ms per session on average (%.1f ms of processor time); write %.1f ms, read %.1f ms\n",
              1e3 * add_seconds / sessions, 1e3 * add_cpu_seconds / sessions, 1e3 * seconds(w0, w1),
              1e3 * seconds(w1, w2));
  std::printf("bytes per stored change: %.1f\n", bytes_per_change);
  {
    const TemporalMap::MemoryUse m = map.memoryUse();
    auto mib = [](size_t b) { return static_cast<double>(b) / 1048576.0; };
    std::printf("memory by part, MiB: inner %.1f, list records %.1f, arena entries %.1f, hit parts %.1f, "
                "slack %.1f, coarse %.1f, sessions %.1f, change masks %.1f\n",
                mib(m.inner), mib(m.lists), mib(m.entries), mib(m.hit_parts), mib(m.slack), mib(m.coarse),
                mib(m.sessions), mib(m.change_masks));
    size_t lists = 0, single = 0, entries = 0, hit = 0, single_hit = 0;
    map.forEachList([&](const VoxelKey&, int, std::span<const TemporalMap::Entry> e) {
      ++lists;
      single += e.size() == 1;
      entries += e.size();
      for (const auto& x : e) hit += x.value.hits > 0;
      single_hit += e.size() == 1 && e[0].value.hits > 0;
    });
    std::printf("lists %zu (%zu of one entry, %zu of them with hits), entries %zu (%zu with hits), inner nodes %zu\n",
                lists, single, single_hit, entries, hit, map.counts().inner_nodes);
  }
  double relayout_ms = 0.0;
  {
    TemporalMap copy = map;
    const double cpu0 = threadCpuSeconds();
    copy.relayout();
    relayout_ms = 1e3 * (threadCpuSeconds() - cpu0);
  }
  std::printf("pools re-laid out in memory by add: %zu times in %d sessions; one re-layout of the last map: %.1f ms "
              "of CPU time\n",
              map.relayouts(), sessions, relayout_ms);
  if (!(back.counts().nodes() == compacted.counts().nodes())) std::printf("WARNING: read-back differs\n");

  if (!plot.empty()) {
    writePng(plot, renderStoragePlot(sep_nodes, nodes_4d, "Nodes after each session"));
    std::printf("wrote %s\n", plot.c_str());
  }
  nlohmann::json j = {{"sessions", sessions},
                            {"nodes_separate", static_cast<uint64_t>(separate)},
                            {"nodes_4d", c.nodes()},
                            {"bytes_4d", map.memoryBytes()},
                            {"file_bytes_4d", file_bytes},
                            {"octomap_bytes_separate", static_cast<uint64_t>(octomap_total)},
                            {"snapshot_66_vs_8", ratio},
                            {"snapshot_last_vs_8_compacted", ratio_compacted},
                            {"snapshot_8_ms", 1e3 * best[0]},
                            {"snapshot_last_ms", 1e3 * best[1]},
                            {"history_us", history_us},
                            {"add_ms_per_session", 1e3 * add_seconds / sessions},
                            {"add_cpu_ms_per_session", 1e3 * add_cpu_seconds / sessions},
                            {"relayouts", map.relayouts()},
                            {"bytes_per_change", bytes_per_change}};
  const bool joined = !file_nights_run || file_nights_run->report(j);
  std::printf("%s\n", j.dump().c_str());
  return joined ? 0 : 1;
}
