// chronomap alerts: the changed objects of a session ranked by how unusual their change was
// under the history of the place (thesis §3.3), with reasons, pictures and PLYs.

#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/format.h"
#include "chronomap/analysis/alerts.h"
#include "chronomap/core/time.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/alerts.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

struct AlertsCmdOptions {
  std::string map, at, history_to, output;
  size_t top = 10;
  uint64_t min_voxels = AlertSettings{}.segment.min_voxels;
  int neighbourhood = AlertSettings{}.neighbourhood_voxels;
  bool json = false;
};

int runAlerts(const AlertsCmdOptions& o) {
  requireExtension(o.map, ".cmap", "4D map");
  const double t = parseTime(o.at);
  AlertSettings settings;
  settings.segment.min_voxels = o.min_voxels;
  settings.neighbourhood_voxels = o.neighbourhood;
  if (!o.history_to.empty()) settings.history_to_s = parseTime(o.history_to);
  settings.validate();
  checkOutputs({{o.output, "-o", true}}, {o.map});
  const TemporalMap map = readTemporalMap(o.map);
  const AlertReport report = findAlerts(map, t, settings);
  if (!o.output.empty()) writeAlerts(o.output, map, report, o.top, o.map);
  const nlohmann::json summary = alertsJson(report, o.top);
  if (o.json) {
    std::cout << summary.dump() << "\n";
    return 0;
  }
  std::printf("%s at %s (against %s; %s of history)\n", countOf(report.alerts.size(), "changed object").c_str(),
              formatTime(report.time_s).c_str(), formatTime(report.previous_time_s).c_str(),
              countOf(report.history_sessions, "session").c_str());
  const size_t n = o.top == 0 ? report.alerts.size() : std::min(o.top, report.alerts.size());
  for (size_t i = 0; i < n; ++i) {
    const Alert& a = report.alerts[i];
    const Component& c = a.component;
    std::printf("%3zu. %5.1f bits  %-8s %6llu voxels at (%.2f, %.2f, %.2f): %s\n", i + 1, a.score_bits,
                toString(c.kind), static_cast<unsigned long long>(c.voxels), c.centroid_m.x(), c.centroid_m.y(),
                c.centroid_m.z(), a.reason.c_str());
  }
  if (!o.output.empty()) {
    std::printf("wrote alerts.json, alerts.png and a picture and PLY per object (alert_NN.*) to %s\n",
                o.output.c_str());
  }
  return 0;
}

}  // namespace

Command addAlerts(CLI::App& root) {
  auto o = std::make_shared<AlertsCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "alerts",
      "Which changes of a session are unusual (docs/alerts.md): the session at --at is compared with the "
      "session before it, each changed object (a connected component of the diff) is scored by how unlikely "
      "its change was under the earlier observations of its space and of the space around it at that time "
      "of day, and the objects are listed from the most unusual, each with the evidence in words. "
      "-o writes alerts.json, alerts.png (the place from above, the objects framed and numbered by rank) "
      "and per object a framed top view and a PLY.");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("--at", o->at, "the session's time: ISO-8601 or seconds since the epoch (a session of the map)")
      ->required();
  app->add_option("--top", o->top, "list and write the K most unusual objects (0: all)")
      ->check(numberIn(0, 1e6))
      ->capture_default_str();
  app->add_option("--history-to", o->history_to,
                  "only sessions before this time are history (default: every session before --at)");
  app->add_option("--min-voxels", o->min_voxels, "smaller changed components are not objects")
      ->check(numberIn(1, 1e12))
      ->capture_default_str();
  app->add_option("--neighbourhood", o->neighbourhood,
                  "voxels: the history of the space this close counts as evidence (0..6)")
      ->check(numberIn(0, 6))
      ->capture_default_str();
  app->add_option("-o,--output", o->output, "folder for alerts.json, alerts.png and alert_NN.png/.ply");
  app->add_flag("--json", o->json, "print the ranked objects as JSON on stdout");
  return {app, [o] { return runAlerts(*o); }};
}

}  // namespace chronomap::cli
