// realign_eval: how much of the change a 4D map stores is localisation noise, and how much of
// it re-alignment against the consensus (thesis §2.2) removes, measured against the
// simulator's ground truth.
//
// For a simulation (office, floor66): every session is integrated (fast mode, 0.05 m) with its
// estimated poses and added to a 4D map in time order: as recorded, re-aligned against the
// consensus of all sessions, registered to the consensus (3 rounds, re-integrated), and
// registered then re-aligned. For each session after the first, the voxels whose state the 4D
// map records as changed by it (history entries after a voxel's first) are split into true
// changes (within one voxel of a truth event voxel of an event between the session that saw
// the previous state and this one) and false ones. "True changes kept" is the share of the
// observable truth voxels still matched: those that the changes recorded as is match and that
// the changes recorded with the true poses match too. (The share of all truth voxels matched as
// recorded is printed beside it: noise changes next to a truth voxel count there, so it scores
// better alignment as loss.) Then sweeps over the settings.
//
// Usage: realign_eval [--office DIR] [--floor66 DIR] [--quick] [--skip-floor66] [--register-model M] [--drift-knots N]
//   --seeds A-B    simulate seeds A to B (with --sensor NAME, through that sensor) and run once on each;
//                  prints every figure's mean, min and max (seeds.h). Train on 1-5, report 6-15.
//   --office DIR    a `chronomap simulate --preset office` output (default: simulate one at half
//                   resolution into a temporary folder)
//   --floor66 DIR   a floor66 simulation (default: simulate one at half resolution, ~7 minutes)
//   --quick         no sweep
//   --sensor NAME  ideal (default), kinect or realsense: the sensor of the simulations made here
//                  (SimulationSettings::sensor); a folder given keeps its own
//   --skip-floor66  office only (the last line then reports the office)
//   --register-model  world (default) or per-pose: the registration's correction model
//                   (align/register.h)
//   --drift-knots N  the registration's drift correction: knots every N frames (default 20;
//                   0: one rigid correction per session only)
// The last line of output is one JSON object for floor66 with the recommended step,
// registration (as `chronomap build --register --register-drift 20`): false_changes_removed,
// true_changes_kept (fractions), nodes_4d (as recorded) and nodes_4d_realigned (registered);
// then the same for re-alignment alone and for registration followed by re-alignment.

#include <chrono>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <unordered_set>
#include <vector>

#include "bench_sim.h"
#include "seeds.h"
#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/align/register.h"
#include "chronomap/temporal/temporal_map.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

using bench::seconds;

// The truth event voxels by the session gap they belong to (events between sessions s, s + 1).
class TruthIndex {
 public:
  TruthIndex(const std::vector<ChangeEvent>& events, size_t sessions) : by_gap_(sessions) {
    for (const auto& e : events) {
      if (e.from_session >= by_gap_.size()) continue;
      for (const VoxelKey& k : e.voxels) by_gap_[e.from_session].insert(mortonEncode(k));
    }
  }
  // True when a voxel within one voxel of `key` changed in the truth between sessions
  // `before` and `after`; those truth voxels (Morton code | gap << 48) go to `found`.
  bool isTrue(const VoxelKey& key, uint32_t before, uint32_t after, std::unordered_set<uint64_t>& found) const {
    bool any = false;
    for (uint32_t s = before; s < after && s < by_gap_.size(); ++s) {
      if (by_gap_[s].empty()) continue;
      anyKeyWithin(key, 1, [&](const VoxelKey& k) {
        if (by_gap_[s].count(mortonEncode(k))) {
          found.insert(mortonEncode(k) | (uint64_t{s} << 48));
          any = true;
        }
        return false;
      });
    }
    return any;
  }

 private:
  std::vector<std::unordered_set<uint64_t>> by_gap_;
};

const char* moveName(RealignSettings::Move m) { return m == RealignSettings::Move::Swap ? "swap" : "transfer"; }

struct SessionTally {
  uint64_t true_changes = 0, false_changes = 0;
  int64_t nodes_added = 0;
};

