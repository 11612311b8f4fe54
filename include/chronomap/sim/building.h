#pragma once
/// @file
/// The simulated building: an office floor recorded by a patrolling robot over many sessions,
/// with every change known. simulate() writes it; the scene (scene.h), the camera (render.h) and
/// the ground truth (truth.h) come with this header.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "chronomap/sim/render.h"
#include "chronomap/sim/scene.h"
#include "chronomap/sim/truth.h"

namespace chronomap {

/// Settings of a simulation. Presets: "tiny" (one room), "office" (three rooms and a corridor,
/// the demo), "floor66" (40 x 20 m, 16 rooms, 66 sessions over 45 days), "weeks" (the office
/// on a weekly schedule, 56 sessions at all hours over four weeks; see applySchedule()), "site"
/// (floors of floor66 stacked, patrolled every night for a year: 365 sessions; a run of N sessions
/// is the first N of the year, byte for byte).
struct SimulationSettings {
  std::string preset = "office";
  uint64_t seed = 1;
  int sessions = 0;               ///< 0: the preset's default
  double resolution_scale = 1.0;  ///< image size relative to 640 x 480 (0.25 .. 1)
  double voxel_resolution_m = 0.05;  ///< of the ground-truth occupancy
  double noise_per_m2 = 0.0014;   ///< depth noise sigma = this * z^2 (metres); 0 = none
  double localisation_offset_m = 0.02;   ///< sigma of the per-session position offset
  double localisation_yaw_deg = 0.3;     ///< sigma of the per-session heading offset
  double drift_per_frame_m = 0.002;      ///< sigma of the position random walk per frame
  int threads = 0;                ///< 0: all cores
  /// "weeks" only: rare events on top of the routines (rareEventOf), labelled "rare" in
  /// scene.json. Off, the simulation is what it was before rare events existed.
  bool rare_events = false;
  /// "fixed" (the default): lightingAt(hour), the same everywhere, as before lighting could be
  /// chosen. "daylight": Daylight's lamps in working hours and sun through the windows, warm at
  /// sunrise and sunset, none at night; its true curves go into scene.json ("lighting"). Only
  /// the colour images change with it.
  std::string lighting = "fixed";
  /// Repaint one object that never moves (the first table no routine moves, else a desk) in the session a quarter of the way before
  /// the end: from then on all its faces have another colour. Labelled in scene.json
  /// ("repaints", with the object's voxels); the occupancy does not change. Off, nothing does.
  bool repaint = false;
  /// "site" only: how many floors are stacked and patrolled (1 .. 50; kSiteFloors by default).
  int floors = kSiteFloors;
  /// The depth camera and odometry imitated (parseSensorKind): "ideal" (the default: the clean
  /// z^2 Gaussian of noise_per_m2 and the localisation above, as before sensors could be chosen),
  /// "kinect" or "realsense" (sensorModel(): published noise, quantisation, lateral noise, range,
  /// grazing, dark and shiny surfaces, flying pixels, and estimated poses from a drifting
  /// odometry). The true poses, the truth files and the colour images do not depend on it.
  std::string sensor = "ideal";
};

/// What simulate() wrote.
struct SimulationSummary {
  std::vector<std::filesystem::path> session_dirs;
  std::vector<double> times_s;
  std::vector<double> hours;
  size_t frames = 0;
  size_t events = 0;
  double seconds = 0.0;
};

/// Progress: (sessions done, sessions in all).
using SimulationProgress = std::function<void(size_t, size_t)>;

/// Simulates and writes `out`: session_NN/ TUM folders (rgb/, depth/, rgb.txt, depth.txt,
/// groundtruth.txt = true poses, trajectory.txt = estimated poses, camera-intrinsics.txt),
/// truth/ (objects_NN.json and occupancy_NN.cmap per session), and scene.json (settings,
/// sessions and every change event). The same settings give byte-identical output.
/// @throw UsageError for an unknown preset or bad settings; IoError when writing fails.
SimulationSummary simulate(const SimulationSettings& settings, const std::filesystem::path& out,
                           const SimulationProgress& progress = {});

}  // namespace chronomap
