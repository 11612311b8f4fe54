#pragma once
// Shared by the benchmark programs: the sessions of a `chronomap simulate` output, integrated,
// and a stopwatch.

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <span>
#include <string>
#include <unistd.h>
#include <vector>

#include <nlohmann/json.hpp>

#include "chronomap/align/consensus.h"
#include "chronomap/align/register.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/change_truth.h"

namespace chronomap::bench {

// Seconds since `since`.
/// The value after option argv[i] (and i moved onto it); exits with status 2 when there is none.
inline std::string argValue(int& i, int argc, char** argv) {
  if (i + 1 >= argc) {
    std::fprintf(stderr, "%s needs a value\n", argv[i]);
    std::exit(2);
  }
  return argv[++i];
}

/// The sensor the programs simulate with when they simulate (`--sensor NAME`:
/// SimulationSettings::sensor, ideal by default); a folder given to them keeps its own.
inline std::string& simSensor() {
  static std::string name = "ideal";
  return name;
}
/// Sets simSensor(); exits with status 2 and the reason for a name that is not a sensor.
inline void setSimSensor(const std::string& name) {
  try {
    parseSensorKind(name);
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    std::exit(2);
  }
  simSensor() = name;
}

inline double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

struct SimSessions {
  std::vector<SessionMap> estimated;   // integrated with the estimated poses (trajectory.txt)
  std::vector<SessionMap> truth_pose;  // with the true poses (groundtruth.txt), when asked for
  std::vector<ChangeEvent> events;
  std::vector<std::filesystem::path> dirs;  // the session folders, in order
  std::vector<std::vector<Eigen::Vector3d>> positions;  // each session's sensor positions (estimated poses)
};

// How the benchmarks integrate simulated sessions: fast mode at 0.05 m. The environment's
// CHRONOMAP_BENCH_DEPTH_EDGES=R also drops depth-edge points (IntegratorSettings::
// depth_edge_ratio, `--depth-edges R`) in every benchmark that integrates through here, to
// measure the rule without a flag in each program.
inline SessionSettings simSessionSettings() {
  SessionSettings s;
  s.integrator.fast = true;
  if (const char* r = std::getenv("CHRONOMAP_BENCH_DEPTH_EDGES"); r && *r) s.integrator.depth_edge_ratio = std::atof(r);
  return s;
}

// The change criterion of the benchmarks' 4D maps: the default, with the evidence rule from the
// environment when set (CHRONOMAP_BENCH_MIN_FREE_LENGTH=M, CHRONOMAP_BENCH_MIN_HITS=N, as
// `build --min-free-length M --min-hits N`), to measure it without a flag in each program.
inline ChangeCriterion benchCriterion() {
  ChangeCriterion c;
  if (const char* m = std::getenv("CHRONOMAP_BENCH_MIN_FREE_LENGTH"); m && *m) c.min_free_length_m = std::atof(m);
  if (const char* n = std::getenv("CHRONOMAP_BENCH_MIN_HITS"); n && *n) c.min_hits = static_cast<uint32_t>(std::atoi(n));
  c.validate();
  return c;
}

// How far a session's poses, with a correction applied, lie from its true poses
// (groundtruth.txt): the mean error vector (the part one rigid offset would remove), the
// spread of the errors around it (what is left to drift), the largest error, and the mean
// heading error.
struct PoseError {
  Eigen::Vector3d mean_offset_m = Eigen::Vector3d::Zero();
  double spread_m = 0.0;  // root mean square distance of the errors from their mean
  double max_m = 0.0;
  double mean_yaw_deg = 0.0;  // mean absolute heading error
};

// Heading error: the turn of the camera's optical axis (z) about the world's vertical, from the
// true pose to the corrected one (radians).
inline double headingError(const Eigen::Isometry3d& corrected, const Eigen::Isometry3d& true_pose) {
  const Eigen::Vector3d a = true_pose.linear().col(2), b = corrected.linear().col(2);
  return std::atan2(a.x() * b.y() - a.y() * b.x(), a.x() * b.x() + a.y() * b.y());
}

inline PoseError poseError(const std::filesystem::path& dir, const PoseCorrection& correction) {
  const auto estimated = openDataset(dir);
  DatasetSettings truth_options;
  truth_options.trajectory = dir / "groundtruth.txt";
  const auto truth = openDataset(dir, truth_options);
  const size_t n = std::min(estimated->size(), truth->size());
  PoseError e;
  if (n == 0) return e;
  std::vector<Eigen::Vector3d> errors;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Isometry3d corrected = correction.apply(estimated->poseOf(i), i);
    const Eigen::Isometry3d true_pose = truth->poseOf(i);
    errors.push_back(corrected.translation() - true_pose.translation());
    e.mean_yaw_deg += std::abs(headingError(corrected, true_pose)) * 180.0 / M_PI;
    e.max_m = std::max(e.max_m, errors.back().norm());
  }
  for (const auto& v : errors) e.mean_offset_m += v;
  e.mean_offset_m /= static_cast<double>(n);
  for (const auto& v : errors) e.spread_m += (v - e.mean_offset_m).squaredNorm();
  e.spread_m = std::sqrt(e.spread_m / static_cast<double>(n));
  e.mean_yaw_deg /= static_cast<double>(n);
  return e;
}