struct Run {
  std::vector<SessionTally> sessions;
  std::unordered_set<uint64_t> truth_found;  // truth event voxels that a recorded change matches
  uint64_t true_changes = 0, false_changes = 0;
  uint64_t nodes_4d = 0;
  size_t moved = 0;
  double realign_s = 0.0;
};

// Builds the 4D map of `maps` in order and tallies each session's changes.
Run tally(const std::vector<SessionMap>& maps, const TruthIndex& truth) {
  Run run;
  TemporalMap map(maps.front().resolution_m());
  for (size_t k = 0; k < maps.size(); ++k) map.add(static_cast<double>(k), maps[k]);
  run.sessions.resize(maps.size());
  for (size_t k = 0; k < maps.size(); ++k) run.sessions[k].nodes_added = map.sessions()[k].nodes_added;
  for (uint32_t k = 1; k < maps.size(); ++k) {
    SessionTally& t = run.sessions[k];
    map.forEachListChangedIn(k, k + 1, [&](const VoxelKey& corner, int level, std::span<const TemporalMap::Entry> e) {
      for (size_t i = 1; i < e.size(); ++i) {
        if (e[i].session != k) continue;
        const int side = 1 << level;
        for (int dz = 0; dz < side; ++dz) {
          for (int dy = 0; dy < side; ++dy) {
            for (int dx = 0; dx < side; ++dx) {
              const VoxelKey v{static_cast<uint16_t>(corner.x + dx), static_cast<uint16_t>(corner.y + dy),
                               static_cast<uint16_t>(corner.z + dz)};
              (truth.isTrue(v, e[i - 1].session, k, run.truth_found) ? t.true_changes : t.false_changes)++;
            }
          }
        }
      }
    });
    run.true_changes += t.true_changes;
    run.false_changes += t.false_changes;
  }
  run.nodes_4d = map.counts().nodes();
  return run;
}

Run realignedRun(const std::vector<SessionMap>& maps, const SessionMap& avg, const RealignSettings& settings,
                 const TruthIndex& truth) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<SessionMap> aligned;
  aligned.reserve(maps.size());
  size_t moved = 0;
  for (const SessionMap& m : maps) {
    RealignReport r;
    aligned.push_back(realign(m, avg, settings, &r));
    moved += r.moved();
  }
  const double s = seconds(start);
  Run run = tally(aligned, truth);
  run.moved = moved;
  run.realign_s = s;
  return run;
}

struct Outcome {
  double false_removed = 0.0;
  // Of the truth event voxels that both the changes recorded as is and those recorded with the
  // true poses match (the true changes a perfectly localised map records), the share still
  // matched. The headline "true changes kept".
  double true_kept = 0.0;
  // Of the truth event voxels that the changes recorded as is match, the share still matched.
  // Biased against better alignment: noise changes that happen to lie next to a truth voxel
  // count as finding it, so even the true poses keep only ~85% by this measure.
  double true_kept_any = 0.0;
  uint64_t nodes_4d = 0, nodes_4d_realigned = 0;
};

// The figures of one preset: re-alignment alone, registration alone, and both.
struct Evaluation {
  Outcome realign_only, register_only, pipeline;
};

// `reference` is the run with the true poses: it decides which truth voxels are observable
// changes (Outcome::true_kept).
Outcome compare(const Run& before, const Run& after, const Run& reference) {
  Outcome o;
  o.false_removed = before.false_changes ? 1.0 - double(after.false_changes) / double(before.false_changes) : 0.0;
  size_t kept_any = 0, observable = 0, kept = 0;
  for (uint64_t v : before.truth_found) {
    const bool still = after.truth_found.count(v) != 0;
    kept_any += still;
    if (reference.truth_found.count(v)) {
      ++observable;
      kept += still;
    }
  }
  o.true_kept_any = before.truth_found.empty() ? 1.0 : double(kept_any) / double(before.truth_found.size());
  o.true_kept = observable == 0 ? 1.0 : double(kept) / double(observable);
  o.nodes_4d = before.nodes_4d;
  o.nodes_4d_realigned = after.nodes_4d;
  return o;
}

