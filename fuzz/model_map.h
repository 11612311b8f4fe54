#pragma once
// The 4D map the saved models' seeds are fitted on (make_seeds.cpp), which fuzz_model checks
// every model that reads against (as predict and view check a saved model against their map), so
// that the seeds pass the check and their mutations reach each of its refusals.

#include "chronomap/temporal/temporal_map.h"

namespace chronomap::fuzz {

/// Two sessions of a row of voxels at 0.1 m, at 1000 s and 2000 s; a voxel occupied in the
/// second only and one that moves, so that the rhythm models have cubes that changed.
inline TemporalMap modelMap() {
  TemporalMap map(0.1, ChangeCriterion{0.0, 10.0});
  for (int s = 0; s < 2; ++s) {
    SessionMap session(0.1);
    VoxelCounters free, hit;
    free.length_m = 0.1f;
    hit.length_m = 0.05f;
    hit.hits = 2;
    hit.red = static_cast<uint32_t>(100 + 50 * s) * 2;
    for (uint16_t x = 0; x < 6; ++x) {
      const bool occupied = (x == 2 && s == 1) || x == 4 + s;
      session.add({static_cast<uint16_t>(32768 + x), 32768, 32768}, occupied ? hit : free);
    }
    map.add(1000.0 * (s + 1), session);
  }
  return map;
}

}  // namespace chronomap::fuzz
