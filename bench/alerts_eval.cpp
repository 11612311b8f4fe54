// Which changes are unusual (issue 23): the rhythmic building (preset "weeks") with rare events,
// every session in one 4D map; each test session's changed objects scored by findAlerts() with
// the learning days as history, and matched to the truth's events (scoreChanges): objects of
// rare events against objects of routine ones. ROC AUC and precision among the top k (k = the
// objects of rare events) over all test sessions pooled; baselines: the object's size alone
// (bigger is more unusual) and its voxels' change count while learning alone (fewer changes is
// more unusual).
//
// Usage: alerts_eval [--sim DIR] [--learn-days D] [--poses true|registered] [--scale S]
//   --seeds A-B    simulate seeds A to B (with --sensor NAME, through that sensor) and run once on each;
//                  prints every figure's mean, min and max (seeds.h). Train on 1-5, report 6-15.
//                    [--max-range M] [--out DIR]
//   --sim DIR      a `chronomap simulate --preset weeks --rare-events` output (default: simulated
//                  here, seed 1)
//   --learn-days   days whose sessions are history (default 21: three weeks; the rest test)
//   --poses        true: integrate with the true poses; registered (default): as
//                  `chronomap build --register`
//   --scale        image size of the simulation made here (default 0.25)
//   --sensor NAME  ideal (default), kinect or realsense: the sensor of the simulations made here
//                  (SimulationSettings::sensor); a folder given keeps its own
//   --max-range    integration range, metres (default 3, as chronomap build)
//   --out DIR      also write `chronomap alerts -o` output per test session (DIR/session_NN)
//   --free-share S, --all-hours-observations K, --no-moves: AlertSettings other than the
//                  defaults (to see what each rule does)
//   --map FILE     keep the 4D map of every session there: read it when it exists, else build
//                  and write it (the registered build takes most of the time)
// Prints a table per scored object and, last, one JSON object (alerts_auc,
// alerts_precision_at_k, alerts_auc_size_only, alerts_auc_count_only, ...).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "bench_sim.h"
#include "seeds.h"
#include "chronomap/analysis/alerts.h"
#include "chronomap/core/time.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/alerts.h"
#include "chronomap/sim/change_truth.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

struct Scored {
  double score = 0, own = 0, size = 0, count = 0;
  int label = -1;  // 1 rare, 0 routine, -1 matched no event or an event's undoing
  std::string what;
};

/// Share of the first k by `key` (descending; ties by order) that are rare, among labelled ones.
double precisionAtK(std::vector<Scored> s, double Scored::*key, size_t k) {
  std::stable_sort(s.begin(), s.end(), [&](const Scored& a, const Scored& b) { return a.*key > b.*key; });
  size_t rare = 0;
  for (size_t i = 0; i < k && i < s.size(); ++i) rare += s[i].label == 1;
  return k ? static_cast<double>(rare) / static_cast<double>(k) : 0.0;
}

double auc(const std::vector<Scored>& s, double Scored::*key) {
  std::vector<std::pair<double, uint8_t>> v;
  for (const Scored& x : s) v.emplace_back(x.*key, static_cast<uint8_t>(x.label == 1));
  return bench::rocAuc(v);
}

}  // namespace