Evaluation evaluate(const std::string& name, const fs::path& dir, bool sweep, bool per_session, CorrectionModel model,
                    int drift_knots) {
  std::printf("\n== %s (%s) ==\n", name.c_str(), dir.c_str());
  const bench::SimSessions s = bench::loadSimulation(dir, true);
  const TruthIndex truth(s.events, s.estimated.size());
  auto t = std::chrono::steady_clock::now();
  const SessionMap avg = consensus(std::span<const SessionMap>(s.estimated));
  const double consensus_s = seconds(t);
  std::printf("%zu sessions; consensus of all: %zu leaves, %.2f s\n", s.estimated.size(), avg.leafCount(), consensus_s);

  const Run plain = tally(s.estimated, truth);
  const Run true_poses = tally(s.truth_pose, truth);
  const RealignSettings defaults;
  const Run aligned = realignedRun(s.estimated, avg, defaults, truth);
  const Outcome o = compare(plain, aligned, true_poses);
  if (per_session) {
    std::printf("\nper session (changed voxels the 4D map records; true = within 1 voxel of a truth event):\n");
    std::printf("| session | true | false | nodes added | true, re-aligned | false, re-aligned | nodes added, re-aligned |\n");
    std::printf("|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t k = 1; k < plain.sessions.size(); ++k) {
      const auto& a = plain.sessions[k];
      const auto& b = aligned.sessions[k];
      std::printf("| %zu | %llu | %llu | %lld | %llu | %llu | %lld |\n", k, (unsigned long long)a.true_changes,
                  (unsigned long long)a.false_changes, (long long)a.nodes_added, (unsigned long long)b.true_changes,
                  (unsigned long long)b.false_changes, (long long)b.nodes_added);
    }
  }
  const double n = static_cast<double>(s.estimated.size() - 1);
  auto mean_added = [&](const Run& r) {
    double sum = 0;
    for (size_t k = 1; k < r.sessions.size(); ++k) sum += static_cast<double>(r.sessions[k].nodes_added);
    return sum / n;
  };
  std::printf("\ndefaults (%s, alpha %.4g, d_max %.3g voxels, epsilon %.3g, consensus occupied above %.4g, "
              "weights %.3g/%.3g/%.3g):\n",
              moveName(defaults.move), defaults.alpha, defaults.max_distance_voxels, defaults.epsilon,
              defaults.consensus_occupied_above, defaults.weight_distance, defaults.weight_colour,
              defaults.weight_probability);
  std::printf("  as recorded: %llu true + %llu false changed voxels; 4D map %llu nodes, %.0f added per session\n",
              (unsigned long long)plain.true_changes, (unsigned long long)plain.false_changes,
              (unsigned long long)plain.nodes_4d, mean_added(plain));
  std::printf("  true poses (no localisation error, for reference): %llu true + %llu false changed voxels; 4D map "
              "%llu nodes\n",
              (unsigned long long)true_poses.true_changes, (unsigned long long)true_poses.false_changes,
              (unsigned long long)true_poses.nodes_4d);
  {
    const Outcome perfect = compare(plain, true_poses, true_poses);
    std::printf("  (true poses on this scale: false changes removed %.1f%%, true change voxels kept %.1f%% "
                "of those any recorded change matches)\n",
                100.0 * perfect.false_removed, 100.0 * perfect.true_kept_any);
  }
  std::printf("  re-aligned:  %llu true + %llu false changed voxels; 4D map %llu nodes, %.0f added per session; "
              "%zu voxels moved in %.2f s (%.1f ms a session)\n",
              (unsigned long long)aligned.true_changes, (unsigned long long)aligned.false_changes,
              (unsigned long long)aligned.nodes_4d, mean_added(aligned), aligned.moved, aligned.realign_s,
              aligned.realign_s * 1000.0 / static_cast<double>(s.estimated.size()));
  std::printf("  false changes removed %.1f%%, true change voxels kept %.1f%% (of any matched: %.1f%%), nodes %.1f%% "
              "of as recorded\n",
              100.0 * o.false_removed, 100.0 * o.true_kept, 100.0 * o.true_kept_any,
              100.0 * double(aligned.nodes_4d) / double(std::max<uint64_t>(1, plain.nodes_4d)));

  // Registration first: one rigid correction per session against the consensus, the session
  // integrated again with it, then the per-voxel re-alignment against the new consensus.
  Evaluation result;
  result.realign_only = o;
  {
    const auto start = std::chrono::steady_clock::now();
    std::vector<RegisterReport> reports;
    std::vector<PoseCorrection> corrections;
    const std::vector<SessionMap> registered = bench::registerSimulation(s, model, &corrections, &reports, drift_knots);
    double shift_before = 0.0, shift_after = 0.0, correction_m = 0.0;
    for (size_t k = 0; k < corrections.size(); ++k) {
      shift_before += reports[k].mean_shift_before_m;
      shift_after += reports[k].mean_shift_after_m;
      correction_m += corrections[k].motion.translation().norm();
    }
    const double register_s = seconds(start);
    const double n_s = static_cast<double>(s.estimated.size());
    const Run reg = tally(registered, truth);
    const Outcome ro = compare(plain, reg, true_poses);
    const SessionMap avg2 = consensus(std::span<const SessionMap>(registered));
    const Run both = realignedRun(registered, avg2, defaults, truth);
    const Outcome bo = compare(plain, both, true_poses);
    result.pipeline = bo;
    result.register_only = ro;
    bench::printPoseErrors(s.dirs, corrections);
    if (drift_knots > 0) std::printf("\ndrift corrected too: knots every %d frames, 2 rounds", drift_knots);
    std::printf("\nregistered to the consensus (%s corrections; mean pull %.1f mm before, %.1f mm after; mean correction %.1f mm; "
                "%.2f s a session for 3 rounds with re-integration):\n",
                toString(model), 1000.0 * shift_before / n_s, 1000.0 * shift_after / n_s, 1000.0 * correction_m / n_s,
                register_s / n_s);
    std::printf("  registered:               %llu true + %llu false; false removed %.1f%%, true kept %.1f%% (of any "
                "matched: %.1f%%), 4D map %llu nodes\n",
                (unsigned long long)reg.true_changes, (unsigned long long)reg.false_changes, 100.0 * ro.false_removed,
                100.0 * ro.true_kept, 100.0 * ro.true_kept_any, (unsigned long long)reg.nodes_4d);
    std::printf("  registered + re-aligned:  %llu true + %llu false; false removed %.1f%%, true kept %.1f%% (of any "
                "matched: %.1f%%), 4D map %llu nodes\n",
                (unsigned long long)both.true_changes, (unsigned long long)both.false_changes, 100.0 * bo.false_removed,
                100.0 * bo.true_kept, 100.0 * bo.true_kept_any, (unsigned long long)both.nodes_4d);
    if (sweep) {
      std::printf("\nre-alignment after registration (transfer, consensus occupied above 0.5):\n"
                  "| d_max | alpha | false removed | true kept | nodes 4D |\n|---:|---:|---:|---:|---:|\n");
      for (double d_max : {1.0, 1.75}) {
        for (double alpha : {300.0, 1000.0, 3000.0, 5000.0, 8000.0}) {
          RealignSettings rs = defaults;
          rs.alpha = alpha;
          rs.max_distance_voxels = d_max;
          const Outcome c = compare(plain, realignedRun(registered, avg2, rs, truth), true_poses);
          std::printf("| %g | %g | %.1f%% | %.1f%% | %llu |\n", d_max, alpha, 100.0 * c.false_removed,
                      100.0 * c.true_kept, (unsigned long long)c.nodes_4d_realigned);
          std::fflush(stdout);
        }
      }
    }
  }

  if (sweep) {
    std::printf("\nsweep (epsilon %.3g, weights 1; the score of identical voxels 1 voxel apart is %.0f):\n",
                defaults.epsilon, realignScore(1.0, 0.0, 0.0, defaults));
    std::printf("| move | consensus occupied above | d_max | alpha | moved | false removed | true kept | nodes 4D |\n"
                "|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (auto move : {RealignSettings::Move::Swap, RealignSettings::Move::Transfer}) {
      for (double tau : {0.5, 0.999}) {
        for (double d_max : {1.0, 1.75, 2.0}) {
          for (double alpha : {2.0, 300.0, 1000.0, 2000.0, 3000.0, 5000.0}) {
            RealignSettings rs = defaults;
            rs.move = move;
            rs.consensus_occupied_above = tau;
            rs.alpha = alpha;
            rs.max_distance_voxels = d_max;
            const Run r = realignedRun(s.estimated, avg, rs, truth);
            const Outcome c = compare(plain, r, true_poses);
            std::printf("| %s | %g | %g | %g | %zu | %.1f%% | %.1f%% | %llu |\n", moveName(move), tau, d_max, alpha,
                        r.moved, 100.0 * c.false_removed, 100.0 * c.true_kept, (unsigned long long)r.nodes_4d);
            std::fflush(stdout);
          }
        }
      }
    }
  }
  return result;
}

}  // namespace

