#pragma once
// The subcommands of the chronomap binary. Each registers its options on the root app and
// returns the function that runs it; commands only parse, call the library and print.

#include <CLI/CLI.hpp>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "chronomap/align/register.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/io/dataset.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap::cli {

/// Runs a parsed subcommand; returns the exit code.
using Runner = std::function<int()>;

/// A registered subcommand and the function that runs it once parsed.
struct Command {
  CLI::App* app = nullptr;
  Runner run;
};

Command addIntegrate(CLI::App& root);
Command addStats(CLI::App& root);
Command addExport(CLI::App& root);
Command addAdd(CLI::App& root);
Command addBuild(CLI::App& root);
Command addSnapshot(CLI::App& root);
Command addHistory(CLI::App& root);
Command addChanges(CLI::App& root);
Command addDiff(CLI::App& root);
Command addSegment(CLI::App& root);

/// How datasets become session maps (the options of integrate, shared with build).
struct IntegrateSettings {
  double resolution_m = 0.05;
  double max_range_m = IntegratorSettings{}.max_range_m;
  std::string format = "auto";
  bool fast = false;
  int threads = 0;
  bool no_compress = false;
  bool no_positions = false;
  double depth_scale = 0.0;
  std::string intrinsics;
  std::string pose;
  std::string trajectory;
};
/// Registers the integration options on a subcommand.
void addIntegrateOptions(CLI::App* app, IntegrateSettings& settings);

/// A dataset integrated into a session map.
struct IntegratedSession {
  SessionMap map;
  IntegrationStats stats;
  std::optional<double> recorded_at;  ///< from the dataset's own timestamps, if any
  std::string format;
  size_t frames_dropped = 0;
  std::vector<Eigen::Vector3d> sensor_positions;  ///< of every frame, as recorded (before `correction`)
};
/// The reader options the integrate options ask for.
io::DatasetOptions datasetOptions(const IntegrateSettings& settings);
/// The integrator settings they ask for.
IntegratorSettings integratorSettings(const IntegrateSettings& settings);
/// Opens and integrates a dataset with a progress bar labelled `label`, every pose corrected by
/// `correction` (integrator.h).
/// @throw DataError when no point could be integrated.
IntegratedSession integrateDataset(const std::string& path, const IntegrateSettings& settings, const std::string& label,
                                   const PoseCorrection& correction = {});
/// Registers the session maps integrated from `paths` (in that order, with `sensor_positions`
/// as recorded) to their consensus (registerSessions), integrating each dataset again with its
/// correction; `maps` become the corrected sessions.
std::vector<PoseCorrection> registerDatasets(std::vector<SessionMap>& maps, const std::vector<std::string>& paths,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions,
                                             const IntegrateSettings& settings, int rounds,
                                             const RegisterSettings& register_settings);

Command addSimulate(CLI::App& root);
Command addDemo(CLI::App& root);

/// Draws nodes against sessions (stored separately and as the 4D map) into a PNG.
void writeStoragePlot(const std::string& path, const TemporalMap& map);

/// Formats a byte count as "12.3 MiB".
std::string humanBytes(double bytes);

}  // namespace chronomap::cli