// How far the sessions lie from each other, which is what the change rules see (an error all
// sessions share moves the whole map and changes nothing): over every pair of frames of two
// different sessions whose true positions lie within 0.5 m of each other, the root mean square
// of the difference of their position errors (horizontal) and of their heading errors.
struct RelativePoseError {
  double rms_m = 0.0;
  double heading_deg = 0.0;
  size_t pairs = 0;
};

inline RelativePoseError relativePoseError(const std::vector<std::filesystem::path>& dirs,
                                           const std::vector<PoseCorrection>& corrections) {
  struct Sample {
    Eigen::Vector2d truth, error;
    double yaw = 0.0;
    size_t session = 0;
  };
  std::vector<Sample> all;
  for (size_t k = 0; k < dirs.size() && k < corrections.size(); ++k) {
    const auto estimated = openDataset(dirs[k]);
    DatasetSettings truth_options;
    truth_options.trajectory = dirs[k] / "groundtruth.txt";
    const auto truth = openDataset(dirs[k], truth_options);
    for (size_t i = 0; i < std::min(estimated->size(), truth->size()); ++i) {
      const Eigen::Isometry3d a = corrections[k].apply(estimated->poseOf(i), i), b = truth->poseOf(i);
      all.push_back({b.translation().head<2>(), (a.translation() - b.translation()).head<2>(), headingError(a, b), k});
    }
  }
  RelativePoseError r;
  double position = 0.0, heading = 0.0;
  for (size_t i = 0; i < all.size(); ++i) {
    for (size_t j = i + 1; j < all.size(); ++j) {
      if (all[i].session == all[j].session || (all[i].truth - all[j].truth).squaredNorm() > 0.25) continue;
      position += (all[i].error - all[j].error).squaredNorm();
      heading += (all[i].yaw - all[j].yaw) * (all[i].yaw - all[j].yaw);
      ++r.pairs;
    }
  }
  if (r.pairs == 0) return r;
  r.rms_m = std::sqrt(position / static_cast<double>(r.pairs));
  r.heading_deg = std::sqrt(heading / static_cast<double>(r.pairs)) * 180.0 / M_PI;
  return r;
}

// Prints one table row per session: its pose errors before (estimated poses) and after the
// correction, in millimetres and degrees; then the sessions against each other, which it returns
// (after the correction).
inline RelativePoseError printPoseErrors(const std::vector<std::filesystem::path>& dirs,
                                         const std::vector<PoseCorrection>& corrections) {
  std::printf("\nposes against the truth per session (mm; offset = mean error, spread = rms about it):\n");
  std::printf("| session | offset before (x, y, z) | spread before | offset after (x, y, z) | spread after | max after "
              "| heading before | heading after |\n|---:|---|---:|---|---:|---:|---:|---:|\n");
  for (size_t k = 0; k < dirs.size() && k < corrections.size(); ++k) {
    const PoseError b = poseError(dirs[k], PoseCorrection{});
    const PoseError a = poseError(dirs[k], corrections[k]);
    std::printf("| %zu | %.1f, %.1f, %.1f | %.1f | %.1f, %.1f, %.1f | %.1f | %.1f | %.3f deg | %.3f deg |\n", k,
                1e3 * b.mean_offset_m.x(), 1e3 * b.mean_offset_m.y(), 1e3 * b.mean_offset_m.z(), 1e3 * b.spread_m,
                1e3 * a.mean_offset_m.x(), 1e3 * a.mean_offset_m.y(), 1e3 * a.mean_offset_m.z(), 1e3 * a.spread_m,
                1e3 * a.max_m, b.mean_yaw_deg, a.mean_yaw_deg);
  }
  const RelativePoseError before =
      relativePoseError(dirs, std::vector<PoseCorrection>(std::min(dirs.size(), corrections.size())));
  const RelativePoseError after = relativePoseError(dirs, corrections);
  std::printf("sessions against each other (frames of two sessions within 0.5 m, %zu pairs): rms %.1f mm and "
              "%.3f deg before, %.1f mm and %.3f deg after\n",
              after.pairs, 1e3 * before.rms_m, before.heading_deg, 1e3 * after.rms_m, after.heading_deg);
  return after;
}

