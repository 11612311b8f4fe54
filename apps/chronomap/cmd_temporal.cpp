// chronomap add | build | snapshot | history | changes: the 4D map on the command line.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <numbers>
#include <iostream>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/align/register.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/io/cloud_io.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/export.h"
#include "chronomap/io/file.h"
#include "chronomap/io/temporal_file.h"
#include "commands.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

void requireExtension(const std::string& path, const std::string& ext, const std::string& what) {
  if (fs::path(path).extension() != ext) throw UsageError(what + " '" + path + "' must end in " + ext);
}

/// Opens the 4D map at `path`, or a new one when the file does not exist.
TemporalMap openOrCreate(const std::string& path, double resolution_m, const ChangeCriterion& criterion,
                         bool& created, io::TemporalFileLayout* layout = nullptr) {
  created = !fs::exists(path);
  if (created) return TemporalMap(resolution_m, criterion);
  TemporalMap map = io::readTemporalMap(path, layout);
  if (map.resolution_m() != resolution_m) {
    throw UsageError(path + ": the 4D map has resolution " + std::to_string(map.resolution_m()) +
                     " m but the session has " + std::to_string(resolution_m) + " m");
  }
  return map;
}

nlohmann::json addReportJson(const AddReport& r, double time_s, int64_t nodes_added) {
  return {{"time", formatTime(time_s)},      {"time_s", time_s},           {"entries_added", r.entries_added},
          {"entries_removed", r.entries_removed}, {"inner_added", r.inner_added}, {"nodes_added", nodes_added},
          {"replaced", r.replaced},          {"out_of_order", r.out_of_order}};
}

int64_t nodesAddedAt(const TemporalMap& map, double time_s) {
  for (const auto& s : map.sessions()) {
    if (s.time_s == time_s) return s.nodes_added;
  }
  return 0;
}

/// --realign and its settings, shared by add and build.
struct RealignOptions {
  bool enabled = false;
  RealignSettings settings;
  std::string move = "transfer";
};

void addRealignOptions(CLI::App* app, RealignOptions& o) {
  app->add_flag("--realign", o.enabled,
                "re-align each session against the consensus map first (thesis §2.2): voxel data that "
                "localisation error put a voxel away from where the other sessions saw it is moved back, "
                "so it is not stored as change (docs/realign.md)");
  app->add_option("--realign-alpha", o.settings.alpha, "least score of a move")->capture_default_str();
  app->add_option("--realign-max-distance", o.settings.max_distance_voxels,
                  "farthest move in voxels (d_max, at most 8)")
      ->capture_default_str();
  app->add_option("--realign-move", o.move,
                  "transfer: the data goes to the new place and the old one becomes unobserved; swap: the two "
                  "places exchange their contents")
      ->check(CLI::IsMember({"transfer", "swap"}))
      ->capture_default_str();
}

RealignSettings realignSettings(const RealignOptions& o) {
  RealignSettings s = o.settings;
  s.move = o.move == "swap" ? RealignSettings::Move::Swap : RealignSettings::Move::Transfer;
  s.validate();
  return s;
}

// ------------------------------------------------------------------------------------------
// add

struct AddCmdOptions {
  std::string map;
  std::string session;
  std::string time;
  bool replace = false;
  std::string write = "auto";
  ChangeCriterion criterion;
  RealignOptions realign;
  bool json = false;
};

