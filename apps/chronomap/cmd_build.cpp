// chronomap add | build: sessions into a 4D map.

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <numbers>
#include <sstream>
#include <nlohmann/json.hpp>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"
#include "chronomap/pipeline/distributed.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/pipeline/stream.h"
#include "chronomap/pipeline/tiles.h"
#include "commands.h"
#include "progress.h"

namespace chronomap::cli {

namespace {

/// --realign and its settings, shared by add and build.
struct RealignFlags {
  bool enabled = false;
  RealignSettings settings;
  std::string move = "transfer";
};

void addRealignFlags(CLI::App* app, RealignFlags& f) {
  app->add_flag("--realign", f.enabled,
                "re-align each session against the consensus map first (thesis §2.2): voxel data that "
                "localisation error put a voxel away from where the other sessions saw it is moved back, "
                "so it is not stored as change (docs/realign.md)");
  app->add_option("--realign-alpha", f.settings.alpha, "least score of a move")->capture_default_str();
  app->add_option("--realign-max-distance", f.settings.max_distance_voxels,
                  "farthest move in voxels (d_max, at most 8)")
      ->capture_default_str();
  app->add_option("--realign-move", f.move,
                  "transfer: the data goes to the new place and the old one becomes unobserved; swap: the two "
                  "places exchange their contents")
      ->check(CLI::IsMember({"transfer", "swap"}))
      ->capture_default_str();
}

/// The re-alignment the flags ask for, validated even when not enabled (bad values fail early).
std::optional<RealignSettings> realignSettings(const RealignFlags& f) {
  RealignSettings s = f.settings;
  s.move = f.move == "swap" ? RealignSettings::Move::Swap : RealignSettings::Move::Transfer;
  s.validate();
  if (!f.enabled) return std::nullopt;
  return s;
}

void addCriterionFlags(CLI::App* app, ChangeCriterion& c) {
  app->add_option("--probability-threshold", c.probability_threshold,
                  "new map only: also store a change when P moves by more than this (0 = state only)")
      ->capture_default_str();
  app->add_option("--color-distance,--colour-distance", c.colour_distance,
                  "new map only: also store a change when the mean colour moves farther than this "
                  "(8-bit RGB units; 0 = off)")
      ->capture_default_str();
  app->add_option("--surface-shift", c.surface_shift_voxels,
                  "new map only: also store a change when the hits in an occupied voxel moved farther than this "
                  "(voxels; 0 = off): what the diff's shift test reads")
      ->capture_default_str();
  app->add_option("--min-free-length", c.min_free_length_m,
                  "new map only: a free observation with less ray length than this through a voxel (metres; "
                  "a grazing ray, no hit) does not end its occupied state (0 = off; docs/temporal.md)")
      ->capture_default_str();
  app->add_option("--min-hits", c.min_hits,
                  "new map only: an occupied observation with fewer hits does not end a free state, and the "
                  "surface-shift test needs this many hits on both sides (0 = off; docs/temporal.md)")
      ->capture_default_str();
}

nlohmann::json addReportJson(const AddReport& r, double time_s, int64_t nodes_added) {
  return {{"time", formatTime(time_s)},           {"time_s", time_s},           {"entries_added", r.entries_added},
          {"entries_removed", r.entries_removed}, {"inner_added", r.inner_added}, {"nodes_added", nodes_added},
          {"replaced", r.replaced},               {"out_of_order", r.out_of_order}};
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
  RealignFlags realign;
  std::optional<double> memory_limit_gib;  ///< a tiled map: the streaming build's parts budget
  std::optional<int> threads;              ///< a tiled map: groups of tiles at once
  bool json = false;
};

void printAdded(const AddCmdOptions& o, const AddSessionResult& r) {
  if (o.json) {
    nlohmann::json j = addReportJson(r.report, r.time_s, r.nodes_added);
    if (r.realigned_voxels) j["realigned_voxels"] = *r.realigned_voxels;
    j["map"] = o.map;
    j["created"] = r.created;
    j["appended"] = r.appended;
    j["sessions"] = r.sessions;
    j["nodes"] = r.nodes;
    j["file_bytes"] = r.file_bytes;
    std::cout << j.dump() << "\n";
    return;
  }
  std::cout << (r.created ? "created " : "updated ") << o.map << ": session " << formatTime(r.time_s)
            << (r.report.replaced ? " replaced" : " added") << (r.report.out_of_order ? " (before later sessions)" : "")
            << ", " << r.nodes_added << " nodes added (" << r.report.entries_added << " entries, "
            << r.report.inner_added << " inner nodes); " << r.sessions << " session(s), " << r.nodes << " nodes, "
            << humanBytes(static_cast<double>(r.file_bytes)) << " on disk ("
            << (r.appended ? "appended " + humanBytes(static_cast<double>(r.record_bytes)) : std::string("written whole"))
            << ")\n";
  if (r.realigned_voxels) std::cout << "re-aligned: " << *r.realigned_voxels << " voxel(s) moved\n";
}

/// The streaming build's budget for session parts: --memory-limit, else 256 MiB.
constexpr double kDefaultPartsGib = 0.25;

/// The streaming build decodes and encodes one tile after another on each thread (a group of
/// tiles per thread), each in buffers of a few MiB.
/// glibc gives every freed block above its mmap threshold back to the kernel, so the next tile
/// faulted the same memory in again, zeroed page by page. Blocks up to 32 MiB now come from the
/// heap, which keeps what is freed (up to 1 GiB) for the next tile: one night added to the
/// one-floor year (365 nights) took 0.61-0.64 s of system time instead of 2.65-3.0 s, 8.8-8.9 s of
/// processor time in all instead of 11.2-11.3 s, peak RSS 348-352 MB instead of 312 MB
/// (docs/scale.md). The process ends after the night, so what the heap keeps goes with it.
void keepFreedMemoryForTheNextTile() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

int runAdd(const AddCmdOptions& o) {
  AddSessionSettings s;
  s.map = o.map;
  s.session = o.session;
  if (!o.time.empty()) s.time_s = parseTime(o.time);
  s.replace = o.replace;
  s.write = parseWritePolicy(o.write);
  s.realign = realignSettings(o.realign);
  if (isTiledMapFolder(o.map)) {
    // A tiled map: the session streamed in tile by tile (docs/scale.md).
    keepFreedMemoryForTheNextTile();
    s.threads = o.threads.value_or(0);
    const StreamResult r =
        streamAddSession(s, gibToBytes(o.memory_limit_gib.value_or(kDefaultPartsGib)));
    const nlohmann::json j = {{"map", o.map},           {"time", formatTime(r.added_times.at(0))},
                              {"time_s", r.added_times.at(0)}, {"nodes_added", r.nodes_added.at(0)},
                              {"sessions", r.sessions}, {"tiles", r.tiles},
                              {"file_bytes", r.index_bytes + r.tile_bytes}};
    if (o.json) {
      std::cout << j.dump() << "\n";
    } else {
      std::cout << "updated " << o.map << ": session " << formatTime(r.added_times.at(0)) << " added, "
                << r.nodes_added.at(0) << " nodes added; " << r.sessions << " session(s), " << r.tiles << " tiles, "
                << humanBytes(static_cast<double>(r.index_bytes + r.tile_bytes)) << " on disk\n";
    }
    return 0;
  }
  requireExtension(o.map, ".cmap", "4D map");
  if (o.memory_limit_gib) throw UsageError("--memory-limit applies to a tiled map folder only");
  if (o.threads) throw UsageError("--threads applies to a tiled map folder only");
  s.criterion = o.criterion;
  printAdded(o, chronomap::addSession(s));
  return 0;
}

// ------------------------------------------------------------------------------------------
// build

struct BuildCmdOptions {
  std::string map;
  std::vector<std::string> datasets;
  std::string times;
  bool replace = false;
  ChangeCriterion criterion;
  IntegrateFlags integrate;
  RealignFlags realign;
  bool register_sessions = false;
  std::optional<std::string> register_preset;
  std::optional<int> register_rounds;         // unset: the preset's (3)
  std::optional<std::string> register_model;  // unset: the preset's (world)
  std::optional<int> register_drift;  // given 0: no drift correction, whatever the preset's
  std::optional<double> register_drift_path;
  std::optional<double> register_radius;  // given or not: the flags that need another say so
  bool register_planar = false;
  bool register_points = false;
  bool register_keep_mean = false;
  std::optional<double> register_drift_yaw;
  std::optional<int> register_drift_rounds;
  std::optional<double> register_fine_radius;
  std::optional<double> register_cache_gib;
  bool tiles = false;
  std::optional<double> tile_size_m;
  std::optional<uint32_t> tile_windows;
  bool windowed_tiles = false;
  bool json = false;
};

/// True when the flags ask for registration: --register or a --register-preset.
bool registering(const BuildCmdOptions& o) { return o.register_sessions || o.register_preset.has_value(); }

/// The drift part of the registration flags (--register-drift and the flags that need it), each
/// given one replacing the preset's setting in `align`.
void setDriftSettings(const BuildCmdOptions& o, RegisterSettings& align) {
  const int knot_frames = o.register_drift.value_or(0);
  if (knot_frames < 0 || knot_frames > 100000) {
    throw UsageError("--register-drift must be a number of frames in [0, 100000] (0: no drift correction)");
  }
  if (knot_frames > 0 && !registering(o)) throw UsageError("--register-drift needs --register");
  if (o.register_drift) {  // replaces the preset's knots, by frames or along the path (0: none)
    align.drift_knot_frames = knot_frames;
    align.drift_knot_m = 0.0;
  }
  if (o.register_drift_path) {
    if (!(*o.register_drift_path > 0.0 && *o.register_drift_path <= 1000.0)) {
      throw UsageError("--register-drift-path must be a distance in (0, 1000] metres");
    }
    if (!registering(o)) throw UsageError("--register-drift-path needs --register");
    if (knot_frames > 0) throw UsageError("--register-drift and --register-drift-path: give one of them");
    align.drift_knot_m = *o.register_drift_path;
    align.drift_knot_frames = 0;
  }
  const bool drift = align.drift();
  if (o.register_drift_yaw) {
    if (!(*o.register_drift_yaw > 0.0 && *o.register_drift_yaw <= 10.0)) {
      throw UsageError("--register-drift-yaw must lie in (0, 10] degrees per frame");
    }
    if (align.drift_knot_frames <= 0) {
      throw UsageError(align.drift_knot_m > 0.0 ? "--register-drift-yaw is per frame, for --register-drift; with "
                                                  "knots along the path the prior is per metre travelled"
                                                : "--register-drift-yaw needs --register-drift");
    }
    align.drift_yaw_per_frame_deg = *o.register_drift_yaw;
  }
  if (o.register_drift_rounds) {
    if (*o.register_drift_rounds < 1 || *o.register_drift_rounds > 10) {
      throw UsageError("--register-drift-rounds must lie in [1, 10]");
    }
    if (!drift) throw UsageError("--register-drift-rounds needs --register-drift or --register-drift-path");
    align.drift_rounds = *o.register_drift_rounds;
  }
  if (o.register_fine_radius) {
    if (!(*o.register_fine_radius >= 1.0 && *o.register_fine_radius <= 8.0)) {
      throw UsageError("--register-fine-radius must lie in [1, 8] voxels");
    }
    if (!drift) throw UsageError("--register-fine-radius needs --register-drift or --register-drift-path");
    align.fine_radius_voxels = *o.register_fine_radius;
  }
}

/// The registration the flags ask for: the preset's (plain --register: no drift, radius 2), each
/// flag given replacing one setting; refuses values out of range and flags without --register.
std::optional<RegistrationSettings> registrationSettings(const BuildCmdOptions& o) {
  RegistrationSettings s = o.register_preset ? registrationNamed(*o.register_preset) : RegistrationSettings{};
  if (o.register_rounds) {
    if (*o.register_rounds < 1 || *o.register_rounds > 10) throw UsageError("--register-rounds must lie in [1, 10]");
    if (!registering(o)) throw UsageError("--register-rounds needs --register");
    s.rounds = *o.register_rounds;
  }
  if (o.register_model) {
    if (!registering(o)) throw UsageError("--register-model needs --register");
    s.align.model = parseCorrectionModel(*o.register_model);
  }
  setDriftSettings(o, s.align);
  if (o.register_radius) {
    if (!(*o.register_radius >= 1.0 && *o.register_radius <= 8.0)) {
      throw UsageError("--register-radius must lie in [1, 8] voxels");
    }
    if (!registering(o)) throw UsageError("--register-radius needs --register");
    s.align.radius_voxels = *o.register_radius;
    // A preset's finer radius never wider than the radius given: then one radius throughout.
    if (!o.register_fine_radius && s.align.fine_radius_voxels > s.align.radius_voxels) s.align.fine_radius_voxels = 0.0;
  }
  if (o.register_planar && !registering(o)) throw UsageError("--register-planar needs --register");
  if (o.register_points && !s.align.drift()) {
    throw UsageError("--register-points needs --register-drift or --register-drift-path");
  }
  s.align.planar = s.align.planar || o.register_planar;
  s.align.drift_points = s.align.drift_points || o.register_points;
  if (o.register_keep_mean && !registering(o)) throw UsageError("--register-keep-mean needs --register");
  s.align.keep_mean = s.align.keep_mean || o.register_keep_mean;
  if (o.register_cache_gib) {
    if (!registering(o)) throw UsageError("--register-cache needs --register");
    s.depth_cache_bytes = gibToBytes(*o.register_cache_gib);
  }
  if (!registering(o)) return std::nullopt;
  s.align.validate();
  return s;
}

/// One time per dataset from --times, or none.
std::vector<std::optional<double>> buildTimes(const BuildCmdOptions& o) {
  if (o.times.empty()) return {};
  const std::vector<std::string> parts = splitCommas(o.times);
  if (parts.size() != o.datasets.size()) {
    throw UsageError("--times lists " + std::to_string(parts.size()) + " time(s) for " +
                     std::to_string(o.datasets.size()) + " dataset(s)");
  }
  std::vector<std::optional<double>> times;
  for (const auto& p : parts) times.emplace_back(parseTime(p));
  return times;
}

/// The registration settings as --json reports them: the preset named (or "none"), then the
/// settings the flags change as they were used (0 or false where they did not apply), so that a
/// preset changed by flags shows what ran.
nlohmann::json registrationJson(const BuildCmdOptions& o, const RegistrationSettings& s) {
  const RegisterSettings& a = s.align;
  return {{"preset", o.register_preset.value_or("none")},
          {"rounds", s.rounds},
          {"model", toString(a.model)},
          {"radius_voxels", a.radius_voxels},
          {"drift_knot_frames", a.drift_knot_frames},
          {"drift_knot_m", a.drift_knot_m},
          {"drift_rounds", a.drift() ? a.drift_rounds : 0},
          {"drift_yaw_per_frame_deg", a.drift_knot_frames > 0 ? a.drift_yaw_per_frame_deg : 0.0},
          {"fine_radius_voxels", a.drift() ? a.fine_radius_voxels : 0.0},
          {"planar", a.planar},
          {"points", a.drift() && a.drift_points},
          {"keep_mean", a.keep_mean}};
}

/// registrationJson() in words, for the text output.
std::string registrationLine(const nlohmann::json& j) {
  std::ostringstream line;
  const auto rounds = [](int n) { return std::to_string(n) + (n == 1 ? " round" : " rounds"); };
  line << "preset " << j["preset"].get<std::string>() << " (" << rounds(j["rounds"].get<int>()) << ", "
       << j["model"].get<std::string>() << ", radius " << j["radius_voxels"].get<double>() << " voxels";
  if (j["drift_rounds"].get<int>() > 0) {
    line << "; drift knots every ";
    if (j["drift_knot_frames"].get<int>() > 0) line << j["drift_knot_frames"].get<int>() << " frames";
    else line << j["drift_knot_m"].get<double>() << " m of path";
    line << ", " << rounds(j["drift_rounds"].get<int>());
    if (j["fine_radius_voxels"].get<double>() > 0.0) line << ", later at " << j["fine_radius_voxels"].get<double>() << " voxels";
    if (j["points"].get<bool>()) line << ", on points";
  }
  if (j["planar"].get<bool>()) line << "; planar";
  if (j["keep_mean"].get<bool>()) line << "; mean kept";
  line << ")";
  return line.str();
}

/// A session's registration in its --json object: the motion, its model, the largest drift step.
void addCorrection(nlohmann::json& j, const PoseCorrection& correction) {
  const Eigen::Isometry3d& c = correction.motion;
  j["registration_m"] = {c.translation().x(), c.translation().y(), c.translation().z()};
  j["registration_deg"] = Eigen::AngleAxisd(c.linear()).angle() * 180.0 / std::numbers::pi;
  j["registration_model"] = toString(correction.model);
  if (!correction.per_frame.empty()) {
    double largest = 0.0;
    for (const auto& f : correction.per_frame) largest = std::max(largest, f.translation().norm());
    j["drift_correction_max_m"] = largest;
  }
}

/// The registration of a session's --json object (addCorrection), as text: ", moved by ...".
void printCorrection(const nlohmann::json& j) {
  if (!j.contains("registration_m")) return;
  const auto& t = j["registration_m"];
  std::cout << ", moved by (" << std::fixed << std::setprecision(3) << t[0].get<double>() << ", "
            << t[1].get<double>() << ", " << t[2].get<double>() << ") m, " << std::setprecision(2)
            << j["registration_deg"].get<double>() << " deg" << std::defaultfloat;
}

nlohmann::json builtJson(const BuiltSession& b) {
  nlohmann::json j = addReportJson(b.report, b.time_s, b.nodes_added);
  if (b.realigned_voxels) j["realigned_voxels"] = *b.realigned_voxels;
  if (b.correction) addCorrection(j, *b.correction);
  j["dataset"] = b.dataset.string();
  j["points"] = b.points;
  j["nodes_separate"] = b.nodes_separate;
  j["warnings"] = b.warnings;
  return j;
}

void printBuilt(const BuildCmdOptions& o, const BuildSettings& s, const BuildResult& r) {
  nlohmann::json reports = nlohmann::json::array();
  for (const auto& b : r.added) {
    for (const std::string& w : b.warnings) printWarning(b.dataset.string() + ": " + w);
    reports.push_back(builtJson(b));
  }
  if (o.json) {
    nlohmann::json j{{"map", o.map},     {"created", r.created},       {"sessions", r.sessions},
                     {"nodes", r.nodes}, {"file_bytes", r.file_bytes}, {"added", reports}};
    if (r.up.from != "default") j.update(upJson(r.up));
    if (s.registration) j["registration"] = registrationJson(o, *s.registration);
    std::cout << j.dump() << "\n";
    return;
  }
  if (r.up.from != "default") std::cout << "  up: " << upLine(r.up) << "\n";
  if (s.registration) std::cout << "  registration: " << registrationLine(registrationJson(o, *s.registration)) << "\n";
  for (const auto& j : reports) {
    std::cout << "  " << j["time"].get<std::string>() << "  " << j["dataset"].get<std::string>() << ": "
              << j["nodes_added"].get<int64_t>() << " nodes added (" << j["nodes_separate"].get<uint64_t>()
              << " on its own)";
    printCorrection(j);
    if (j.contains("realigned_voxels")) std::cout << ", " << j["realigned_voxels"].get<size_t>() << " voxels re-aligned";
    std::cout << "\n";
  }
  std::cout << (r.created ? "created " : "updated ") << o.map << ": " << r.sessions << " session(s), " << r.nodes
            << " nodes, " << humanBytes(static_cast<double>(r.file_bytes)) << " on disk\n";
}

int runStreamBuild(const BuildCmdOptions& o, BuildSettings& s) {
  const Ranks ranks;
  if (ranks.size() > 1) throw UsageError("--tiles (the streaming build) runs in one process, not under mpirun");
  s.progress = terminalProgress(o.json);
  keepFreedMemoryForTheNextTile();
  const double gib = o.integrate.memory_limit_gib.value_or(kDefaultPartsGib);
  // --memory-limit is the parts' budget here; integration keeps its own default limit.
  s.session.integrator.memory_limit_bytes = defaultMemoryLimitBytes();
  const StreamResult r = streamBuild(s, o.tile_size_m, gibToBytes(gib), o.tile_windows.value_or(kDefaultWindowSessions),
                                     o.windowed_tiles);
  nlohmann::json added = nlohmann::json::array();
  for (size_t i = 0; i < r.added_times.size(); ++i) {
    added.push_back({{"time", formatTime(r.added_times[i])}, {"time_s", r.added_times[i]},
                     {"nodes_added", r.nodes_added[i]}});
    if (i < r.corrections.size()) addCorrection(added.back(), r.corrections[i]);
  }
  nlohmann::json j = {{"map", o.map},
                            {"created", r.created},
                            {"sessions", r.sessions},
                            {"tiles", r.tiles},
                            {"tile_size_m", std::ldexp(s.session.resolution_m, r.tile_level)},
                            {"index_bytes", r.index_bytes},
                            {"tile_bytes", r.tile_bytes},
                            {"groups", r.stats.groups},
                            {"largest_group_tiles", r.stats.largest_group_tiles},
                            {"tiles_read", r.stats.tiles_read},
                            {"tiles_written", r.stats.tiles_written},
                            {"tiles_kept", r.stats.tiles_kept},
                            {"windows_written", r.stats.windows_written},
                            {"spills", r.stats.spills},
                            {"spilled_bytes", r.stats.spilled_bytes},
                            {"peak_parts_bytes", r.stats.peak_parts_bytes},
                            {"peak_group_bytes", r.stats.peak_group_bytes},
                            {"added", added},
                            {"consensus_sessions", r.consensus_sessions},
                            {"warnings", r.warnings}};
  for (const std::string& w : r.warnings) printWarning(w);
  if (o.json) {
    if (s.registration) j["registration"] = registrationJson(o, *s.registration);
    std::cout << j.dump() << "\n";
    return 0;
  }
  if (s.registration) std::cout << "  registration: " << registrationLine(registrationJson(o, *s.registration)) << "\n";
  for (const auto& a : added) {
    std::cout << "  " << a["time"].get<std::string>() << ": " << a["nodes_added"].get<int64_t>() << " nodes added";
    printCorrection(a);
    std::cout << "\n";
  }
  std::cout << (r.created ? "created " : "updated ") << o.map << ": " << r.sessions << " session(s), " << r.tiles
            << " tiles of " << j["tile_size_m"].get<double>() << " m, "
            << humanBytes(static_cast<double>(r.index_bytes + r.tile_bytes)) << " on disk; " << r.stats.groups
            << " tile group(s) added to, parts held at most "
            << humanBytes(static_cast<double>(r.stats.peak_parts_bytes))
            << " (" << r.stats.spills << " spill(s)), largest working map "
            << humanBytes(static_cast<double>(r.stats.peak_group_bytes));
  if (r.consensus_sessions > 0) std::cout << "; the registration's consensus holds " << r.consensus_sessions << " session(s)";
  std::cout << "\n";
  return 0;
}

int runBuild(const BuildCmdOptions& o) {
  const bool tiled = o.tiles || isTiledMapFolder(o.map);
  if (!tiled) {
    requireExtension(o.map, ".cmap", "4D map");
    if (o.tile_size_m) throw UsageError("--tile-size needs --tiles");
    if (o.tile_windows) throw UsageError("--tile-windows needs --tiles");
    if (o.windowed_tiles) throw UsageError("--windowed-tiles needs --tiles");
  }
  BuildSettings s;
  s.realign = realignSettings(o.realign);
  s.registration = registrationSettings(o);
  s.map = o.map;
  s.datasets.assign(o.datasets.begin(), o.datasets.end());
  s.times_s = buildTimes(o);
  s.replace = o.replace;
  s.criterion = o.criterion;
  s.session = sessionSettings(o.integrate);
  if (tiled) return runStreamBuild(o, s);
  // Under mpirun the ranks cast the recordings' frames and rank 0 merges, writes and reports; alone, one process.
  const Ranks ranks;
  s.progress = terminalProgress(o.json || ranks.rank() != 0);
  try {
    if (const auto result = buildOnRanks(s, ranks)) printBuilt(o, s, *result);
  } catch (const RankStopped& stopped) {
    return stopped.exitCode();  // rank 0 says why
  } catch (...) {
    if (ranks.size() < 2) throw;
    // Rank 0 says why before the ranks' destructor finalises MPI: the other ranks exit (non-zero) as
    // soon as every rank has finalised, and mpirun may end the job before a message printed later.
    const ErrorReport report = describeError(std::current_exception());
    return printError(report.exit_code, report.message);
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
  app->add_option("MAP", o->map, "the 4D map (.cmap), or a tiled map folder")->required();
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
  addCriterionFlags(app, o->criterion);
  addRealignFlags(app, o->realign);
  app->add_option("--memory-limit", o->memory_limit_gib,
                  "MAP a tiled map folder: the session is added tile by tile (the streaming build, docs/scale.md), "
                  "holding its parts up to this many GiB (default 0.25)")
      ->check(numberIn(0, 1e6));
  app->add_option("--threads", o->threads,
                  "MAP a tiled map folder: groups of tiles read, added to and written at once, each on its own "
                  "thread (memory holds one group per thread); 0 = all cores, the default (the files do not depend "
                  "on it)")
      ->check(CLI::Range(0, 4096));
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runAdd(*o); }};
}

/// The flags a registration preset stands for: its settings where they differ from plain
/// --register's, as the flags that would set them (--help's line, so it follows the presets).
std::string registrationFlags(const RegistrationSettings& s) {
  const RegistrationSettings plain;
  const RegisterSettings &a = s.align, &p = plain.align;
  std::string text;
  const auto add = [&text](const std::string& flag) { text += (text.empty() ? "" : " ") + flag; };
  if (s.rounds != plain.rounds) add("--register-rounds " + std::to_string(s.rounds));
  if (a.drift_knot_frames > 0) add("--register-drift " + std::to_string(a.drift_knot_frames));
  if (a.drift_knot_m > 0.0) add("--register-drift-path " + exactNumber(a.drift_knot_m));
  if (a.planar) add("--register-planar");
  if (a.drift_points) add("--register-points");
  if (a.radius_voxels != p.radius_voxels) add("--register-radius " + exactNumber(a.radius_voxels));
  if (a.keep_mean) add("--register-keep-mean");
  if (a.drift_rounds != p.drift_rounds) add("--register-drift-rounds " + std::to_string(a.drift_rounds));
  if (a.fine_radius_voxels != p.fine_radius_voxels) add("--register-fine-radius " + exactNumber(a.fine_radius_voxels));
  return text;
}

/// build's --register flags.
void addRegisterFlags(CLI::App* app, BuildCmdOptions& o) {
  const RegistrationSettings odometry = odometryRegistration();
  app->add_flag("--register", o.register_sessions,
                "register each session to the consensus of all given and integrate it again with the "
                "correction (removes the part of the localisation error that is one offset per session; "
                "docs/realign.md)");
  app->add_option("--register-preset", o.register_preset,
                  "registration settings by name (implies --register; each --register-* flag given replaces one of "
                  "them): localiser = " + registrationFlags(recommendedRegistration()) +
                      " (poses from a localiser against a map: an offset and a slow drift per session); odometry = " +
                      registrationFlags(odometry) +
                      " (poses from an odometry that drifts with the distance travelled; docs/changes.md has the "
                      "figures of both)")
      ->check(CLI::IsMember({"localiser", "odometry"}));
  app->add_option("--register-model", o.register_model,
                  "what a correction is: world (one rigid motion of the session's map frame, the default) or per-pose "
                  "(the same position and heading offset of every pose, turned about each pose; docs/realign.md "
                  "compares them)");
  app->add_option("--register-drift", o.register_drift,
                  "after the rigid rounds, also correct each session's drift: every frame gets its own position and "
                  "heading correction, linear between knots this many frames apart (default 0: none; 0 also turns a "
                  "preset's drift correction off; docs/realign.md)");
  app->add_option("--register-drift-path", o.register_drift_path,
                  "the drift correction with knots every this many metres, in (0, 1000], of the sensor's path "
                  "instead of every N frames (an odometry drifts with the distance travelled: a stop's frames share "
                  "one correction), "
                  "its prior 1 cm and 0.2 degrees per square root of a metre; not with --register-drift "
                  "(docs/realign.md has the figures)");
  app->add_option("--register-drift-yaw", o.register_drift_yaw,
                  "the drift fit's smoothness: how far (degrees) the heading error may wander from one frame to the "
                  "next, in (0, 10] (default 0.01), needs knots by frames (--register-drift, or the localiser preset); larger follows an odometry's heading drift "
                  "more closely (docs/changes.md has the figures)");
  app->add_option("--register-drift-rounds", o.register_drift_rounds,
                  "rounds of drift correction, each against the consensus the previous one left, in [1, 10] (default "
                  "2, the odometry preset's " + std::to_string(odometry.align.drift_rounds) + "); needs --register-drift or --register-drift-path");
  app->add_option("--register-fine-radius", o.register_fine_radius,
                  "the neighbourhood (voxels, in [1, 8]) of the drift rounds after the first: a wide --register-radius "
                  "reaches a large drift, a narrower one refines once the sessions lie close (without it: "
                  "--register-radius throughout; docs/changes.md has the figures); needs --register-drift or --register-drift-path");
  app->add_option("--register-rounds", o.register_rounds,
                  "registration rounds, each against the consensus the previous one left (default 3)");
  app->add_option("--register-radius", o.register_radius,
                  "how far (voxels) each surface voxel looks for the consensus' surfaces; smaller resolves finer "
                  "offsets once sessions lie close, in [1, 8] (default 2, the odometry preset's " +
                      exactNumber(odometry.align.radius_voxels) + "; docs/changes.md has the office figures)");
  app->add_flag("--register-planar", o.register_planar,
                "correct x, y and heading only, never the height: the error of a robot's 2D localisation "
                "(docs/realign.md)");
  app->add_flag("--register-points", o.register_points,
                "fit the drift against the sessions' points rather than voxel centres, which resolves offsets "
                "below a voxel (docs/realign.md has the office figures)");
  app->add_flag("--register-keep-mean", o.register_keep_mean,
                "after every round, take out the motion all sessions' corrections share, so that registration moves "
                "the sessions against each other and the map stays where their mean put it (docs/realign.md)");
  app->add_option("--register-cache", o.register_cache_gib,
                  "GiB of decoded depth images kept between registration's passes over the frames (default 3, or "
                  "a quarter of the machine's memory if less; 0: none; about 154 KB a frame at 320 x 240); the "
                  "corrections do not depend on it")
      ->check(numberIn(0, 1e6));
}

Command addBuild(CLI::App& root) {
  auto o = std::make_shared<BuildCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "build",
      "Integrate several recordings and add them to a 4D map in time order (the map is created when "
      "missing and written once, atomically, at the end). Under mpirun -np N the frames of every recording are cast "
      "by the N processes (one thread each) and merged in frame order by the first; the map is the same, byte for byte (docs/scale.md). With --tiles (or a tiled map "
      "folder as MAP) the sessions are added tile by tile in bounded memory (the streaming build).");
  app->add_option("MAP", o->map, "the 4D map (.cmap), or with --tiles a tiled map folder")->required();
  app->add_option("DATASET", o->datasets, "dataset folders or files, one per session")->required();
  app->add_option("--times", o->times,
                  "comma-separated times, one per dataset (ISO-8601 or epoch seconds); default: the datasets' "
                  "first timestamps (TUM)");
  app->add_flag("--replace", o->replace, "replace sessions stored at the same times");
  addCriterionFlags(app, o->criterion);
  addIntegrateFlags(app, o->integrate);
  addRegisterFlags(app, *o);
  addRealignFlags(app, o->realign);
  app->add_flag("--tiles", o->tiles,
                "build into a tiled map folder (created when missing), tile by tile: memory holds one session, "
                "the session parts up to --memory-limit (default 0.25 GiB; the rest spilled to files; integration then "
                "keeps its default limit) and one tile "
                "or group of tiles per thread (--threads groups at once; the files do not depend on it); sessions must come after the map's last; with --register the given recordings are "
                "registered first, as without --tiles (their session maps held together), and also against the "
                "consensus of the sessions stored before, which the folder keeps from its first registered run on; "
                "no --realign or --replace (docs/scale.md)");
  app->add_option("--tile-size", o->tile_size_m,
                  "with --tiles, for a new tiled map: tile edge in metres, a power-of-two number of voxels "
                  "(default 128 voxels)")
      ->check(numberIn(1e-6, 1e6));
  app->add_option("--tile-windows", o->tile_windows,
                  "with --tiles: sessions per window file of a tile's history (default " +
                      std::to_string(kDefaultWindowSessions) +
                      "; 0: none): a snapshot of an older time reads the window that holds it, not the whole history; "
                      "a map that has windows keeps their size (docs/scale.md)")
      ->check(CLI::Range(0, 65535));
  app->add_flag("--windowed-tiles", o->windowed_tiles,
                "with --tiles, for a new tiled map: keep each tile as windows of --tile-windows sessions, of which a "
                "night reads and writes the open (last) one only, so that a night's work does not grow with the "
                "history; reading a tile whole joins its windows. An existing map keeps its layout (docs/scale.md)");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runBuild(*o); }};
}

}  // namespace chronomap::cli
