// Uses an installed chronomap: simulates a small recorded building (or takes TUM RGB-D folders
// given after the output folder), builds a 4D map of its sessions and prints, for each session's
// time, the counts of the map's snapshot.
//
//   four_d_map OUT_FOLDER [DATASET...]

#include <cstdio>
#include <exception>
#include <filesystem>
#include <optional>

#include "chronomap/core/error.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/sim/building.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/version.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s OUT_FOLDER [DATASET...]\n", argv[0]);
    return 2;
  }
  try {
    const std::filesystem::path out = argv[1];
    chronomap::BuildSettings build;
    build.map = out / "map.cmap";
    if (argc > 2) {
      for (int i = 2; i < argc; ++i) build.datasets.emplace_back(argv[i]);
    } else {
      // The simulator's one-room building, two sessions, small images: a second or two.
      chronomap::SimulationSettings simulation;
      simulation.preset = "tiny";
      simulation.sessions = 2;
      simulation.resolution_scale = 0.25;
      const chronomap::SimulationSummary recorded = chronomap::simulate(simulation, out / "recordings");
      build.datasets = recorded.session_dirs;
      for (double t : recorded.times_s) build.times_s.emplace_back(t);
    }
    std::filesystem::remove(build.map);
    const chronomap::BuildResult built = chronomap::build(build);
    std::printf("chronomap %s: %zu sessions, %zu nodes, %llu bytes in %s\n", chronomap::kVersion, built.sessions,
                built.nodes, static_cast<unsigned long long>(built.file_bytes), build.map.string().c_str());

    const chronomap::TemporalMap map = chronomap::readTemporalMap(build.map);
    for (double t : map.times()) {
      const chronomap::SessionMapCounts counts = map.snapshot(t).counts();
      std::printf("snapshot at %.3f: %llu occupied voxels, %llu free voxels, %zu leaves\n", t,
                  static_cast<unsigned long long>(counts.occupied_voxels),
                  static_cast<unsigned long long>(counts.free_voxels), counts.leaves);
    }
    return 0;
  } catch (const chronomap::Error& e) {
    std::fprintf(stderr, "four_d_map: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "four_d_map: internal error: %s\n", e.what());
    return 1;
  }
}
