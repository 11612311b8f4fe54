// How well the temporal models predict the rhythmic building (preset "weeks", issue 22): the
// sessions of the first weeks build a 4D map and the models learn from it; each later session's
// true occupancy (truth/occupancy_NN.cmap) then scores every model's prediction at that
// session's time, on the voxels that changed at least once while learning. Baselines: the
// latest snapshot of the learning weeks, and the mean occupancy over its sessions.
//
// Usage: rhythm_eval [--sim DIR] [--learn-days D] [--poses true|registered] [--scale S]
//   --seeds A-B    simulate seeds A to B (with --sensor NAME, through that sensor) and run once on each;
//                  prints every figure's mean, min and max (seeds.h). Train on 1-5, report 6-15.
//                    [--max-range M] [--min-changes N] [--robot-height H]
//   --sim DIR      a `chronomap simulate --preset weeks` output (default: simulated here, seed 1)
//   --learn-days   days of sessions to learn from (default 21: three weeks; the rest test)
//   --poses        true: integrate with the true poses; registered (default): the estimated
//                  poses registered to the consensus, as `chronomap build --register` does
//   --scale        image size of the simulation made here (default 0.25)
//   --sensor NAME  ideal (default), kinect or realsense: the sensor of the simulations made here
//                  (SimulationSettings::sensor); a folder given keeps its own
//   --max-range    integration range, metres (default 3, as chronomap build)
//   --no-carve     drop points beyond the range whole (default: free space carved along their
//                  rays up to the range, --carve-beyond-range)
//   --robot-height the top of the band the costmaps read, metres (default 1.8)
//   --z-min        its bottom, metres (default 0.05, as chronomap costmap)
//   --lethal       probability above which a cell is an obstacle (default 0.5, as chronomap costmap)
//   --min-occupied-sessions N  the combined model's cost map takes a modelled voxel for an obstacle
//                  only where the learning sessions saw it occupied at least N times
//                  (CostmapSettings::min_occupied_sessions; default 0: off)
//   --min-changes  model the voxels that changed at least this often while learning (default 1)
//   --no-groups    fit without grouping co-changing voxels into objects (RhythmGroupSettings)
//   --group-correlation C, --group-common N, --group-voxels N, --group-gain G: the grouping's
//                  settings
//   --endpoint-clearance M  plan from and to the truth's free cell nearest each room's centre
//                  that has only free cells within M metres (default 0.15: a spot the robot can
//                  stand on; 0, the default before 2026-12-02's third pass, takes the nearest free
//                  cell, at the edge of an obstacle's inflation, where a map one voxel thicker
//                  shuts it whatever it knows of the place's rhythm)
//   --save-map F   write the learning weeks' 4D map to F; --map F reads it instead of building it
//                  (the registered build takes minutes: this lets model changes be compared on
//                  the same map; F must come from the same simulation, poses and integration flags)
// Then navigation: plans between every pair of rooms at each test session's time on the latest
// snapshot, the mean map and the combined model's cost map, executed against the truth
// (RHYTHM_EVAL_DUMP=DIR writes every grid there as map_server files (raw mode),
// to load in ROS;
// RHYTHM_EVAL_PLANS=1 lists every plan that a map does not find or that the truth blocks).
// Prints tables and, last, one JSON object (brier_*, auc_* per model and baseline, nav_*).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/export/map_server.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/map4d.h"
#include "chronomap/sim/building.h"
#include "bench_sim.h"
#include "seeds.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

using bench::rocAuc;
using bench::seconds;

/// The truth of a session as a costmap on `like`'s grid: lethal where a true voxel lies in the
/// band, free elsewhere, inflated by the radius.
Costmap truthCostmap(const SessionMap& truth, const Costmap& like, const CostmapSettings& s) {
  Costmap c = like;
  std::fill(c.cost.begin(), c.cost.end(), int8_t{0});
  truth.forEachLeaf([&](const LeafView& leaf) {
    const Eigen::Vector3d p = truth.grid().centerOf(leaf.key);
    if (p.z() < s.z_min_m || p.z() > s.z_max_m || leaf.counters.state() != VoxelState::Occupied) return;
    if (const auto cell = c.cellOf(p.head<2>())) c.at(cell->x(), cell->y()) = Costmap::kLethal;
  });
  inflate(c, s.robot_radius_m);
  return c;
}