// The estimated sessions registered to the consensus of all (`rounds` rounds, re-integrated)
// with `settings` (its model, radius and, when settings.drift(), the drift correction);
// the corrections go to `corrections` when given.
inline std::vector<SessionMap> registerSimulation(const SimSessions& s, const RegisterSettings& settings, int rounds,
                                                  std::vector<PoseCorrection>* corrections = nullptr,
                                                  std::vector<RegisterReport>* reports = nullptr) {
  std::vector<SessionMap> maps = s.estimated;
  auto found = registerDatasets(maps, s.dirs, s.positions, simSessionSettings(), {rounds, settings}, reports);
  if (corrections) *corrections = std::move(found);
  return maps;
}

// Session k of `s` registered alone (registerDatasets of one recording), against `prior` when
// given; its correction is appended to `corrections` when given.
inline SessionMap registerAlone(const SimSessions& s, size_t k, const RegisterSettings& settings, int rounds,
                                const SessionMap* prior, std::vector<PoseCorrection>* corrections) {
  std::vector<SessionMap> one = {s.estimated[k]};
  const std::vector<std::filesystem::path> paths = {s.dirs[k]};
  const std::vector<std::vector<Eigen::Vector3d>> positions = {s.positions[k]};
  auto found = registerDatasets(one, paths, positions, simSessionSettings(), {rounds, settings}, nullptr, prior);
  if (corrections) corrections->push_back(found.front());
  return std::move(one.front());
}

// Registers the sessions as the streaming build does night by night, one recording a night
// (`chronomap build DIR --tiles --register ...` once per session, in time order): each against
// the consensus of the sessions registered before it (registerSessions' prior), which then has
// the corrected session summed into it, as the tiled map keeps it.
inline std::vector<SessionMap> registerSimulationNightly(const SimSessions& s, const RegisterSettings& settings,
                                                         int rounds, std::vector<PoseCorrection>* corrections = nullptr) {
  std::vector<SessionMap> out;
  SessionMap running(s.estimated.front().resolution_m());
  for (size_t k = 0; k < s.estimated.size(); ++k) {
    SessionMap night = registerAlone(s, k, settings, rounds, k > 0 ? &running : nullptr, corrections);
    const SessionMap* both[] = {&running, &night};
    running = consensus(std::span<const SessionMap* const>(both));
    out.push_back(std::move(night));
    std::fprintf(stderr, "\r  registered night %zu/%zu", k + 1, s.estimated.size());
  }
  std::fprintf(stderr, "\n");
  return out;
}

// A diagnostic of the registration itself: every session registered alone against the consensus
// of all sessions integrated with their true poses (registerSessions' prior), so that the target
// is exact and what is left is the fit's own error. Needs loadSimulation(dir, true).
inline std::vector<SessionMap> registerSimulationToTruth(const SimSessions& s, const RegisterSettings& settings,
                                                         int rounds, std::vector<PoseCorrection>* corrections) {
  std::vector<const SessionMap*> truth;
  for (const SessionMap& m : s.truth_pose) truth.push_back(&m);
  if (truth.size() != s.estimated.size()) throw UsageError("registration to the truth needs the true-pose maps");
  const SessionMap prior = consensus(std::span<const SessionMap* const>(truth));
  std::vector<SessionMap> out;
  for (size_t k = 0; k < s.estimated.size(); ++k) out.push_back(registerAlone(s, k, settings, rounds, &prior, corrections));
  return out;
}

// The same with the library's settings but for the model and the drift knots.
inline std::vector<SessionMap> registerSimulation(const SimSessions& s, CorrectionModel model,
                                                  std::vector<PoseCorrection>* corrections = nullptr,
                                                  std::vector<RegisterReport>* reports = nullptr,
                                                  int drift_knot_frames = 0, int rounds = 3) {
  RegisterSettings settings;
  settings.model = model;
  settings.drift_knot_frames = drift_knot_frames;
  return registerSimulation(s, settings, rounds, corrections, reports);
}