int main(int argc, char** argv) {
  {  // --seeds A-B: this program once per simulated seed, and the spread of its figures (seeds.h)
    SimulationSettings s;
    s.preset = "weeks";
    s.resolution_scale = 0.25;
    s.rare_events = true;
    if (const int rc = bench::runOverSeeds(argc, argv, "--sim", s); rc >= 0) return rc;
  }
  fs::path sim_dir, out_dir, map_file;
  int learn_days = 21;
  std::string poses = "registered";
  double scale = 0.25, max_range_m = 3.0;
  AlertSettings defaults;
  double free_share = defaults.free_share, all_hours = defaults.evidence.all_hours_observations;
  bool pair_moves = defaults.moves.pair;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return bench::argValue(i, argc, argv); };
    if (a == "--sim") sim_dir = value();
    else if (a == "--learn-days") learn_days = std::stoi(value());
    else if (a == "--poses") poses = value();
    else if (a == "--scale") scale = std::stod(value());
    else if (a == "--max-range") max_range_m = std::stod(value());
    else if (a == "--out") out_dir = value();
    else if (a == "--map") map_file = value();
    else if (a == "--free-share") free_share = std::stod(value());
    else if (a == "--all-hours-observations") all_hours = std::stod(value());
    else if (a == "--no-moves") pair_moves = false;
    else if (a == "--sensor") bench::setSimSensor(value());
    else {
      std::fprintf(stderr, "usage: alerts_eval [--sim DIR] [--learn-days D] [--poses true|registered] [--scale S] "
                           "[--max-range M] [--out DIR] [--map FILE] [--free-share S] [--all-hours-observations K] "
                           "[--no-moves] [--sensor ideal|kinect|realsense]\n");
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
    tmp = fs::temp_directory_path() / ("alerts_eval_" + std::to_string(::getpid()));
    sim_dir = bench::simulateWeeks(tmp, scale, true);
  }
  const bench::WeeksSim weeks = bench::readWeeks(sim_dir, learn_days);
  const std::vector<ChangeEvent> events = readTruthEvents(sim_dir / "scene.json");
  std::vector<size_t> all(weeks.times.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  const auto build_started = std::chrono::steady_clock::now();
  // --map FILE: the 4D map built once and kept (read when it exists, else built and written).
  auto buildMap = [&]() -> TemporalMap {
    if (!map_file.empty() && fs::exists(map_file)) return readTemporalMap(map_file);
    TemporalMap m = bench::buildWeeksMap(weeks, all, poses == "true", max_range_m,
                                         (tmp.empty() ? fs::temp_directory_path() : tmp) /
                                             ("alerts_eval_" + std::to_string(::getpid()) + ".cmap"));
    if (!map_file.empty()) writeTemporalMap(map_file, m, {{"created_by", "alerts_eval"}, {"poses", poses}});
    return m;
  };
  const TemporalMap map = buildMap();
  const double build_s = bench::seconds(build_started);
  std::printf("built the 4D map of %zu sessions (%s poses) in %.0f s; history: the %zu sessions of the first %d days\n",
              all.size(), poses.c_str(), build_s, weeks.learn.size(), learn_days);

  AlertSettings settings;
  settings.history_to_s = weeks.split_s;
  settings.free_share = free_share;
  settings.evidence.all_hours_observations = all_hours;
  settings.moves.pair = pair_moves;
  std::vector<Scored> scored;
  size_t unmatched = 0, undoing = 0, rare_events = 0, rare_found = 0;
  double alert_s = 0;
  std::printf("| session | time | rank | score (bits) | own (bits) | voxels | kind | truth | reason |\n"
              "|---:|---|---:|---:|---:|---:|---|---|---|\n");
  for (size_t t : weeks.test) {
    const double time_s = weeks.times[t];
    const auto alert_started = std::chrono::steady_clock::now();
    const AlertReport report = findAlerts(map, time_s, settings);
    alert_s += bench::seconds(alert_started);
    const SessionMap before = map.snapshot(report.previous_time_s), after = map.snapshot(time_s);
    const std::vector<ChangeEvent> here = eventsFrom(events, static_cast<uint32_t>(t - 1));
    const ChangeScore truth = scoreChanges(report.diff, report.segmentation, here, before, after);
    for (const ChangeEvent& e : here) rare_events += e.cause == "rare";
    std::vector<bool> rare_seen(here.size(), false);
    for (size_t rank = 0; rank < report.alerts.size(); ++rank) {
      const Alert& a = report.alerts[rank];
      // The component's index in the segmentation (component_event is in that order).
      const auto& comps = report.segmentation.components;
      size_t ci = 0;
      while (ci < comps.size() && comps[ci].id != a.component.id) ++ci;
      const int ev = ci < truth.component_event.size() ? truth.component_event[ci] : -1;
      Scored s;
      s.score = a.score_bits;
      s.own = a.own_score_bits;
      s.size = static_cast<double>(a.component.voxels);
      // Change count: the mean number of stored changes of its voxels within the history.
      double changes = 0;
      size_t n = 0;
      for (uint32_t cell : a.component.cells) {
        const VoxelKey& k = report.diff.cells()[cell].key;
        const auto h = map.history(k);
        size_t c = 0;
        for (size_t i = 1; i < h.size(); ++i) c += h[i].time_s < weeks.split_s;
        changes += static_cast<double>(c);
        ++n;
      }
      s.count = -(n ? changes / static_cast<double>(n) : 0.0);
      std::string label = "none";
      if (ev >= 0) {
        const ChangeEvent& e = here[static_cast<size_t>(ev)];
        label = e.cause + ": " + (e.routine.empty() ? std::string(toString(e.object_kind)) : e.routine) + " " +
                toString(e.kind);
        if (e.cause == "rare") {
          s.label = 1;
          rare_seen[static_cast<size_t>(ev)] = true;
        } else if (e.cause == "routine") {
          s.label = 0;
        } else {
          ++undoing;
        }
      } else {
        ++unmatched;
      }
      s.what = label;
      scored.push_back(s);
      std::printf("| %zu | %s | %zu | %.1f | %.1f | %llu | %s | %s | %s |\n", t, formatTime(time_s).substr(5, 11).c_str(),
                  rank + 1, a.score_bits, a.own_score_bits, static_cast<unsigned long long>(a.component.voxels),
                  toString(a.component.kind), label.c_str(), a.reason.c_str());
    }
    for (size_t i = 0; i < here.size(); ++i) rare_found += rare_seen[i];
    if (!out_dir.empty()) {
      char name[32];
      std::snprintf(name, sizeof name, "session_%02zu", t);
      writeAlerts(out_dir / name, map, report, 10, "");
    }
  }
  std::vector<Scored> labelled;
  for (const Scored& s : scored) {
    if (s.label >= 0) labelled.push_back(s);
  }
  size_t k = 0;
  for (const Scored& s : labelled) k += s.label == 1;
  // Every object scored: those that matched no event, and the undoing of rare events, as routine.
  std::vector<Scored> every = scored;
  for (Scored& s : every) s.label = s.label == 1 ? 1 : 0;
  nlohmann::json out = {{"poses", poses},
                        {"free_share", free_share},
                        {"all_hours_observations", all_hours},
                        {"learn_sessions", weeks.learn.size()},
                        {"test_sessions", weeks.test.size()},
                        {"objects", scored.size()},
                        {"objects_rare", k},
                        {"objects_routine", labelled.size() - k},
                        {"objects_unmatched", unmatched},
                        {"objects_undoing_rare", undoing},
                        {"rare_events", rare_events},
                        {"rare_events_found", rare_found},
                        {"alerts_auc", auc(labelled, &Scored::score)},
                        {"alerts_precision_at_k", precisionAtK(labelled, &Scored::score, k)},
                        {"alerts_auc_unpaired", auc(labelled, &Scored::own)},
                        {"alerts_precision_at_k_unpaired", precisionAtK(labelled, &Scored::own, k)},
                        {"alerts_auc_size_only", auc(labelled, &Scored::size)},
                        {"alerts_precision_at_k_size_only", precisionAtK(labelled, &Scored::size, k)},
                        {"alerts_auc_count_only", auc(labelled, &Scored::count)},
                        {"alerts_precision_at_k_count_only", precisionAtK(labelled, &Scored::count, k)},
                        {"alerts_auc_every_object", auc(every, &Scored::score)},
                        {"alerts_precision_at_k_every_object", precisionAtK(every, &Scored::score, k)},
                        {"alerts_s_per_session", alert_s / static_cast<double>(weeks.test.size())},
                        {"build_s", build_s},
                        {"seconds", bench::seconds(started)}};
  std::printf("\n%zu objects in %zu test sessions: %zu of rare events, %zu of routine ones, %zu of the undoing of a "
              "rare event, %zu matching no event; %zu of %zu rare events found\n",
              scored.size(), weeks.test.size(), k, labelled.size() - k, undoing, unmatched, rare_found, rare_events);
  std::printf("| scoring | AUC rare vs routine | precision at k=%zu |\n|---|---:|---:|\n", k);
  std::printf("| unusualness | %.3f | %.3f |\n", out["alerts_auc"].get<double>(),
              out["alerts_precision_at_k"].get<double>());
  std::printf("| unusualness, moves not paired | %.3f | %.3f |\n", out["alerts_auc_unpaired"].get<double>(),
              out["alerts_precision_at_k_unpaired"].get<double>());
  std::printf("| size only | %.3f | %.3f |\n", out["alerts_auc_size_only"].get<double>(),
              out["alerts_precision_at_k_size_only"].get<double>());
  std::printf("| change count only | %.3f | %.3f |\n", out["alerts_auc_count_only"].get<double>(),
              out["alerts_precision_at_k_count_only"].get<double>());
  std::printf("| unusualness, every object (unmatched as routine) | %.3f | %.3f |\n",
              out["alerts_auc_every_object"].get<double>(), out["alerts_precision_at_k_every_object"].get<double>());
  std::error_code ec;
  if (!tmp.empty()) fs::remove_all(tmp, ec);
  std::printf("%s\n", out.dump().c_str());
  return 0;
}
