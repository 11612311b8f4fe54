// chronomap snapshot | history | changes: asking a 4D map.

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "chronomap/analysis/change_frequency.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/maps.h"
#include "commands.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

// ------------------------------------------------------------------------------------------
// snapshot

struct SnapshotCmdOptions {
  std::string map;
  std::string at;
  std::string output;
  std::string box;
  std::optional<double> memory_limit_gib;
  bool json = false;
};

/// "X0,Y0,Z0,X1,Y1,Z1" in metres.
BoxMetres parseBox(const std::string& text) {
  const std::vector<std::string> parts = splitCommas(text);
  double v[6];
  bool ok = parts.size() == 6;
  for (size_t i = 0; ok && i < 6; ++i) {
    try {
      size_t used = 0;
      v[i] = std::stod(parts[i], &used);
      ok = used == parts[i].size() && std::isfinite(v[i]);
    } catch (const std::exception&) {
      ok = false;
    }
  }
  if (!ok) throw UsageError("--box must be X0,Y0,Z0,X1,Y1,Z1 in metres, got '" + text + "'");
  return {Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5])};
}

nlohmann::json tileStatsJson(const std::optional<TileCacheStats>& s) {
  if (!s) return nullptr;
  // Tiles read from disk whole or at one time (readTileSnapshot); latest states not counted.
  return {{"tiles_loaded", s->loads + s->time_reads},
          {"windows_read", s->window_reads},
          {"tiles_evicted", s->evictions},
          {"peak_tile_bytes", s->peak_resident_bytes}};
}

int runSnapshot(const SnapshotCmdOptions& o) {
  const std::string ext = fs::path(o.output).extension().string();
  if (ext != ".cmap" && ext != ".ply" && ext != ".ot" && ext != ".png") {
    throw UsageError("output '" + o.output + "' must end in .cmap, .ply, .ot or .png");
  }
  refuseOverwritingInputs(o.output, {o.map});
  const double t = parseTime(o.at);
  const std::optional<BoxMetres> box = o.box.empty() ? std::nullopt : std::optional(parseBox(o.box));
  const MapSnapshot r = snapshotOfMap(o.map, t, box, tileCacheSettings(o.memory_limit_gib));
  const SessionMap& snap = r.map;
  ExportSettings settings;
  settings.metadata = {{"created_by", "chronomap snapshot"}, {"snapshot_of", o.map}, {"time_s", t}};
  const size_t n = exportSessionMap(o.output, snap, settings);
  const SessionMapCounts c = snap.counts();
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output},   {"time", formatTime(t)},       {"time_s", t},
                                {"occupied", c.occupied_voxels}, {"free", c.free_voxels}, {"elements", n},
                                {"tiles", tileStatsJson(r.tiles)}}
                     .dump()
              << "\n";
  } else {
    std::cout << "wrote " << o.output << ": the map as last observed at " << formatTime(t) << " ("
              << c.occupied_voxels << " occupied, " << c.free_voxels << " free voxels)\n";
  }
  return 0;
}

// ------------------------------------------------------------------------------------------
// history

struct HistoryCmdOptions {
  std::string map;
  std::string point;
  std::optional<double> memory_limit_gib;
  bool json = false;
};

Eigen::Vector3d parsePoint(const std::string& text) {
  const std::vector<std::string> parts = splitCommas(text);
  if (parts.size() != 3) throw UsageError("--point must be X,Y,Z in metres, got '" + text + "'");
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) {
    try {
      size_t used = 0;
      p[i] = std::stod(parts[static_cast<size_t>(i)], &used);
      if (used != parts[static_cast<size_t>(i)].size() || !std::isfinite(p[i])) throw std::invalid_argument("");
    } catch (const std::exception&) {
      throw UsageError("--point must be X,Y,Z in metres, got '" + text + "'");
    }
  }
  return p;
}

void printHistoryJson(const Eigen::Vector3d& p, const Eigen::Vector3d& c, const VoxelKey& key,
                      const std::vector<HistoryEntry>& history) {
  nlohmann::json entries = nlohmann::json::array();
  for (const auto& e : history) {
    const Rgb rgb = e.counters.meanColour();
    entries.push_back({{"time", formatTime(e.time_s)},
                       {"time_s", e.time_s},
                       {"state", toString(e.counters.state())},
                       {"probability", e.counters.probability()},
                       {"hits", e.counters.hits},
                       {"length_m", e.counters.length_m},
                       {"color", {rgb.r, rgb.g, rgb.b}},
                       {"level", e.level}});
  }
  std::cout << nlohmann::json{{"point", {p.x(), p.y(), p.z()}},
                              {"voxel_center", {c.x(), c.y(), c.z()}},
                              {"key", {key.x, key.y, key.z}},
                              {"entries", entries}}
                   .dump()
            << "\n";
}

void printHistory(const Eigen::Vector3d& c, const VoxelKey& key, const std::vector<HistoryEntry>& history,
                  size_t sessions) {
  std::cout << "voxel at (" << c.transpose() << ") m, key (" << key.x << ", " << key.y << ", " << key.z << ")\n";
  if (history.empty()) {
    std::cout << "  never observed in " << sessions << " session(s)\n";
    return;
  }
  for (const auto& e : history) {
    const Rgb rgb = e.counters.meanColour();
    std::cout << "  " << formatTime(e.time_s) << "  " << std::setw(8) << std::left << toString(e.counters.state())
              << std::right << " P=" << std::fixed << std::setprecision(3) << e.counters.probability()
              << std::defaultfloat << "  hits=" << e.counters.hits;
    if (e.counters.hits) std::cout << "  colour=(" << int(rgb.r) << "," << int(rgb.g) << "," << int(rgb.b) << ")";
    if (e.level > 0) std::cout << "  (uniform cube of " << (1 << e.level) << "^3 voxels)";
    std::cout << "\n";
  }
  std::cout << "  " << history.size() << " entr" << (history.size() == 1 ? "y" : "ies") << " in " << sessions
            << " session(s); unchanged observations are not stored\n";
}