// Integrates every session_NN folder of `dir` in fast mode at 0.05 m.
inline SimSessions loadSimulation(const std::filesystem::path& dir, bool with_true_poses) {
  namespace fs = std::filesystem;
  SimSessions s;
  s.events = readTruthEvents(dir / "scene.json");
  std::vector<fs::path> sessions;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_directory() && e.path().filename().string().rfind("session_", 0) == 0) sessions.push_back(e.path());
  }
  std::sort(sessions.begin(), sessions.end());
  s.dirs = sessions;
  for (const fs::path& p : sessions) {
    IntegratedSession estimated = integrateDataset(p, simSessionSettings());
    s.estimated.push_back(std::move(estimated.map));
    s.positions.push_back(std::move(estimated.sensor_positions));
    if (with_true_poses) {
      SessionSettings truth = simSessionSettings();
      truth.dataset.trajectory = p / "groundtruth.txt";
      s.truth_pose.push_back(integrateDataset(p, truth).map);
    }
    std::fprintf(stderr, "\r  integrated %zu/%zu sessions", s.estimated.size(), sessions.size());
  }
  std::fprintf(stderr, "\n");
  return s;
}

// Simulates `preset` at half resolution into a fresh temporary folder and returns it.
inline std::filesystem::path simulateTemporary(const std::string& preset, const std::string& tag) {
  const auto dir = std::filesystem::temp_directory_path() / (tag + "_" + preset + "_" + std::to_string(::getpid()));
  SimulationSettings s;
  s.preset = preset;
  s.resolution_scale = 0.5;
  s.sensor = simSensor();
  std::fprintf(stderr, "simulating %s (%s sensor) into %s\n", preset.c_str(), s.sensor.c_str(), dir.c_str());
  chronomap::simulate(s, dir, {});
  return dir;
}

/// Area under the ROC curve of scores against labels (Mann-Whitney, ties counted half).
inline double rocAuc(std::vector<std::pair<double, uint8_t>> scored) {
  std::sort(scored.begin(), scored.end());
  double positives = 0, negatives = 0, rank_sum = 0;
  for (size_t i = 0; i < scored.size();) {
    size_t j = i;
    while (j < scored.size() && scored[j].first == scored[i].first) ++j;
    const double mid_rank = 0.5 * static_cast<double>(i + 1 + j);  // ranks i+1 .. j
    for (size_t k = i; k < j; ++k) {
      if (scored[k].second) {
        positives += 1;
        rank_sum += mid_rank;
      } else {
        negatives += 1;
      }
    }
    i = j;
  }
  if (positives == 0 || negatives == 0) return 0.5;
  return (rank_sum - positives * (positives + 1) / 2) / (positives * negatives);
}

// ---- The rhythmic building (preset "weeks"): rhythm_eval and alerts_eval ----

// A weeks simulation's sessions, split into learning days and test days.
struct WeeksSim {
  std::filesystem::path dir;
  nlohmann::json scene;
  std::vector<double> times;
  std::vector<std::filesystem::path> dirs;
  std::vector<size_t> learn, test;  // session indices: before the split, and from it on
  double split_s = 0.0;
};

// Simulates the weeks preset (seed 1) at `scale` into `tmp`/weeks, with rare events if asked.
inline std::filesystem::path simulateWeeks(const std::filesystem::path& tmp, double scale, bool rare_events) {
  SimulationSettings s;
  s.preset = "weeks";
  s.resolution_scale = scale;
  s.rare_events = rare_events;
  s.sensor = simSensor();
  std::printf("simulating the weeks preset at %.2f of 640x480%s (%s sensor) ...\n", scale,
              rare_events ? " with rare events" : "", s.sensor.c_str());
  std::fflush(stdout);
  chronomap::simulate(s, tmp / "weeks");
  return tmp / "weeks";
}

// Reads a weeks simulation and splits its sessions after `learn_days` days. Exits with a message
// when either side is empty.
inline WeeksSim readWeeks(const std::filesystem::path& dir, int learn_days) {
  WeeksSim w;
  w.dir = dir;
  w.scene = nlohmann::json::parse(readTextFile(dir / "scene.json"));
  for (const auto& s : w.scene["sessions"]) {
    w.times.push_back(s["time_s"].get<double>());
    w.dirs.push_back(dir / s["dir"].get<std::string>());
  }
  w.split_s = kScheduleStart_s + 86400.0 * learn_days;
  for (size_t i = 0; i < w.times.size(); ++i) (w.times[i] < w.split_s ? w.learn : w.test).push_back(i);
  if (w.learn.empty() || w.test.empty()) {
    std::fprintf(stderr, "--learn-days %d leaves no session to learn from or to test\n", learn_days);
    std::exit(2);
  }
  return w;
}