int main(int argc, char** argv) {
  {  // --seeds A-B: this program once per simulated seed, and the spread of its figures (seeds.h)
    SimulationSettings s;
    s.preset = "office";
    s.resolution_scale = 0.5;
    if (const int rc = bench::runOverSeeds(argc, argv, "--office", s); rc >= 0) return rc;
  }
  fs::path office, floor66;
  bool quick = false, skip_floor66 = false;
  CorrectionModel model = CorrectionModel::World;
  int drift_knots = 20;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--drift-knots") && i + 1 < argc) {
      drift_knots = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--register-model") && i + 1 < argc) {
      model = parseCorrectionModel(argv[++i]);
    } else if (!std::strcmp(argv[i], "--office") && i + 1 < argc) {
      office = argv[++i];
    } else if (!std::strcmp(argv[i], "--floor66") && i + 1 < argc) {
      floor66 = argv[++i];
    } else if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--skip-floor66")) {
      skip_floor66 = true;
    } else if (!std::strcmp(argv[i], "--sensor") && i + 1 < argc) {
      bench::setSimSensor(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: realign_eval [--office DIR] [--floor66 DIR] [--quick] [--skip-floor66] [--sensor ideal|kinect|realsense] "
                   "[--register-model world|per-pose] [--drift-knots FRAMES]\n");
      return 2;
    }
  }
  try {
    std::vector<fs::path> temporary;
    if (office.empty()) temporary.push_back(office = bench::simulateTemporary("office", "realign_eval"));
    const Evaluation o = evaluate("office", office, !quick, true, model, drift_knots);
    Evaluation f = o;
    if (!skip_floor66) {
      if (floor66.empty()) temporary.push_back(floor66 = bench::simulateTemporary("floor66", "realign_eval"));
      f = evaluate("floor66", floor66, false, false, model, drift_knots);
    }
    for (const auto& t : temporary) fs::remove_all(t);
    // The headline is the recommended step, registration (with the drift correction unless
    // --drift-knots 0): re-alignment after it removes more but trades true changes for false.
    std::printf("\n%s\n", nlohmann::json{{"preset", skip_floor66 ? "office" : "floor66"},
                                         {"register_model", toString(model)},
                                         {"drift_knot_frames", drift_knots},
                                         {"false_changes_removed", f.register_only.false_removed},
                                         {"true_changes_kept", f.register_only.true_kept},
                                         {"true_changes_kept_of_any_matched", f.register_only.true_kept_any},
                                         {"nodes_4d", f.register_only.nodes_4d},
                                         {"nodes_4d_realigned", f.register_only.nodes_4d_realigned},
                                         {"realign_only_false_changes_removed", f.realign_only.false_removed},
                                         {"realign_only_true_changes_kept", f.realign_only.true_kept},
                                         {"nodes_4d_realign_only", f.realign_only.nodes_4d_realigned},
                                         {"register_realign_false_changes_removed", f.pipeline.false_removed},
                                         {"register_realign_true_changes_kept", f.pipeline.true_kept},
                                         {"nodes_4d_register_realign", f.pipeline.nodes_4d_realigned},
                                         {"office_false_changes_removed", o.register_only.false_removed},
                                         {"office_true_changes_kept", o.register_only.true_kept},
                                         {"office_register_realign_false_changes_removed", o.pipeline.false_removed},
                                         {"office_register_realign_true_changes_kept", o.pipeline.true_kept}}
                              .dump()
                              .c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "realign_eval: %s\n", e.what());
    return 1;
  }
  return 0;
}