int runHistory(const HistoryCmdOptions& o) {
  const Eigen::Vector3d p = parsePoint(o.point);
  const VoxelHistory h = historyOfMap(o.map, p, tileCacheSettings(o.memory_limit_gib));
  if (o.json) {
    printHistoryJson(p, h.center_m, h.key, h.entries);
  } else {
    printHistory(h.center_m, h.key, h.entries, h.sessions);
  }
  return 0;
}

// ------------------------------------------------------------------------------------------
// changes

struct ChangesCmdOptions {
  std::string map;
  std::string from;
  std::string to;
  uint32_t min = 1;
  std::string output;
  bool json = false;
};

void printChanges(const ChangesCmdOptions& o, const ChangeFrequency& f, size_t sessions) {
  const std::vector<uint64_t>& histogram = f.histogram;
  if (o.json) {
    nlohmann::json hist = nlohmann::json::object();
    for (size_t n = 1; n < histogram.size(); ++n) {
      if (histogram[n]) hist[std::to_string(n)] = histogram[n];
    }
    std::cout << nlohmann::json{{"min", o.min},       {"voxels", f.voxels.size()}, {"max_changes", f.max_count},
                                {"histogram", hist}, {"output", o.output}}
                     .dump()
              << "\n";
    return;
  }
  std::cout << f.voxels.size() << " voxel(s) changed at least " << o.min << " time(s)";
  if (!f.voxels.empty()) std::cout << " (at most " << f.max_count << ")";
  std::cout << " in " << sessions << " session(s)\n";
  for (size_t n = 1; n < histogram.size(); ++n) {
    if (histogram[n]) std::cout << "  " << std::setw(3) << n << " change(s): " << histogram[n] << " voxel(s)\n";
  }
  if (!o.output.empty()) std::cout << "wrote " << o.output << " (voxel centres coloured blue = few to red = many)\n";
}

int runChanges(const ChangesCmdOptions& o) {
  if (!o.output.empty()) {
    requireExtension(o.output, ".ply", "output");
    refuseOverwritingInputs(o.output, {o.map});
  }
  if (o.min < 1) throw UsageError("--min must be at least 1");
  const TemporalMap map = readTemporalMap(o.map);
  const double t0 = o.from.empty() ? -std::numeric_limits<double>::infinity() : parseTime(o.from);
  const double t1 = o.to.empty() ? std::numeric_limits<double>::infinity() : parseTime(o.to);
  if (t1 < t0) throw UsageError("--to lies before --from");
  const ChangeFrequency f = changeFrequency(map, t0, t1, o.min);
  if (!o.output.empty()) writeChangeFrequencyPly(o.output, map, f, o.min);
  printChanges(o, f, map.sessionCount());
  return 0;
}

}  // namespace

Command addSnapshot(CLI::App& root) {
  auto o = std::make_shared<SnapshotCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "snapshot",
      "The map as most recently observed at a time: every voxel carries its latest state at or before "
      "--at. Output by extension: .cmap (a session map), .ply (occupied voxels), .ot (OctoMap), .png (top view).");
  app->add_option("MAP", o->map, "the 4D map (.cmap) or a tiled map folder (chronomap tile)")->required();
  app->add_option("--at", o->at, "time: ISO-8601 or seconds since the epoch")->required();
  app->add_option("-o,--output", o->output, "file to write (.cmap, .ply, .ot or .png)")->required();
  app->add_option("--box", o->box,
                  "tiled maps: X0,Y0,Z0,X1,Y1,Z1 in metres; only the tiles that meet the box are read and written");
  app->add_option("--memory-limit", o->memory_limit_gib, kTileMemoryHelp)->check(numberIn(0, 1e6));
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runSnapshot(*o); }};
}

Command addHistory(CLI::App& root) {
  auto o = std::make_shared<HistoryCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "history", "Every stored state of the voxel that contains a point: time, state, probability, colour.");
  app->add_option("MAP", o->map, "the 4D map (.cmap) or a tiled map folder (one tile is read)")->required();
  app->add_option("--point", o->point, "X,Y,Z in metres, map frame")->required();
  app->add_option("--memory-limit", o->memory_limit_gib, kTileMemoryHelp)->check(numberIn(0, 1e6));
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runHistory(*o); }};
}

Command addChanges(CLI::App& root) {
  auto o = std::make_shared<ChangesCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "changes",
      "Voxels whose state changed at least --min times in (--from, --to], with a histogram of change "
      "counts; -o writes them as a PLY coloured by count (the thesis' Figure 6b: --min 7 for 'more than 6').");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("--from", o->from, "count changes after this time (default: the beginning)");
  app->add_option("--to", o->to, "count changes up to this time (default: the end)");
  app->add_option("--min", o->min, "least number of changes a voxel needs")->capture_default_str();
  app->add_option("-o,--output", o->output, "PLY of the voxel centres to write");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runChanges(*o); }};
}

}  // namespace chronomap::cli