int runAdd(const AddCmdOptions& o) {
  requireExtension(o.map, ".cmap", "4D map");
  const RealignSettings realign_settings = realignSettings(o.realign);
  const io::CmapFile file = io::readCmap(o.session);
  SessionMap session = io::sessionMapFrom(file, o.session);
  double time_s = 0.0;
  if (!o.time.empty()) {
    time_s = parseTime(o.time);
  } else {
    const nlohmann::json meta = io::metadataOf(file);
    if (!meta.contains("recorded_at") || !meta["recorded_at"].is_number()) {
      throw UsageError(o.session + " does not say when it was recorded; give --time");
    }
    time_s = meta["recorded_at"].get<double>();
  }
  // One add at a time per map: a second one waits here, then reads what the first wrote.
  std::optional<io::FileLock> lock;
  if (fs::exists(o.map)) lock.emplace(o.map);
  bool created = false;
  io::TemporalFileLayout layout;
  TemporalMap map = openOrCreate(o.map, session.resolution_m(), o.criterion, created, &layout);
  std::optional<RealignReport> realigned;
  if (o.realign.enabled) {
    // The consensus of every session stored so far (each time's snapshot) and this one.
    SessionMap avg = map.sessionCount() ? consensus(map, map.sessions().front().time_s, map.sessions().back().time_s)
                                        : SessionMap(session.resolution_m());
    avg.merge(session);
    realigned.emplace();
    session = realign(session, avg, realign_settings, &*realigned);
  }
  const AddOptions add_options{o.replace, fs::path(o.session).filename().string()};
  const AddReport report = map.add(time_s, session, add_options);
  // Append the session as a record (the file's bytes so far stay as they are), or write the whole
  // map again, folding earlier records in: "auto" appends while the records stay smaller than the
  // base, so that reading never replays more than the base holds.
  const std::vector<uint8_t> record = created ? std::vector<uint8_t>{} : io::encodeSessionRecord(time_s, session, add_options);
  const bool append = !created && (o.write == "append" ||
                                   (o.write == "auto" && layout.appended_bytes + record.size() <= layout.base_bytes));
  if (append) {
    io::appendToFile(o.map, layout.completeBytes(), record);
  } else {
    io::writeTemporalMap(o.map, map, {});
  }
  const int64_t added = nodesAddedAt(map, time_s);
  if (o.json) {
    nlohmann::json j = addReportJson(report, time_s, added);
    if (realigned) j["realigned_voxels"] = realigned->moved();
    j["map"] = o.map;
    j["created"] = created;
    j["appended"] = append;
    j["sessions"] = map.sessionCount();
    j["nodes"] = map.counts().nodes();
    j["file_bytes"] = fs::file_size(o.map);
    std::cout << j.dump() << "\n";
  } else {
    std::cout << (created ? "created " : "updated ") << o.map << ": session " << formatTime(time_s)
              << (report.replaced ? " replaced" : " added") << (report.out_of_order ? " (before later sessions)" : "")
              << ", " << added << " nodes added (" << report.entries_added << " entries, " << report.inner_added
              << " inner nodes); " << map.sessionCount() << " session(s), " << map.counts().nodes() << " nodes, "
              << humanBytes(static_cast<double>(fs::file_size(o.map))) << " on disk ("
              << (append ? "appended " + humanBytes(static_cast<double>(record.size())) : std::string("written whole"))
              << ")\n";
    if (realigned) std::cout << "re-aligned: " << realigned->moved() << " voxel(s) moved\n";
  }
  return 0;
}

void addCriterionOptions(CLI::App* app, ChangeCriterion& c) {
  app->add_option("--probability-threshold", c.probability_threshold,
                  "new map only: also store a change when P moves by more than this (0 = state only)")
      ->capture_default_str();
  app->add_option("--color-distance", c.color_distance,
                  "new map only: also store a change when the mean colour moves farther than this "
                  "(8-bit RGB units; 0 = off)")
      ->capture_default_str();
}

// ------------------------------------------------------------------------------------------
// build

struct BuildCmdOptions {
  std::string map;
  std::vector<std::string> datasets;
  std::string times;
  bool replace = false;
  ChangeCriterion criterion;
  IntegrateSettings integrate;
  RealignOptions realign;
  bool register_sessions = false;
  int register_rounds = 3;
  std::string register_model = "world";
  int register_drift = 0;
  double register_radius = RegisterSettings{}.radius_voxels;
  bool register_planar = false;
  bool register_points = false;
  bool json = false;
};