// The registration of `chronomap build --register` (RegistrationSettings{}), or the one
// CHRONOMAP_BENCH_REGISTER names: comma-separated words, a preset first if at all ("localiser" or
// its older name "recommended", or "odometry": build's --register-preset, registrationNamed()),
// then changes to it: "radius=V", "knots=F",
// "path=M" (knots every M metres of path instead of frames; "path-m=S", "path-yaw=DEG" its prior
// per square root of a metre), "yaw=DEG", "rounds=N", "drift-rounds=N", "fine=V", "planar", "points", "keep-mean" (as build's
// --register-radius, --register-drift, --register-drift-yaw, --register-rounds,
// --register-drift-rounds, --register-fine-radius, --register-planar, --register-points,
// --register-keep-mean).
inline RegistrationSettings benchRegistration() {
  RegistrationSettings r;
  const char* env = std::getenv("CHRONOMAP_BENCH_REGISTER");
  if (!env || !*env) return r;
  std::string words = env;
  for (size_t start = 0; start <= words.size();) {
    const size_t comma = std::min(words.find(',', start), words.size());
    const std::string w = words.substr(start, comma - start);
    const size_t eq = w.find('=');
    const std::string key = w.substr(0, eq);
    double value = 0.0;
    if (eq != std::string::npos) {
      char* end = nullptr;
      value = std::strtod(w.c_str() + eq + 1, &end);
      if (end == w.c_str() + eq + 1 || *end != '\0' || !std::isfinite(value)) {
        throw UsageError("CHRONOMAP_BENCH_REGISTER: '" + w + "' needs a number after '='");
      }
    }
    if (w == "recommended" || w == "localiser" || w == "odometry") {
      if (start != 0) throw UsageError("CHRONOMAP_BENCH_REGISTER: '" + w + "' must come first");
      r = registrationNamed(w == "recommended" ? "localiser" : w);
    } else if (key == "radius") {
      r.align.radius_voxels = value;
    } else if (key == "knots") {
      r.align.drift_knot_frames = static_cast<int>(value);
      r.align.drift_knot_m = 0.0;
    } else if (key == "path") {
      r.align.drift_knot_m = value;
      r.align.drift_knot_frames = 0;
    } else if (key == "path-m") {
      r.align.drift_per_m = value;
    } else if (key == "path-yaw") {
      r.align.drift_yaw_per_m_deg = value;
    } else if (key == "yaw") {
      r.align.drift_yaw_per_frame_deg = value;
    } else if (key == "rounds") {
      r.rounds = static_cast<int>(value);
    } else if (key == "drift-rounds") {
      r.align.drift_rounds = static_cast<int>(value);
    } else if (key == "fine") {
      r.align.fine_radius_voxels = value;
    } else if (w == "planar") {
      r.align.planar = true;
    } else if (w == "points") {
      r.align.drift_points = true;
    } else if (w == "keep-mean") {
      r.align.keep_mean = true;
    } else if (!w.empty()) {
      throw UsageError("CHRONOMAP_BENCH_REGISTER: unknown word '" + w + "'");
    }
    start = comma + 1;
  }
  r.align.validate();
  return r;
}

// The 4D map of the sessions `which` of `w`, fast mode at 0.05 m with `max_range_m`: with true
// poses each session integrated with its groundtruth.txt and added in memory; else as
// `chronomap build --register` does it (or with CHRONOMAP_BENCH_REGISTER's registration), written to `scratch` (a .cmap path) and read back.
inline TemporalMap buildWeeksMap(const WeeksSim& w, const std::vector<size_t>& which, bool true_poses,
                                 double max_range_m, const std::filesystem::path& scratch,
                                 bool carve_beyond_range = false) {
  BuildSettings build;
  build.map = scratch;
  for (size_t i : which) {
    build.datasets.push_back(w.dirs[i]);
    build.times_s.emplace_back(w.times[i]);
  }
  build.session = simSessionSettings();  // fast mode (and CHRONOMAP_BENCH_DEPTH_EDGES)
  build.session.integrator.max_range_m = max_range_m;
  build.session.integrator.carve_beyond_range = carve_beyond_range;
  build.registration = benchRegistration();
  build.criterion = benchCriterion();
  if (true_poses) {
    TemporalMap m(0.05, build.criterion);
    for (size_t i : which) {
      SessionSettings ss = build.session;
      ss.dataset.trajectory = w.dirs[i] / "groundtruth.txt";
      m.add(w.times[i], integrateDataset(w.dirs[i], ss).map);
    }
    return m;
  }
  chronomap::build(build);
  TemporalMap m = readTemporalMap(build.map);
  std::error_code ec;
  std::filesystem::remove(build.map, ec);
  return m;
}

}  // namespace chronomap::bench
