#pragma once
// The subcommands of the chronomap binary. Each registers its flags on the root app and returns
// the function that runs it; a command parses its flags into library settings, makes one call
// (pipeline/, or one library function) and prints what it returned.

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <functional>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "chronomap/core/memory.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/pipeline/tiles.h"

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
Command addPredict(CLI::App& root);
Command addCostmap(CLI::App& root);
Command addAlerts(CLI::App& root);
Command addDiff(CLI::App& root);
Command addSegment(CLI::App& root);
Command addSimulate(CLI::App& root);
Command addDemo(CLI::App& root);
Command addView(CLI::App& root);
Command addTile(CLI::App& root);
Command addUntile(CLI::App& root);

/// Bytes of a --memory-limit given in GiB (already checked to be finite and within 0..1e6), rounded.
/// Prints one error the way every command does ("chronomap: error: ..." on stderr). @return code
inline int printError(int code, const std::string& message) {
  std::cerr << "chronomap: error: " << message << "\n" << std::flush;
  return code;
}

/// Prints one warning the way every command does ("chronomap: warning: ..." on stderr).
inline void printWarning(const std::string& message) { std::cerr << "chronomap: warning: " << message << "\n" << std::flush; }

inline size_t gibToBytes(double gib) { return memoryLimitFromGib(gib); }
/// Help of the --memory-limit flag of the commands that read tiled maps.
inline constexpr const char* kTileMemoryHelp =
    "tiled maps: GiB of tiles held at once (least recently used tiles are dropped whole); 0: no limit; default 1";
/// The tile cache a --memory-limit flag (GiB; 0: none; unset: the default) asks for.
TileCacheSettings tileCacheSettings(const std::optional<double>& gib);

/// The integration flags of integrate and build, as given.
struct IntegrateFlags {
  double resolution_m = 0.05;
  double max_range_m = IntegratorSettings{}.max_range_m;
  bool carve_beyond_range = false;
  std::string format = "auto";
  bool fast = false;
  int threads = 0;
  bool no_compress = false;
  bool no_positions = false;
  std::string carve_level = "auto";  ///< "auto" or 0 to kMaxCarveLevel
  std::optional<double> depth_scale;  ///< unset: the format's own
  std::optional<double> memory_limit_gib;  ///< unset: IntegratorSettings' default; 0: none
  std::string intrinsics;
  std::string pose;
  std::string trajectory;
  BagSettings bag;                      ///< ROS bags: topics and frames
  std::optional<double> pose_tolerance_s;  ///< unset: BagSettings' default
};
/// Registers the integration flags on a subcommand.
void addIntegrateFlags(CLI::App* app, IntegrateFlags& flags);
/// The session settings the flags ask for. @throw UsageError for unreadable values.
SessionSettings sessionSettings(const IntegrateFlags& flags);

/// Validator for a numeric flag: the value must be a finite number in [lo, hi]; otherwise the
/// command stops with "--flag: VALUE: must lie in [lo, hi]" before anything runs. Every numeric
/// flag with a limit uses it, so no value out of range is read as something else.
CLI::Validator numberIn(double lo, double hi);
/// The most worker threads a flag accepts.
inline constexpr int kMaxThreads = 1024;

/// The comma-separated items of a flag's value ("a,b,,c" gives four, the third empty).
std::vector<std::string> splitCommas(const std::string& text);

/// Throws UsageError unless `path` ends in `ext` ("4D map 'x' must end in .cmap").
void requireExtension(const std::string& path, const std::string& ext, const std::string& what);

}  // namespace chronomap::cli