std::vector<std::string> splitCommas(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

int runBuild(const BuildCmdOptions& o) {
  requireExtension(o.map, ".cmap", "4D map");
  const RealignSettings realign_settings = realignSettings(o.realign);  // bad settings fail before integrating
  if (o.register_rounds < 1 || o.register_rounds > 10) throw UsageError("--register-rounds must lie in [1, 10]");
  RegisterSettings register_settings;
  if (o.register_model == "world") {
    register_settings.model = CorrectionModel::World;
  } else if (o.register_model == "per-pose") {
    register_settings.model = CorrectionModel::PerPose;
  } else {
    throw UsageError("--register-model must be world or per-pose, not '" + o.register_model + "'");
  }
  if (o.register_drift < 0 || o.register_drift > 100000) {
    throw UsageError("--register-drift must be a number of frames in [0, 100000] (0: no drift correction)");
  }
  if (o.register_drift > 0 && !o.register_sessions) throw UsageError("--register-drift needs --register");
  register_settings.drift_knot_frames = o.register_drift;
  if (!(o.register_radius >= 1.0 && o.register_radius <= 8.0)) {
    throw UsageError("--register-radius must lie in [1, 8] voxels");
  }
  if (o.register_radius != RegisterSettings{}.radius_voxels && !o.register_sessions) {
    throw UsageError("--register-radius needs --register");
  }
  register_settings.radius_voxels = o.register_radius;
  if (o.register_planar && !o.register_sessions) throw UsageError("--register-planar needs --register");
  if (o.register_points && o.register_drift <= 0) throw UsageError("--register-points needs --register-drift");
  register_settings.planar = o.register_planar;
  register_settings.drift_points = o.register_points;
  for (const auto& d : o.datasets) {
    if (!fs::exists(d)) throw UsageError("dataset '" + d + "' does not exist");
  }
  std::vector<std::optional<double>> times(o.datasets.size());
  if (!o.times.empty()) {
    const auto parts = splitCommas(o.times);
    if (parts.size() != o.datasets.size()) {
      throw UsageError("--times lists " + std::to_string(parts.size()) + " time(s) for " +
                       std::to_string(o.datasets.size()) + " dataset(s)");
    }
    for (size_t i = 0; i < parts.size(); ++i) times[i] = parseTime(parts[i]);
  }
  // Held to the end: an add to the same map meanwhile would otherwise be lost by the rewrite.
  std::optional<io::FileLock> lock;
  if (fs::exists(o.map)) lock.emplace(o.map);
  bool created = false;
  TemporalMap map = openOrCreate(o.map, o.integrate.resolution_m, o.criterion, created);
  // Refuse known clashes before the long integration.
  for (size_t i = 0; i < times.size(); ++i) {
    if (!times[i] || o.replace) continue;
    for (const auto& s : map.sessions()) {
      if (s.time_s == *times[i]) {
        throw UsageError(o.map + " already holds a session at " + formatTime(s.time_s) + " (given for " +
                         o.datasets[i] + "); use --replace or another time");
      }
    }
  }
  // Integrate first (times may come from the datasets), then add in time order.
  struct Pending {
    size_t index;
    double time_s;
    IntegratedSession session;
  };
  std::vector<Pending> pending;
  for (size_t i = 0; i < o.datasets.size(); ++i) {
    if (!o.json) std::cerr << "[" << i + 1 << "/" << o.datasets.size() << "] " << o.datasets[i] << "\n";
    IntegratedSession s = integrateDataset(o.datasets[i], o.integrate, "integrating");
    const std::optional<double> t = times[i] ? times[i] : s.recorded_at;
    if (!t) {
      throw UsageError(o.datasets[i] + " has no timestamps (" + s.format +
                       " datasets do not carry times); give one per dataset with --times");
    }
    pending.push_back({i, *t, std::move(s)});
  }
  std::stable_sort(pending.begin(), pending.end(), [](const Pending& a, const Pending& b) { return a.time_s < b.time_s; });
  for (size_t i = 1; i < pending.size(); ++i) {
    if (pending[i].time_s == pending[i - 1].time_s) {
      throw UsageError(o.datasets[pending[i - 1].index] + " and " + o.datasets[pending[i].index] +
                       " have the same time " + formatTime(pending[i].time_s));
    }
  }
  // Registration: each session's rigid correction against the consensus of all given, then
  // integrated again with it.
  std::vector<std::optional<PoseCorrection>> corrections(pending.size());
  if (o.register_sessions) {
    std::vector<SessionMap> maps;
    maps.reserve(pending.size());
    for (Pending& p : pending) maps.push_back(std::move(p.session.map));
    if (!o.json) std::cerr << "registering " << maps.size() << " session(s), " << o.register_rounds << " round(s)\n";
    std::vector<std::vector<Eigen::Vector3d>> positions;
    std::vector<std::string> paths;
    for (const Pending& p : pending) {
      positions.push_back(p.session.sensor_positions);
      paths.push_back(o.datasets[p.index]);
    }
    const auto found = registerDatasets(maps, paths, positions, o.integrate, o.register_rounds, register_settings);
    for (size_t i = 0; i < pending.size(); ++i) {
      pending[i].session.map = std::move(maps[i]);
      corrections[i] = found[i];
    }
  }
  // Re-alignment against the consensus of every session given (taken before any is replaced).
  std::vector<std::optional<size_t>> moved(pending.size());
  if (o.realign.enabled) {
    std::vector<const SessionMap*> all;
    all.reserve(pending.size());
    for (const Pending& p : pending) all.push_back(&p.session.map);
    const SessionMap avg = consensus(std::span<const SessionMap* const>(all));
    for (size_t i = 0; i < pending.size(); ++i) {
      if (!o.json) std::cerr << "re-aligning " << o.datasets[pending[i].index] << "\n";
      RealignReport r;
      pending[i].session.map = realign(pending[i].session.map, avg, realign_settings, &r);
      moved[i] = r.moved();
    }
  }
  nlohmann::json reports = nlohmann::json::array();
  for (size_t i = 0; i < pending.size(); ++i) {
    const Pending& p = pending[i];
    const AddReport r =
        map.add(p.time_s, p.session.map, AddOptions{o.replace, fs::path(o.datasets[p.index]).filename().string()});
    nlohmann::json j = addReportJson(r, p.time_s, nodesAddedAt(map, p.time_s));
    if (moved[i]) j["realigned_voxels"] = *moved[i];
    if (corrections[i]) {
      const Eigen::Isometry3d& c = corrections[i]->motion;
      j["registration_m"] = {c.translation().x(), c.translation().y(), c.translation().z()};
      j["registration_deg"] = Eigen::AngleAxisd(c.linear()).angle() * 180.0 / std::numbers::pi;
      j["registration_model"] = o.register_model;
      if (!corrections[i]->per_frame.empty()) {
        double largest = 0.0;
        for (const auto& f : corrections[i]->per_frame) largest = std::max(largest, f.translation().norm());
        j["drift_correction_max_m"] = largest;
      }
    }
    j["dataset"] = o.datasets[p.index];
    j["points"] = p.session.stats.points;
    j["nodes_separate"] = p.session.map.innerCount() + p.session.map.leafCount();
    reports.push_back(j);
  }
  // One atomic write at the end: a crash leaves the previous map (or none) on disk.
  io::writeTemporalMap(o.map, map, {});
  const auto file_bytes = fs::file_size(o.map);
  if (o.json) {
    std::cout << nlohmann::json{{"map", o.map},
                                {"created", created},
                                {"sessions", map.sessionCount()},
                                {"nodes", map.counts().nodes()},
                                {"file_bytes", file_bytes},
                                {"added", reports}}
                     .dump()
              << "\n";
  } else {
    for (const auto& r : reports) {
      std::cout << "  " << r["time"].get<std::string>() << "  " << r["dataset"].get<std::string>() << ": "
                << r["nodes_added"].get<int64_t>() << " nodes added (" << r["nodes_separate"].get<uint64_t>()
                << " on its own)";
      if (r.contains("registration_m")) {
        const auto& t = r["registration_m"];
        std::cout << ", moved by (" << std::fixed << std::setprecision(3) << t[0].get<double>() << ", "
                  << t[1].get<double>() << ", " << t[2].get<double>() << ") m, " << std::setprecision(2)
                  << r["registration_deg"].get<double>() << " deg" << std::defaultfloat;
      }
      if (r.contains("realigned_voxels")) std::cout << ", " << r["realigned_voxels"].get<size_t>() << " voxels re-aligned";
      std::cout << "\n";
    }
    std::cout << (created ? "created " : "updated ") << o.map << ": " << map.sessionCount() << " session(s), "
              << map.counts().nodes() << " nodes, " << humanBytes(static_cast<double>(file_bytes)) << " on disk\n";
  }
  return 0;
}

// ------------------------------------------------------------------------------------------
// snapshot

struct SnapshotCmdOptions {
  std::string map;
  std::string at;
  std::string output;
  bool json = false;
};

int runSnapshot(const SnapshotCmdOptions& o) {
  const std::string ext = fs::path(o.output).extension().string();
  if (ext != ".cmap" && ext != ".ply" && ext != ".ot" && ext != ".png") {
    throw UsageError("output '" + o.output + "' must end in .cmap, .ply, .ot or .png");
  }
  const double t = parseTime(o.at);
  const TemporalMap map = io::readTemporalMap(o.map);
  if (map.sessionCount() == 0 || t < map.sessions().front().time_s) {
    throw UsageError(o.map + " holds no session at or before " + formatTime(t) +
                     (map.sessionCount() ? " (the first is at " + formatTime(map.sessions().front().time_s) + ")" : ""));
  }
  const SessionMap snap = map.snapshot(t);
  size_t n = 0;
  if (ext == ".cmap") {
    io::writeSessionMap(o.output, snap, {{"created_by", "chronomap snapshot"}, {"snapshot_of", o.map}, {"time_s", t}});
    n = snap.leafCount();
  } else if (ext == ".ply") {
    n = io::exportOccupiedPly(o.output, snap);
  } else if (ext == ".ot") {
    n = io::exportOctomap(o.output, snap);
  } else {
    const io::ImageRgb img = io::renderTopView(snap);
    io::writePng(o.output, img);
    n = size_t{img.width} * img.height;
  }
  const SessionMapCounts c = snap.counts();
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output},   {"time", formatTime(t)},       {"time_s", t},
                                {"occupied", c.occupied_voxels}, {"free", c.free_voxels}, {"elements", n}}
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
  bool json = false;
};

