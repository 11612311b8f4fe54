// chronomap simulate | demo: the simulated building, and the newcomer's first run on it.

#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/core/file.h"
#include "chronomap/core/format.h"
#include "chronomap/pipeline/demo.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/dynamic_map.h"
#include "commands.h"
#include "progress.h"

namespace chronomap::cli {

namespace {

struct SimulateOptions {
  SimulationSettings settings;
  std::string output;
  std::string format = "tum";
  DynamicMapSimSettings dynamic;  ///< --format dynamic-map: frames and people
  CLI::Option* resolution_scale = nullptr;  ///< given: dynamic-map takes it, else its own default
  bool json = false;
};

/// --format dynamic-map: the box room with people walking, as the dynamic-map benchmark's folders.
int runSimulateDynamicMap(const SimulateOptions& o) {
  DynamicMapSimSettings settings = o.dynamic;
  settings.seed = o.settings.seed;
  settings.noise_per_m2 = o.settings.noise_per_m2;
  if (o.resolution_scale->count() > 0) settings.resolution_scale = o.settings.resolution_scale;
  std::unique_ptr<ProgressBar> bar;
  const DynamicMapSimSummary s = simulateDynamicMap(settings, o.output, [&](size_t done, size_t total) {
    if (!bar && !o.json) bar = std::make_unique<ProgressBar>("simulating dynamic-map", total);
    if (bar) bar->update(done);
  });
  if (bar) bar->finish();
  if (o.json) {
    std::cout << nlohmann::json{{"format", "dynamic-map"}, {"seed", settings.seed},     {"frames", s.frames},
                                {"people", settings.people}, {"points", s.points},      {"dynamic_points", s.dynamic_points},
                                {"gt_points", s.gt_points},  {"gt_dynamic", s.gt_dynamic}, {"seconds", s.seconds},
                                {"output", o.output}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulated " << s.frames << " frames (" << settings.cameras << " cameras round) of the box room with "
              << settings.people << " people walking ("
              << s.points << " points, " << s.dynamic_points << " on people) in " << std::fixed << std::setprecision(1)
              << s.seconds << " s\n"
              << "  " << o.output << "/pcd/NNNNNN.pcd   frames in the world frame, the sensor pose in VIEWPOINT\n"
              << "  " << o.output << "/gt_cloud.pcd     " << s.gt_points << " points, intensity 1 on the "
              << s.gt_dynamic << " dynamic ones\n";
  }
  return 0;
}

int runSimulate(const SimulateOptions& o) {
  checkOutputs({{o.output, "-o", true}}, {});
  if (o.format == "dynamic-map") return runSimulateDynamicMap(o);
  std::unique_ptr<ProgressBar> bar;
  const SimulationSummary s = chronomap::simulate(o.settings, o.output, [&](size_t done, size_t total) {
    if (!bar) bar = std::make_unique<ProgressBar>("simulating " + o.settings.preset, total);
    bar->update(done);
  });
  if (bar) bar->finish();
  if (o.json) {
    std::cout << nlohmann::json{{"preset", o.settings.preset}, {"seed", o.settings.seed},
                                {"sessions", s.session_dirs.size()}, {"frames", s.frames},
                                {"events", s.events}, {"seconds", s.seconds}, {"output", o.output}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulated " << s.session_dirs.size() << " session(s) of the '" << o.settings.preset << "' preset ("
              << s.frames << " frames, " << s.events << " change events) in " << std::fixed << std::setprecision(1)
              << s.seconds << " s\n"
              << "  " << o.output << "/session_NN/   TUM RGB-D folders (trajectory.txt = estimated poses, "
              << "groundtruth.txt = true poses)\n"
              << "  " << o.output << "/truth/        objects and voxelised occupancy per session\n"
              << "  " << o.output << "/scene.json    sessions and every change event\n";
  }
  return 0;
}

// ------------------------------------------------------------------------------------------
// demo

struct DemoCmdOptions {
  DemoSettings settings;
  std::string output = "chronomap-demo";
  bool exact = false;
  bool json = false;
};

std::string percent(double v) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << 100.0 * v << "%";
  return s.str();
}

void printDemo(const DemoResult& r) {
  std::cout << "\nchronomap demo finished in " << std::fixed << std::setprecision(1) << r.seconds << " s\n"
            << "  " << countOf(r.sessions, "session") << ", " << countOf(r.frames, "frame") << ", "
            << countOf(r.events, "change event") << " simulated\n"
            << "  occupied voxels vs truth: precision " << percent(r.precision) << ", recall " << percent(r.recall)
            << " registered (as recorded: " << percent(r.precision_as_recorded) << ", "
            << percent(r.recall_as_recorded) << "; mean over sessions)\n"
            << "  4D map: " << r.nodes_4d << " nodes vs " << r.nodes_separate << " for the sessions stored separately\n"
            << "  changes: " << r.events_found << " of " << r.events_observable
            << " observed change events found as objects, " << r.false_components << " components match no event\n"
            << "  report:   " << r.report.string() << "\n"
            << "  pictures: " << r.images.string() << "/\n"
            << "  4D map:   " << r.map.string() << "\n"
            << "  tour:     " << r.tour.string() << " (open it in a browser; or: chronomap view " << r.map.string()
            << ")\n";
}

int runDemo(const DemoCmdOptions& o) {
  DemoSettings settings = o.settings;
  settings.output = o.output;
  checkOutputs({{settings.output, "-o", true}}, {});
  settings.fast = !o.exact;
  settings.progress = terminalProgress(o.json);
  const DemoResult r = chronomap::runDemo(settings);
  if (!o.json) {
    printDemo(r);
    return 0;
  }
  std::cout << nlohmann::json{{"output", settings.output.string()},
                              {"sessions", r.sessions},
                              {"frames", r.frames},
                              {"events", r.events},
                              {"nodes_4d", r.nodes_4d},
                              {"nodes_separate", r.nodes_separate},
                              {"precision", r.precision},
                              {"recall", r.recall},
                              {"precision_as_recorded", r.precision_as_recorded},
                              {"recall_as_recorded", r.recall_as_recorded},
                              {"changed_voxels", r.changed_voxels},
                              {"events_observable", r.events_observable},
                              {"events_found", r.events_found},
                              {"false_components", r.false_components},
                              {"seconds", r.seconds}}
                   .dump()
            << "\n";
  return 0;
}

/// --format and the dynamic-map sequence's own flags.
void addDynamicMapFlags(CLI::App* app, SimulateOptions& o) {
  app->add_option("--format", o.format,
                  "tum (the building's sessions) or dynamic-map (the box room with people walking, as the "
                  "dynamic-map benchmark's folders: pcd/*.pcd and a labelled gt_cloud.pcd; --frames, --people)")
      ->check(CLI::IsMember({"tum", "dynamic-map"}))
      ->capture_default_str();
  app->add_option("--frames", o.dynamic.frames, "dynamic-map: frames")->check(numberIn(1, 100000))->capture_default_str();
  app->add_option("--people", o.dynamic.people, "dynamic-map: people walking")->check(numberIn(0, 100))->capture_default_str();
}

}  // namespace

Command addSimulate(CLI::App& root) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* app = root.add_subcommand(
      "simulate",
      "Simulate a building recorded many times by a patrolling robot, with ground truth: one TUM RGB-D "
      "folder per session, the true occupancy and objects per session, and every change event.\n"
      "Presets: tiny (one room, 3 sessions), office (a corridor and three rooms, 6 sessions), floor66 "
      "(40 x 20 m, 16 rooms, 66 sessions over about 45 days), weeks (the office on a clock: doors, people, "
      "meetings, lunch and cleaning follow a weekly schedule with exceptions, kept in scene.json; 56 sessions, "
      "two a day at any hour for four weeks), site (three floors of floor66 patrolled every night for a year, "
      "365 sessions; --sessions N takes the first N).");
  app->add_option("--preset", o->settings.preset, "tiny, office, floor66, weeks or site")->capture_default_str();
  app->add_option("-o,--output", o->output, "folder to write")->required();
  app->add_option("--seed", o->settings.seed, "random seed (same seed, same bytes)")
      ->check(numberIn(0, 1e19))
      ->capture_default_str();
  app->add_option("--sessions", o->settings.sessions, "number of sessions (0 = the preset's)")->capture_default_str();
  app->add_option("--floors", o->settings.floors, "site only: floors stacked and patrolled (1 to 50)")
      ->check(numberIn(1, 50))
      ->capture_default_str();
  o->resolution_scale = app->add_option("--resolution-scale", o->settings.resolution_scale,
                                        "image size relative to 640 x 480 (0.1 .. 1; smaller is faster; "
                                        "dynamic-map: each camera's, default 0.25)")
                            ->capture_default_str();
  app->add_option("--sensor", o->settings.sensor,
                  "the depth camera and odometry imitated: ideal (sigma = NOISE * z^2, dropouts at edges and on "
                  "dark surfaces, a localiser's offset and small drift; the default, as before), kinect (Kinect v1: "
                  "published noise growing with depth and incidence, disparity steps, lateral noise, 0.5-4.5 m, no "
                  "depth at grazing incidence, dark and shiny surfaces lost or centimetres off, flying pixels at "
                  "depth edges, poses from a drifting odometry in trajectory.txt) or realsense (the same with "
                  "D435-like constants, 0.3-6 m); the truth and groundtruth.txt do not change; see docs/simulator.md")
      ->check(CLI::IsMember({"ideal", "kinect", "realsense"}))
      ->capture_default_str();
  app->add_option("--noise", o->settings.noise_per_m2,
                  "ideal sensor: depth noise sigma = NOISE * z^2, metres (0 to 1)")
      ->check(numberIn(0, 1))
      ->capture_default_str();
  app->add_option("--threads", o->settings.threads, "rendering threads, 0 = all cores (output does not depend on it)")
      ->check(numberIn(0, kMaxThreads))
      ->capture_default_str();
  app->add_option("--lighting", o->settings.lighting,
                  "fixed (one light colour per hour, the same everywhere) or daylight (lamps in working hours, "
                  "sun through the windows, warm at sunrise and sunset, none at night; the true curves go into "
                  "scene.json); only the colour images change")
      ->check(CLI::IsMember({"fixed", "daylight"}))
      ->capture_default_str();
  app->add_flag("--repaint", o->settings.repaint,
                "repaint a table (else a desk) that no routine moves a quarter of the sessions before the end (labelled in scene.json "
                "\"repaints\" with its voxels; the occupancy does not change)");
  app->add_flag("--rare-events", o->settings.rare_events,
                "weeks only: rare events on top of the routines in the last quarter of the sessions (a parcel left "
                "in the corridor at night, an item taken from a shelf, a door open at night, a chair in the "
                "corridor, a person at night), labelled \"rare\" in scene.json");
  addDynamicMapFlags(app, *o);
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runSimulate(*o); }};
}

Command addDemo(CLI::App& root) {
  auto o = std::make_shared<DemoCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "demo",
      "The first thing to run: simulate the office preset, integrate every session, register the sessions to "
      "their consensus, build the 4D map, find what changed between sessions and which objects, and write "
      "report.md with pictures (top view of the map, a session's point cloud, a frame, the trajectory, the "
      "storage curve, the changes).");
  app->add_option("-o,--output", o->output, "folder to write")->capture_default_str();
  app->add_option("--seed", o->settings.seed, "random seed of the simulation")->capture_default_str();
  app->add_option("--resolution-scale", o->settings.resolution_scale, "image size relative to 640 x 480")->capture_default_str();
  app->add_flag("--exact", o->exact, "integrate with exact ray casting instead of fast mode (slower)");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runDemo(*o); }};
}

}  // namespace chronomap::cli