double pathLength(const std::vector<Eigen::Vector2i>& path, double resolution_m) {
  double length = 0;
  for (size_t i = 1; i < path.size(); ++i) length += (path[i] - path[i - 1]).cast<double>().norm() * resolution_m;
  return length;
}

/// The free cell of `truth` nearest to `p` (by cell distance) whose cells within `clearance_m`
/// are free too, if any.
std::optional<Eigen::Vector2i> nearestFree(const Costmap& truth, const Eigen::Vector2d& p, double clearance_m) {
  const int reach = static_cast<int>(std::floor(clearance_m / truth.resolution_m + 1e-9));
  auto clear = [&](int i, int j) {
    for (int dy = -reach; dy <= reach; ++dy) {
      for (int dx = -reach; dx <= reach; ++dx) {
        if (dx * dx + dy * dy > reach * reach) continue;
        const int x = i + dx, y = j + dy;
        if (x < 0 || y < 0 || x >= truth.width || y >= truth.height || truth.at(x, y) != 0) return false;
      }
    }
    return true;
  };
  std::optional<Eigen::Vector2i> best;
  double best_d = 1e18;
  for (int j = 0; j < truth.height; ++j) {
    for (int i = 0; i < truth.width; ++i) {
      if (truth.at(i, j) != 0) continue;
      const double d = (truth.centerOf({i, j}) - p).squaredNorm();
      if (d < best_d && clear(i, j)) {
        best_d = d;
        best = Eigen::Vector2i(i, j);
      }
    }
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  {  // --seeds A-B: this program once per simulated seed, and the spread of its figures (seeds.h)
    SimulationSettings s;
    s.preset = "weeks";
    s.resolution_scale = 0.25;
    if (const int rc = bench::runOverSeeds(argc, argv, "--sim", s); rc >= 0) return rc;
  }
  fs::path sim_dir;
  int learn_days = 21;
  std::string poses = "registered";
  double scale = 0.25;
  uint32_t min_changes = 1;
  double max_range_m = 3.0;
  bool carve = true;
  double floor_clearance_m = CostmapSettings{}.z_min_m;
  double lethal = CostmapSettings{}.lethal_probability;
  uint32_t min_occupied_sessions = CostmapSettings{}.min_occupied_sessions;
  double robot_height_m = 1.8;
  fs::path load_map, save_map;
  RhythmGroupSettings grouping;
  double endpoint_clearance_m = 0.15;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return bench::argValue(i, argc, argv); };
    if (a == "--sim") sim_dir = value();
    else if (a == "--learn-days") learn_days = std::stoi(value());
    else if (a == "--poses") poses = value();
    else if (a == "--scale") scale = std::stod(value());
    else if (a == "--max-range") max_range_m = std::stod(value());
    else if (a == "--no-carve") carve = false;
    else if (a == "--z-min") floor_clearance_m = std::stod(value());
    else if (a == "--lethal") lethal = std::stod(value());
    else if (a == "--min-occupied-sessions") min_occupied_sessions = static_cast<uint32_t>(std::stoul(value()));
    else if (a == "--robot-height") robot_height_m = std::stod(value());
    else if (a == "--no-groups") grouping.enabled = false;
    else if (a == "--group-correlation") grouping.min_correlation = std::stod(value());
    else if (a == "--group-common") grouping.min_common = static_cast<uint32_t>(std::stoul(value()));
    else if (a == "--group-gain") grouping.min_gain = std::stod(value());
    else if (a == "--group-voxels") grouping.min_voxels = static_cast<uint32_t>(std::stoul(value()));
    else if (a == "--endpoint-clearance") endpoint_clearance_m = std::stod(value());
    else if (a == "--map") load_map = value();
    else if (a == "--save-map") save_map = value();
    else if (a == "--min-changes") min_changes = static_cast<uint32_t>(std::stoul(value()));
    else if (a == "--sensor") bench::setSimSensor(value());
    else {
      std::fprintf(stderr, "usage: rhythm_eval [--sim DIR] [--learn-days D] [--poses true|registered] [--scale S] [--no-carve] "
                           "[--sensor ideal|kinect|realsense]\n");
      return 2;
    }
  }
  if (poses != "true" && poses != "registered") {
    std::fprintf(stderr, "--poses must be true or registered\n");
    return 2;
  }
  const auto started = std::chrono::steady_clock::now();
  fs::path tmp;
  if (sim_dir.empty()) {
    tmp = fs::temp_directory_path() / ("rhythm_eval_" + std::to_string(::getpid()));
    sim_dir = bench::simulateWeeks(tmp, scale, false);
  }
  const bench::WeeksSim weeks = bench::readWeeks(sim_dir, learn_days);
  const auto& scene = weeks.scene;
  const std::vector<double>& times = weeks.times;
  const std::vector<size_t>&learn = weeks.learn, &test = weeks.test;

  // The 4D map of the learning sessions, as the recommended pipeline builds it.
  const auto build_started = std::chrono::steady_clock::now();
  const TemporalMap map =
      !load_map.empty()
          ? readTemporalMap(load_map)
          : bench::buildWeeksMap(weeks, learn, poses == "true", max_range_m,
                                 (tmp.empty() ? fs::temp_directory_path() : tmp) /
                                     ("rhythm_eval_" + std::to_string(::getpid()) + ".cmap"),
                                 carve);
  const double build_s = seconds(build_started);
  if (!save_map.empty()) writeTemporalMap(save_map, map, nlohmann::json{{"poses", poses}});

  const auto fit_started = std::chrono::steady_clock::now();
  const RhythmModels models = fitRhythm(map, times[learn.front()], times[learn.back()], min_changes, grouping);
  const double fit_s = seconds(fit_started);
  size_t grouped = 0;
  for (const VoxelRhythm& v : models.voxels) grouped += v.group != VoxelRhythm::kNoGroup;
  std::printf("learned from %zu sessions (%d days, %s poses; built in %.1f s): %zu voxels changed, fitted in %.3f s, "
              "%.1f KiB saved (%zu bytes a voxel); %zu voxels predicted by %zu objects' profiles\n",
              learn.size(), learn_days, poses.c_str(), build_s, models.voxels.size(), fit_s,
              static_cast<double>(models.bytes()) / 1024.0, RhythmModels::kVoxelBytes, grouped, models.groups.size());

  // Score every unit voxel of the fitted cubes at every test session against the truth; keep
  // apart the voxels whose truth changes during the test sessions (the routines) from those
  // whose truth stays put (their changes in the map were the sensor's and the mapping's noise).
  const KeyGrid grid(0.05);
  std::vector<SessionMap> truths;
  for (size_t i : test) {
    char name[64];
    std::snprintf(name, sizeof name, "occupancy_%02zu.cmap", i);
    truths.push_back(readSessionMap(sim_dir / "truth" / name));
  }
  std::map<RhythmModel, double> brier, brier_varying, brier_static;
  std::map<RhythmModel, std::vector<std::pair<double, uint8_t>>> scored;
  size_t samples = 0, positives = 0, varying_samples = 0;
  for (const VoxelRhythm& v : models.voxels) {
    if (v.level != 0) continue;  // free cubes that changed as a whole: not voxels a robot meets
    std::vector<uint8_t> y(test.size());
    for (size_t k = 0; k < test.size(); ++k) y[k] = truths[k].stateOf(v.corner) == VoxelState::Occupied ? 1 : 0;
    const bool varies = std::count(y.begin(), y.end(), y[0]) != static_cast<long>(y.size());
    for (size_t k = 0; k < test.size(); ++k) {
      ++samples;
      positives += y[k];
      varying_samples += varies;
      for (RhythmModel m : kRhythmModels) {
        const double p = RhythmModels::predict(v, m, times[test[k]]);
        const double e = (p - y[k]) * (p - y[k]);
        brier[m] += e;
        (varies ? brier_varying : brier_static)[m] += e;
        scored[m].emplace_back(p, y[k]);
      }
    }
  }
  std::printf("%zu of the samples are of voxels whose truth changes during the test sessions\n", varying_samples);
  if (samples == 0) {
    std::fprintf(stderr, "no voxel changed while learning\n");
    return 1;
  }
  nlohmann::json out = {{"learn_sessions", learn.size()},
                        {"test_sessions", test.size()},
                        {"poses", poses},
                        {"voxels", models.voxels.size()},
                        {"samples", samples},
                        {"occupied_share", static_cast<double>(positives) / static_cast<double>(samples)},
                        {"fit_s", fit_s},
                        {"bytes_per_voxel", RhythmModels::kVoxelBytes},
                        {"grouped_voxels", grouped},
                        {"groups", models.groups.size()}};
  std::printf("%zu test sessions x voxels = %zu samples, %.1f%% occupied\n", test.size(), samples,
              100.0 * static_cast<double>(positives) / static_cast<double>(samples));
  std::printf("%-10s %8s %8s %16s %16s\n", "model", "Brier", "AUC", "Brier (varying)", "Brier (static)");
  double best_brier = 1e9, best_auc = 0;
  std::string best_name;
  for (RhythmModel m : kRhythmModels) {
    const double b = brier[m] / static_cast<double>(samples), auc = rocAuc(scored[m]);
    const double bv = brier_varying[m] / std::max<double>(1.0, static_cast<double>(varying_samples));
    const double bs = brier_static[m] / std::max<double>(1.0, static_cast<double>(samples - varying_samples));
    std::printf("%-10s %8.4f %8.4f %16.4f %16.4f\n", toString(m), b, auc, bv, bs);
    out[std::string("brier_varying_") + toString(m)] = bv;
    out[std::string("brier_") + toString(m)] = b;
    out[std::string("auc_") + toString(m)] = auc;
    if (m != RhythmModel::Latest && m != RhythmModel::Mean && b < best_brier) {
      best_brier = b;
      best_auc = auc;
      best_name = toString(m);
    }
  }
  // Navigation: plans between every pair of rooms at each test session's time on (a) the latest
  // snapshot of the learning weeks, (b) the mean map, (c) the cost map of the combined model
  // with change costs, each executed against that session's true occupancy (inflated alike).
  CostmapSettings nav;
  nav.robot_radius_m = 0.25;
  nav.z_max_m = robot_height_m;
  nav.z_min_m = floor_clearance_m;
  nav.lethal_probability = lethal;
  nav.min_occupied_sessions = min_occupied_sessions;
  const SessionMap latest = map.snapshot(times[learn.back()]);
  struct Planner {
    const char* name;
    size_t plans = 0, failed = 0, blocked = 0, endpoint_closed = 0;
    double length_ratio_sum = 0;
    size_t feasible = 0;
  };
  Planner planners[3] = {{"latest"}, {"mean"}, {"costmap"}};
  std::vector<Eigen::Vector2d> room_centres;
  std::vector<std::string> room_names;
  for (const auto& r : scene["rooms"]) {
    room_names.push_back(r.value("name", std::to_string(room_names.size())));
    room_centres.emplace_back(0.5 * (r["min"][0].get<double>() + r["max"][0].get<double>()),
                              0.5 * (r["min"][1].get<double>() + r["max"][1].get<double>()));
  }
  CostmapSettings plain = nav;
  plain.change_weight = 0.0;
  const Costmap latest_cost = costmap(latest, plain);
  const bool list_plans = std::getenv("RHYTHM_EVAL_PLANS") != nullptr;
  for (size_t k = 0; k < test.size(); ++k) {
    const double t = times[test[k]];
    const std::string when_text = formatTime(t);
    const char* when = when_text.c_str();
    const Costmap maps[3] = {latest_cost, costmap(predictMap(map, models, RhythmModel::Mean, t), plain),
                             costmap(predictMap(map, models, RhythmModel::Combined, t), nav, &models)};
    for (int p = 0; p < 3; ++p) {
      const Costmap truth = truthCostmap(truths[k], maps[p], nav);
      if (std::getenv("RHYTHM_EVAL_DUMP")) {  // every test session's grids, for a look
        writeMapServer(fs::path(std::getenv("RHYTHM_EVAL_DUMP")) / (std::string(planners[p].name) + std::to_string(k) + ".yaml"), maps[p]);
        writeMapServer(fs::path(std::getenv("RHYTHM_EVAL_DUMP")) / (std::string(planners[p].name) + std::to_string(k) + "_truth.yaml"), truth);
      }
      Costmap open_truth = truth;  // the shortest feasible path: distance only
      for (auto& c : open_truth.cost) c = c == 0 ? 0 : Costmap::kLethal;
      for (size_t a = 0; a < room_centres.size(); ++a) {
        for (size_t b = a + 1; b < room_centres.size(); ++b) {
          const auto start = nearestFree(truth, room_centres[a], endpoint_clearance_m),
                     goal = nearestFree(truth, room_centres[b], endpoint_clearance_m);
          if (!start || !goal) continue;
          const auto shortest = planPath(open_truth, *start, *goal);
          if (!shortest) continue;  // no way through at that time (a shut door): nothing to score
          Planner& pl = planners[p];
          ++pl.plans;
          const auto path = planPath(maps[p], *start, *goal);
          if (!path) {
            ++pl.failed;
            // The usual reason: the start or goal (the truth's free cell nearest the room's centre,
            // often at the edge of a table's inflation) is inscribed or lethal on this map.
            const auto closed = [&](const Eigen::Vector2i& c) {
              return maps[p].at(c.x(), c.y()) >= Costmap::kInscribed;
            };
            pl.endpoint_closed += closed(*start) || closed(*goal);
            if (list_plans) {
              std::printf("plan %s session %zu %s %s to %s: no plan\n", pl.name, test[k], when, room_names[a].c_str(),
                          room_names[b].c_str());
            }
            continue;
          }
          bool hit = false;
          for (const auto& c : *path) hit |= truth.at(c.x(), c.y()) != 0;
          if (hit) {
            if (list_plans) {
              std::printf("plan %s session %zu %s %s to %s: blocked\n", pl.name, test[k], when, room_names[a].c_str(),
                          room_names[b].c_str());
            }
            ++pl.blocked;
            continue;
          }
          ++pl.feasible;
          pl.length_ratio_sum += pathLength(*path, truth.resolution_m) / pathLength(*shortest, truth.resolution_m);
        }
      }
    }
  }
  std::printf("navigation (robot radius %.2f m, height %.2f m, rooms' centres pairwise, %zu test sessions):\n",
              nav.robot_radius_m, nav.z_max_m, test.size());
  std::printf("%-10s %6s %8s %18s %8s %14s\n", "map", "plans", "no plan", "(endpoint closed)", "blocked",
              "length ratio");
  for (const Planner& pl : planners) {
    const double ratio = pl.feasible ? pl.length_ratio_sum / static_cast<double>(pl.feasible) : 0.0;
    std::printf("%-10s %6zu %8zu %18zu %8zu %14.3f\n", pl.name, pl.plans, pl.failed, pl.endpoint_closed, pl.blocked,
                ratio);
    const std::string n = pl.name;
    out["nav_plans_" + n] = pl.plans;
    out["nav_failed_" + n] = pl.failed;
    out["nav_failed_endpoint_" + n] = pl.endpoint_closed;
    // Of the routes feasible in the truth, the share this map plans at all (issue 44's target:
    // at least 0.9 for the cost map, beside blocked plans at most half the latest snapshot's).
    out["nav_found_" + n] = pl.plans ? static_cast<double>(pl.plans - pl.failed) / static_cast<double>(pl.plans) : 0.0;
    out["nav_blocked_" + n] = pl.plans ? static_cast<double>(pl.blocked) / static_cast<double>(pl.plans) : 0.0;
    out["nav_length_ratio_" + n] = ratio;
  }
  out["nav_length_ratio"] = out["nav_length_ratio_costmap"];
  out["nav_endpoint_clearance_m"] = endpoint_clearance_m;

  out["best"] = best_name;
  out["brier_best"] = best_brier;
  out["auc_best"] = best_auc;
  const double baseline = std::min(out["brier_latest"].get<double>(), out["brier_mean"].get<double>());
  out["brier_best_over_baseline"] = best_brier / baseline;
  std::printf("best: %s, Brier %.4f = %.2fx the better baseline's, AUC %.3f (%.0f s in all)\n", best_name.c_str(),
              best_brier, best_brier / baseline, best_auc, seconds(started));
  std::error_code ec;
  if (!tmp.empty()) fs::remove_all(tmp, ec);
  std::printf("%s\n", out.dump().c_str());
  return 0;
}