Eigen::Vector3d parsePoint(const std::string& text) {
  const auto parts = splitCommas(text);
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

int runHistory(const HistoryCmdOptions& o) {
  const Eigen::Vector3d p = parsePoint(o.point);
  const TemporalMap map = io::readTemporalMap(o.map);
  const auto key = map.grid().keyOf(p);
  if (!key) throw UsageError("point " + o.point + " lies outside the map");
  const auto history = map.history(*key);
  const Eigen::Vector3d c = map.grid().centerOf(*key);
  if (o.json) {
    nlohmann::json entries = nlohmann::json::array();
    for (const auto& e : history) {
      const Rgb rgb = e.counters.meanColor();
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
                                {"key", {key->x, key->y, key->z}},
                                {"entries", entries}}
                     .dump()
              << "\n";
    return 0;
  }
  std::cout << "voxel at (" << c.transpose() << ") m, key (" << key->x << ", " << key->y << ", " << key->z << ")\n";
  if (history.empty()) {
    std::cout << "  never observed in " << map.sessionCount() << " session(s)\n";
    return 0;
  }
  for (const auto& e : history) {
    const Rgb rgb = e.counters.meanColor();
    std::cout << "  " << formatTime(e.time_s) << "  " << std::setw(8) << std::left << toString(e.counters.state())
              << std::right << " P=" << std::fixed << std::setprecision(3) << e.counters.probability()
              << std::defaultfloat << "  hits=" << e.counters.hits;
    if (e.counters.hits) std::cout << "  colour=(" << int(rgb.r) << "," << int(rgb.g) << "," << int(rgb.b) << ")";
    if (e.level > 0) std::cout << "  (uniform cube of " << (1 << e.level) << "^3 voxels)";
    std::cout << "\n";
  }
  std::cout << "  " << history.size() << " entr" << (history.size() == 1 ? "y" : "ies") << " in "
            << map.sessionCount() << " session(s); unchanged observations are not stored\n";
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

// Blue (few changes) to red (many) for a count in [min, max].
Rgb heat(uint32_t n, uint32_t lo, uint32_t hi) {
  const double t = hi > lo ? static_cast<double>(n - lo) / static_cast<double>(hi - lo) : 1.0;
  auto channel = [](double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); };
  return {channel(1.5 * t), channel(1.0 - 2.0 * std::abs(t - 0.5)), channel(1.5 * (1.0 - t))};
}

int runChanges(const ChangesCmdOptions& o) {
  if (!o.output.empty()) requireExtension(o.output, ".ply", "output");
  if (o.min < 1) throw UsageError("--min must be at least 1");
  const TemporalMap map = io::readTemporalMap(o.map);
  const double t0 = o.from.empty() ? -std::numeric_limits<double>::infinity() : parseTime(o.from);
  const double t1 = o.to.empty() ? std::numeric_limits<double>::infinity() : parseTime(o.to);
  if (t1 < t0) throw UsageError("--to lies before --from");
  struct Changed {
    VoxelKey key;
    uint32_t count;
  };
  std::vector<Changed> changed;
  std::vector<uint64_t> histogram;
  map.forEachChangeCount(t0, t1, [&](const VoxelKey& k, int level, uint32_t n) {
    const uint64_t voxels = uint64_t{1} << (3 * level);
    if (histogram.size() <= n) histogram.resize(n + 1, 0);
    histogram[n] += voxels;
    if (n < o.min) return;
    const int side = 1 << level;
    for (int dz = 0; dz < side; ++dz) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dx = 0; dx < side; ++dx) {
          changed.push_back({VoxelKey{static_cast<uint16_t>(k.x + dx), static_cast<uint16_t>(k.y + dy),
                                      static_cast<uint16_t>(k.z + dz)},
                             n});
        }
      }
    }
  });
  uint32_t max_count = 0;
  for (const auto& c : changed) max_count = std::max(max_count, c.count);
  if (!o.output.empty()) {
    PointCloud cloud;
    cloud.points.reserve(changed.size());
    cloud.colors.reserve(changed.size());
    for (const auto& c : changed) {
      cloud.points.push_back(map.grid().centerOf(c.key).cast<float>());
      cloud.colors.push_back(heat(c.count, o.min, max_count));
    }
    cloud.width = static_cast<uint32_t>(cloud.points.size());
    io::writePly(o.output, cloud);
  }
  if (o.json) {
    nlohmann::json hist = nlohmann::json::object();
    for (size_t n = 1; n < histogram.size(); ++n) {
      if (histogram[n]) hist[std::to_string(n)] = histogram[n];
    }
    std::cout << nlohmann::json{{"min", o.min},
                                {"voxels", changed.size()},
                                {"max_changes", max_count},
                                {"histogram", hist},
                                {"output", o.output}}
                     .dump()
              << "\n";
  } else {
    std::cout << changed.size() << " voxel(s) changed at least " << o.min << " time(s)";
    if (!changed.empty()) std::cout << " (at most " << max_count << ")";
    std::cout << " in " << map.sessionCount() << " session(s)\n";
    for (size_t n = 1; n < histogram.size(); ++n) {
      if (histogram[n]) std::cout << "  " << std::setw(3) << n << " change(s): " << histogram[n] << " voxel(s)\n";
    }
    if (!o.output.empty()) std::cout << "wrote " << o.output << " (voxel centres coloured blue = few to red = many)\n";
  }
  return 0;
}

}  // namespace

