#pragma once
// The demo's intermediate results and its report (pipeline/demo.h runs it).

#include <string>
#include <vector>

#include "chronomap/analysis/changes.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/pipeline/demo.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/change_truth.h"
#include "chronomap/temporal/temporal_map.h"

namespace chronomap {

/// One simulated session as the demo integrated and scored it.
struct DemoSession {
  SessionMap map;
  IntegrationStats stats;
  OccupancyScore score;             ///< with the poses as recorded
  OccupancyScore registered_score;  ///< after registration
  std::vector<VoxelKey> truth;           ///< the truth's occupied voxels
  std::vector<Eigen::Vector3d> sensor_positions;
};

/// The changes between sessions `from` and `from + 1`.
struct DemoPair {
  size_t from = 0;
  std::string name;  ///< "diff_01_02" (sessions from 1): of its diff in changes/ and its picture in images/
  std::vector<ChangeEvent> events;
  Changes changes;   ///< findChanges() of the 4D map between the two sessions' times
  std::vector<std::string> pictures;  ///< in images/: the pair's top view, then a close-up per object
  ChangeScore score;
};

/// Everything the report states.
struct DemoReportInput {
  const DemoSettings& settings;
  const SimulationSettings& simulation;
  const SimulationSummary& simulated;
  const std::vector<DemoSession>& sessions;
  const std::vector<DemoPair>& pairs;
  const TemporalMap& map;
  const DemoResult& result;
  const ChangeScore& changes;  ///< over all pairs
  uint64_t map_file_bytes;
  int drift_knots;
};

/// report.md.
std::string demoReport(const DemoReportInput& in);

/// report.json: {"numbering": ..., "pairs": [{"from", "to", "from_time", "to_time", "objects"}]}
/// in session order, sessions numbered from 1; "objects" is changedObjectsJson() of each pair.
std::string demoReportJson(const DemoReportInput& in);

}  // namespace chronomap