Command addAdd(CLI::App& root) {
  auto o = std::make_shared<AddCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "add",
      "Add a session map to a 4D map (created when missing). Only voxels the session observed and whose "
      "state changed are stored; adding a session older than stored ones is allowed.");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("SESSION", o->session, "a session map from chronomap integrate (.cmap)")->required();
  app->add_option("--time", o->time,
                  "when the session was recorded: ISO-8601 (2012-03-01T10:00:00Z) or seconds since the epoch; "
                  "default: the time the session file records");
  app->add_flag("--replace", o->replace, "replace a session stored at the same time instead of refusing");
  app->add_option("--write", o->write,
                  "append: add the session at the end of the file, leaving the bytes before it untouched; rewrite: "
                  "write the whole map again (folding appended sessions in); auto: append while the appended "
                  "sessions take fewer bytes than the rest of the file")
      ->check(CLI::IsMember({"auto", "append", "rewrite"}))
      ->capture_default_str();
  addCriterionOptions(app, o->criterion);
  addRealignOptions(app, o->realign);
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runAdd(*o); }};
}

Command addBuild(CLI::App& root) {
  auto o = std::make_shared<BuildCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "build",
      "Integrate several recordings and add them to a 4D map in time order (the map is created when "
      "missing and written once, atomically, at the end).");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("DATASET", o->datasets, "dataset folders or files, one per session")->required();
  app->add_option("--times", o->times,
                  "comma-separated times, one per dataset (ISO-8601 or epoch seconds); default: the datasets' "
                  "first timestamps (TUM)");
  app->add_flag("--replace", o->replace, "replace sessions stored at the same times");
  addCriterionOptions(app, o->criterion);
  addIntegrateOptions(app, o->integrate);
  app->add_flag("--register", o->register_sessions,
                "register each session to the consensus of all given and integrate it again with the "
                "correction (removes the part of the localisation error that is one offset per session; "
                "docs/realign.md)");
  app->add_option("--register-model", o->register_model,
                  "what a correction is: world (one rigid motion of the session's map frame) or per-pose (the same "
                  "position and heading offset of every pose, turned about each pose; docs/realign.md compares them)")
      ->capture_default_str();
  app->add_option("--register-drift", o->register_drift,
                  "after the rigid rounds, also correct each session's drift: every frame gets its own position and "
                  "heading correction, linear between knots this many frames apart (0: none; docs/realign.md)")
      ->capture_default_str();
  app->add_option("--register-rounds", o->register_rounds,
                  "registration rounds, each against the consensus the previous one left")
      ->capture_default_str();
  app->add_option("--register-radius", o->register_radius,
                  "how far (voxels) each surface voxel looks for the consensus' surfaces; smaller resolves finer "
                  "offsets once sessions lie close (docs/changes.md has the office figures)")
      ->capture_default_str();
  app->add_flag("--register-planar", o->register_planar,
                "correct x, y and heading only, never the height: the error of a robot's 2D localisation "
                "(docs/realign.md)");
  app->add_flag("--register-points", o->register_points,
                "fit the drift against the sessions' points rather than voxel centres, which resolves offsets "
                "below a voxel (docs/realign.md has the office figures)");
  addRealignOptions(app, o->realign);
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runBuild(*o); }};
}

Command addSnapshot(CLI::App& root) {
  auto o = std::make_shared<SnapshotCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "snapshot",
      "The map as most recently observed at a time: every voxel carries its latest state at or before "
      "--at. Output by extension: .cmap (a session map), .ply (occupied voxels), .ot (OctoMap), .png (top view).");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("--at", o->at, "time: ISO-8601 or seconds since the epoch")->required();
  app->add_option("-o,--output", o->output, "file to write (.cmap, .ply, .ot or .png)")->required();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runSnapshot(*o); }};
}

Command addHistory(CLI::App& root) {
  auto o = std::make_shared<HistoryCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "history", "Every stored state of the voxel that contains a point: time, state, probability, colour.");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("--point", o->point, "X,Y,Z in metres, map frame")->required();
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
