// chronomap simulate | demo: the simulated building, and the newcomer's first run on it.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/dataset.h"
#include "chronomap/io/export.h"
#include "chronomap/io/file.h"
#include "chronomap/io/plot.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/io/diff_file.h"
#include "chronomap/sim/change_truth.h"
#include "chronomap/sim/building.h"
#include "commands.h"
#include "progress.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

struct SimulateOptions {
  sim::SimulationSettings settings;
  std::string output;
  bool json = false;
};

int runSimulate(const SimulateOptions& o) {
  std::unique_ptr<ProgressBar> bar;
  const sim::SimulationSummary s = sim::simulate(o.settings, o.output, [&](size_t done, size_t total) {
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

// The demo's registration: as the README's `build --register --register-drift 20`.
constexpr int kDemoRegisterRounds = 3;
constexpr int kDemoDriftKnots = 20;

struct DemoOptions {
  std::string output = "chronomap-demo";
  uint64_t seed = 1;
  double resolution_scale = 0.5;
  bool exact = false;
  bool json = false;
};

io::ImageRgb colorizeDepth(const io::ImageU16& depth, double scale) {
  io::ImageRgb img;
  img.width = depth.width;
  img.height = depth.height;
  img.pixels.resize(depth.pixels.size());
  for (size_t i = 0; i < depth.pixels.size(); ++i) {
    if (depth.pixels[i] == 0) {
      img.pixels[i] = Rgb{0, 0, 0};
      continue;
    }
    const double t = std::clamp(depth.pixels[i] / scale / 5.0, 0.0, 1.0);  // 0..5 m
    auto c = [](double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); };
    img.pixels[i] = Rgb{c(1.5 - std::abs(4.0 * t - 3.0)), c(1.5 - std::abs(4.0 * t - 2.0)), c(1.5 - std::abs(4.0 * t - 1.0))};
  }
  return img;
}

// Points of one session seen from above: each pixel shows the highest point in its colour.
io::ImageRgb cloudTopView(const io::Dataset& dataset, double metres_per_pixel) {
  std::vector<Eigen::Vector3f> points;
  std::vector<Rgb> colors;
  for (size_t i = 0; i < dataset.size(); ++i) {
    const Frame f = dataset.load(i);
    for (size_t k = 0; k < f.cloud.size(); k += 2) {
      const Eigen::Vector3f& p = f.cloud.points[k];
      if (!p.allFinite()) continue;
      points.push_back((f.T_world_sensor * p.cast<double>()).cast<float>());
      colors.push_back(f.cloud.hasColors() ? f.cloud.colors[k] : Rgb{200, 200, 200});
    }
  }
  if (points.empty()) throw DataError("the session has no valid points to draw");
  Eigen::Vector3f lo = points[0], hi = points[0];
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  io::ImageRgb img;
  img.width = static_cast<uint32_t>(std::min(4000.0, std::ceil((hi.x() - lo.x()) / metres_per_pixel) + 1));
  img.height = static_cast<uint32_t>(std::min(4000.0, std::ceil((hi.y() - lo.y()) / metres_per_pixel) + 1));
  img.pixels.assign(size_t{img.width} * img.height, Rgb{255, 255, 255});
  std::vector<float> top(img.pixels.size(), -1e9f);
  for (size_t i = 0; i < points.size(); ++i) {
    const auto u = static_cast<int64_t>((points[i].x() - lo.x()) / metres_per_pixel);
    const auto v = static_cast<int64_t>((hi.y() - points[i].y()) / metres_per_pixel);
    if (u < 0 || v < 0 || u >= img.width || v >= img.height) continue;
    const size_t at = static_cast<size_t>(v) * img.width + static_cast<size_t>(u);
    if (points[i].z() > top[at]) {
      top[at] = points[i].z();
      img.pixels[at] = colors[i];
    }
  }
  return img;
}

std::vector<Eigen::Vector3d> readTrajectory(const fs::path& path) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : io::parseTumTrajectory(io::readTextFile(path), path.string())) out.push_back(p.pose.translation());
  return out;
}

std::string percent(double v) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << 100.0 * v << "%";
  return s.str();
}

int runDemo(const DemoOptions& o) {
  const auto started = std::chrono::steady_clock::now();
  const fs::path out = o.output;
  const fs::path images = out / "images";
  std::error_code ec;
  fs::create_directories(images, ec);
  if (ec) throw IoError(out.string() + ": cannot create folder (" + ec.message() + ")");
  auto step = [&](int n, const std::string& what) {
    if (!o.json) std::cerr << "[" << n << "/6] " << what << "\n";
  };

  // 1. Simulate the office.
  step(1, "simulating the 'office' preset: a corridor, an office, a kitchen and a meeting room");
  sim::SimulationSettings settings;
  settings.preset = "office";
  settings.seed = o.seed;
  settings.resolution_scale = o.resolution_scale;
  ProgressBar sim_bar("simulating", 6);
  const sim::SimulationSummary simulated =
      sim::simulate(settings, out / "data", [&](size_t done, size_t) { sim_bar.update(done); });
  sim_bar.finish();

  // 2. Integrate every session with the estimated poses, score against the truth.
  step(2, "integrating " + std::to_string(simulated.session_dirs.size()) + " sessions (" +
              (o.exact ? "exact" : "fast") + " mode, estimated poses)");
  fs::create_directories(out / "sessions", ec);
  IntegrateSettings is;
  is.fast = !o.exact;
  struct SessionResult {
    SessionMap map;
    IntegrationStats stats;
    sim::OccupancyScore score;             // with the poses as recorded
    sim::OccupancyScore registered_score;  // after registration (step 3)
    std::vector<VoxelKey> truth;           // the truth's occupied voxels
    std::vector<Eigen::Vector3d> sensor_positions;
  };
  std::vector<SessionResult> results;
  for (size_t s = 0; s < simulated.session_dirs.size(); ++s) {
    IntegratedSession i = integrateDataset(simulated.session_dirs[s].string(), is, "session " + std::to_string(s));
    char truth_name[64];
    std::snprintf(truth_name, sizeof truth_name, "occupancy_%02zu.cmap", s);
    const SessionMap truth_map = io::readSessionMap(out / "data" / "truth" / truth_name);
    std::vector<VoxelKey> truth;
    truth_map.forEachLeaf([&](const LeafView& l) { truth.push_back(l.key); });
    const sim::OccupancyScore score = sim::scoreOccupancy(i.map, truth);
    results.push_back({std::move(i.map), i.stats, score, {}, std::move(truth), std::move(i.sensor_positions)});
  }

  // 3. Registration: every session against the consensus of all six, integrated again with its
  // correction (as `chronomap build --register --register-drift 20 --register-planar
  // --register-points`).
  step(3, "registering the sessions to their consensus (x, y and heading; drift per frame, fitted on points)");
  RegisterSettings register_settings;
  register_settings.drift_knot_frames = kDemoDriftKnots;
  register_settings.planar = true;
  register_settings.drift_points = true;
  {
    std::vector<SessionMap> maps;
    std::vector<std::vector<Eigen::Vector3d>> positions;
    std::vector<std::string> paths;
    for (size_t s = 0; s < results.size(); ++s) {
      maps.push_back(std::move(results[s].map));
      positions.push_back(std::move(results[s].sensor_positions));
      paths.push_back(simulated.session_dirs[s].string());
    }
    registerDatasets(maps, paths, positions, is, kDemoRegisterRounds, register_settings);
    for (size_t s = 0; s < results.size(); ++s) {
      results[s].map = std::move(maps[s]);
      results[s].registered_score = sim::scoreOccupancy(results[s].map, results[s].truth);
      char name[64];
      std::snprintf(name, sizeof name, "session_%02zu.cmap", s);
      io::writeSessionMap(out / "sessions" / name, results[s].map,
                          {{"created_by", "chronomap demo"}, {"recorded_at", simulated.times_s[s]}, {"registered", true}});
    }
  }

  // 4. The 4D map.
  step(4, "building the 4D map of the registered sessions");
  TemporalMap map(results.front().map.resolution_m());
  for (size_t s = 0; s < results.size(); ++s) {
    char name[32];
    std::snprintf(name, sizeof name, "session_%02zu", s);
    map.add(simulated.times_s[s], results[s].map, AddOptions{false, name});
  }
  const fs::path map_path = out / "office.cmap";
  io::writeTemporalMap(map_path, map, {{"created_by", "chronomap demo"}});
  const TemporalCounts counts = map.counts();
  uint64_t separate = 0;
  for (const auto& s : map.sessions()) separate += s.nodes_separate;
  uint64_t changed_voxels = 0;
  map.forEachChangeCount(-1e300, 1e300, [&](const VoxelKey&, int level, uint32_t) {
    changed_voxels += uint64_t{1} << (3 * level);
  });

  // 5. What changed between consecutive sessions, and which objects: diff, segment, score.
  step(5, "finding what changed between consecutive sessions");
  fs::create_directories(out / "changes", ec);
  const std::vector<sim::ChangeEvent> truth_events = sim::readTruthEvents(out / "data" / "scene.json");
  DiffSettings diff_settings;
  diff_settings.mode = DiffMode::Band;
  diff_settings.neighbourhood_voxels = 1;
  diff_settings.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  SegmentSettings segment_settings;
  segment_settings.connectivity = Connectivity::Vertex;
  segment_settings.min_voxels = 20;
  sim::ChangeScore change_total;
  std::ostringstream changes_md;
  for (size_t k = 1; k < results.size(); ++k) {
    const std::vector<sim::ChangeEvent> pair_events = sim::eventsFrom(truth_events, static_cast<uint32_t>(k - 1));
    const DiffMap d = diff(results[k - 1].map, results[k].map, diff_settings);
    const Segmentation seg = segment(d, segment_settings);
    const sim::ChangeScore score = sim::scoreChanges(d, seg, pair_events, results[k - 1].map, results[k].map);
    change_total += score;
    char name[64];
    std::snprintf(name, sizeof name, "diff_%02zu_%02zu", k - 1, k);
    io::writeDiffMap(out / "changes" / (std::string(name) + ".cmap"), d, {{"created_by", "chronomap demo"}});
    io::TopViewSettings ctv;
    ctv.pixels_per_voxel = 3;
    io::writePng(images / (std::string(name) + ".png"), io::renderChangeView(results[k].map, d, seg, ctv));
    changes_md << "### Session " << k - 1 << " → " << k << "\n\n"
               << "The simulator made " << pair_events.size() << " changes (";
    for (size_t i = 0; i < pair_events.size(); ++i) {
      changes_md << (i ? ", " : "") << toString(pair_events[i].object_kind) << " " << toString(pair_events[i].kind);
    }
    changes_md << "); " << score.events_observable << " of them were observed in both sessions and "
               << score.events_found << " found. The diff holds " << score.changed_voxels
               << " changed voxels, in " << seg.components.size() << " components of at least "
               << segment_settings.min_voxels << " voxels (" << seg.dropped << " smaller ones dropped).\n\n"
               << "![Changes from session " << k - 1 << " to " << k << "](images/" << name << ".png)\n\n";
    if (!seg.components.empty()) {
      changes_md << "| id | kind | voxels | volume (litres) | centroid x, y, z (m) | size x, y, z (m) | colour | truth |\n"
                 << "|---|---|---|---|---|---|---|---|\n";
    }
    for (size_t c = 0; c < seg.components.size(); ++c) {
      const Component& comp = seg.components[c];
      const Eigen::Vector3d size = comp.bbox_max_m - comp.bbox_min_m;
      char line[256];
      std::snprintf(line, sizeof line, "| %u | %s | %llu | %.1f | %.2f, %.2f, %.2f | %.2f, %.2f, %.2f | #%02x%02x%02x | ",
                    comp.id, toString(comp.kind), static_cast<unsigned long long>(comp.voxels),
                    comp.volume_m3 * 1000.0, comp.centroid_m.x(), comp.centroid_m.y(), comp.centroid_m.z(), size.x(),
                    size.y(), size.z(), comp.mean_color.r, comp.mean_color.g, comp.mean_color.b);
      const int e = score.component_event[c];
      const sim::ChangeEvent* event = e >= 0 ? &pair_events[static_cast<size_t>(e)] : nullptr;
      changes_md << line
                 << (event ? std::string(toString(event->object_kind)) + " " + toString(event->kind)
                           : std::string("no event (false)"))
                 << " |\n";
    }
    changes_md << "\n";
  }

  // 6. Pictures and the report.
  step(6, "drawing the report");
  const double last = simulated.times_s.back();
  const SessionMap latest = map.snapshot(last);
  io::TopViewSettings tv;
  tv.pixels_per_voxel = 3;
  io::writePng(images / "map_topview.png", io::renderTopView(latest, tv));
  {
    io::DatasetOptions dopt;
    auto dataset = io::openDataset(simulated.session_dirs.front(), dopt);
    io::writePng(images / "session_00_cloud.png", cloudTopView(*dataset, 0.02));
  }
  {
    // One frame as recorded: colour and depth (from the middle of the first session).
    const auto names = io::parseStampedList(io::readTextFile(simulated.session_dirs.front() / "depth.txt"),
                                             "depth.txt");
    const auto& mid = names[names.size() / 2];
    fs::copy_file(simulated.session_dirs.front() / ("rgb/" + mid.name.substr(6)), images / "frame_rgb.png",
                  fs::copy_options::overwrite_existing);
    const io::ImageU16 depth = io::readPngU16(simulated.session_dirs.front() / mid.name);
    io::writePng(images / "frame_depth.png", colorizeDepth(depth, 5000.0));
  }
  {
    io::PlotSeries truth{"true path", Rgb{40, 90, 200}, {}, {}}, estimate{"estimated path", Rgb{220, 80, 40}, {}, {}};
    for (const auto& p : readTrajectory(simulated.session_dirs.front() / "groundtruth.txt")) {
      truth.x.push_back(p.x());
      truth.y.push_back(p.y());
    }
    for (const auto& p : readTrajectory(simulated.session_dirs.front() / "trajectory.txt")) {
      estimate.x.push_back(p.x());
      estimate.y.push_back(p.y());
    }
    io::PlotSettings ps;
    ps.title = "Session 0: camera path";
    ps.x_label = "x (m)";
    ps.y_label = "y (m)";
    io::writePng(images / "trajectory.png", io::renderLinePlot({truth, estimate}, ps));
  }
  writeStoragePlot((images / "storage.png").string(), map);

  std::ostringstream md;
  md << "# chronomap demo: the simulated office\n\n"
     << "The simulator built an office floor (a corridor, an office, a kitchen and a meeting room) and "
     << "recorded it " << results.size() << " times with a patrolling robot's Kinect-like camera ("
     << settings.resolution_scale * 640 << " x " << settings.resolution_scale * 480
     << " pixels, depth noise 1.4 mm z^2, localisation offset and drift). Between sessions doors opened and "
     << "closed, chairs and boxes moved, a person and another robot came and went: " << simulated.events
     << " change events, listed with their voxels in `data/scene.json`.\n\n"
     << "Each session was integrated into a session map (" << (o.exact ? "exact" : "fast")
     << " mode, 0.05 m voxels, the estimated poses a real robot would have) and scored against the "
     << "simulator's true occupancy. Then every session was registered to the consensus of all of them and "
     << "integrated again with its correction (x, y and heading, and the drift from frame to frame, fitted on "
     << "the sessions' points: `chronomap build --register --register-drift " << kDemoDriftKnots
     << " --register-planar --register-points`), scored again, and added to one 4D map, `office.cmap`.\n\n"
     << "## Sessions\n\n"
     << "| session | time | frames | points | occupied voxels | precision, as recorded | recall, as recorded "
        "| precision, registered | recall, registered | nodes added to the 4D map |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (size_t s = 0; s < results.size(); ++s) {
    md << "| " << s << " | " << formatTime(simulated.times_s[s]) << " | " << results[s].stats.frames << " | "
       << results[s].stats.points << " | " << results[s].registered_score.predicted << " | "
       << percent(results[s].score.precision) << " | " << percent(results[s].score.recall) << " | "
       << percent(results[s].registered_score.precision) << " | " << percent(results[s].registered_score.recall)
       << " | " << map.sessions()[s].nodes_added << " |\n";
  }
  md << "\nPrecision: occupied voxels of the session map that are occupied in the truth. Recall: truth "
     << "voxels the session observed that it found occupied. Both count exact voxels; the estimated "
     << "poses are off by a few centimetres, about a voxel, and registered by a few millimetres.\n\n"
     << "## The 4D map\n\n"
     << "- " << map.sessionCount() << " sessions, " << counts.nodes() << " nodes (" << counts.inner_nodes
     << " inner, " << counts.entries << " history entries); the session maps on their own hold " << separate
     << " nodes, so the 4D map needs " << percent(static_cast<double>(counts.nodes()) / static_cast<double>(separate))
     << " of that.\n"
     << "- " << changed_voxels << " voxels changed state at least once.\n"
     << "- " << humanBytes(static_cast<double>(fs::file_size(map_path))) << " on disk.\n\n"
     << "![Nodes after each session](images/storage.png)\n\n"
     << "## Pictures\n\n"
     << "The map as last observed, from above (each column shows its highest occupied voxel in its mean "
     << "colour; light grey is free space, dark is never observed):\n\n"
     << "![Top view of the latest snapshot](images/map_topview.png)\n\n"
     << "Session 0's points from above, as the camera saw them:\n\n"
     << "![Session 0 point cloud](images/session_00_cloud.png)\n\n"
     << "One recorded frame, colour and depth (black: no depth; blue near, red far):\n\n"
     << "![RGB frame](images/frame_rgb.png) ![Depth frame](images/frame_depth.png)\n\n"
     << "The camera path of session 0, true and as the localisation estimated it:\n\n"
     << "![Trajectory](images/trajectory.png)\n\n"
     << "## What changed, and which objects\n\n"
     << "Each pair of consecutive registered session maps was compared (`chronomap diff`, band mode: "
     << "probabilities within 0.5 ± 0.1 count as unknown; a voxel is no change when the other session saw a "
     << "surface within one voxel, unless that surface moved by half a voxel or more, measured from where in "
     << "the voxels the rays ended: `--neighbourhood 1 --min-shift 0.5`) and the changed voxels split into objects "
     << "(`chronomap segment`, vertex connectivity, at least " << segment_settings.min_voxels << " voxels). "
     << "Green appeared, red vanished; each object is framed and numbered. Over all pairs: "
     << change_total.events_found << " of " << change_total.events_observable
     << " observable change events found, " << change_total.false_components
     << " components that match no event, voxel precision " << percent(change_total.precision()) << " and recall "
     << percent(change_total.recall()) << " (within one voxel of the truth). The diffs are in `changes/`.\n\n"
     << changes_md.str()
     << "## Try next\n\n```sh\n"
     << "chronomap stats " << map_path.string() << "\n"
     << "chronomap snapshot " << map_path.string() << " --at " << formatTime(simulated.times_s.front())
     << " -o first.ply\n"
     << "chronomap changes " << map_path.string() << " --min 2 -o busy.ply\n"
     << "chronomap segment " << (out / "changes" / "diff_00_01.cmap").string() << " --connectivity vertex --min-voxels 20\n```\n";
  const std::string report = md.str();
  io::writeFileAtomic(out / "report.md", std::vector<uint8_t>(report.begin(), report.end()));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

  double mean_precision = 0.0, mean_recall = 0.0, recorded_precision = 0.0, recorded_recall = 0.0;
  for (const auto& r : results) {
    const double w = 1.0 / static_cast<double>(results.size());
    mean_precision += w * r.registered_score.precision;
    mean_recall += w * r.registered_score.recall;
    recorded_precision += w * r.score.precision;
    recorded_recall += w * r.score.recall;
  }
  if (o.json) {
    std::cout << nlohmann::json{{"output", out.string()},       {"sessions", results.size()},
                                {"frames", simulated.frames},    {"events", simulated.events},
                                {"nodes_4d", counts.nodes()},     {"nodes_separate", separate},
                                {"precision", mean_precision},  {"recall", mean_recall},
                                {"precision_as_recorded", recorded_precision}, {"recall_as_recorded", recorded_recall},
                                {"changed_voxels", changed_voxels}, {"events_observable", change_total.events_observable},
                                {"events_found", change_total.events_found},
                                {"false_components", change_total.false_components}, {"seconds", seconds}}
                     .dump()
              << "\n";
  } else {
    std::cout << "\nchronomap demo finished in " << std::fixed << std::setprecision(1) << seconds << " s\n"
              << "  " << results.size() << " sessions, " << simulated.frames << " frames, " << simulated.events
              << " change events simulated\n"
              << "  occupied voxels vs truth: precision " << percent(mean_precision) << ", recall "
              << percent(mean_recall) << " registered (as recorded: " << percent(recorded_precision) << ", "
              << percent(recorded_recall) << "; mean over sessions)\n"
              << "  4D map: " << counts.nodes() << " nodes vs " << separate << " for the sessions stored separately\n"
              << "  changes: " << change_total.events_found << " of " << change_total.events_observable
              << " observed change events found as objects, " << change_total.false_components
              << " components match no event\n"
              << "  report:   " << (out / "report.md").string() << "\n"
              << "  pictures: " << images.string() << "/\n"
              << "  4D map:   " << map_path.string() << "\n";
  }
  return 0;
}

}  // namespace

Command addSimulate(CLI::App& root) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* app = root.add_subcommand(
      "simulate",
      "Simulate a building recorded many times by a patrolling robot, with ground truth: one TUM RGB-D "
      "folder per session, the true occupancy and objects per session, and every change event.\n"
      "Presets: tiny (one room, 3 sessions), office (a corridor and three rooms, 6 sessions), floor66 "
      "(40 x 20 m, 16 rooms, 66 sessions over about 45 days).");
  app->add_option("--preset", o->settings.preset, "tiny, office or floor66")->capture_default_str();
  app->add_option("-o,--output", o->output, "folder to write")->required();
  app->add_option("--seed", o->settings.seed, "random seed (same seed, same bytes)")->capture_default_str();
  app->add_option("--sessions", o->settings.sessions, "number of sessions (0 = the preset's)")->capture_default_str();
  app->add_option("--resolution-scale", o->settings.resolution_scale,
                  "image size relative to 640 x 480 (0.1 .. 1; smaller is faster)")
      ->capture_default_str();
  app->add_option("--noise", o->settings.noise_per_m2, "depth noise sigma = NOISE * z^2, metres")->capture_default_str();
  app->add_option("--threads", o->settings.threads, "rendering threads, 0 = all cores (output does not depend on it)")
      ->capture_default_str();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runSimulate(*o); }};
}

Command addDemo(CLI::App& root) {
  auto o = std::make_shared<DemoOptions>();
  CLI::App* app = root.add_subcommand(
      "demo",
      "The first thing to run: simulate the office preset, integrate every session, register the sessions to "
      "their consensus, build the 4D map, find what changed between sessions and which objects, and write "
      "report.md with pictures (top view of the map, a session's point cloud, a frame, the trajectory, the "
      "storage curve, the changes).");
  app->add_option("-o,--output", o->output, "folder to write")->capture_default_str();
  app->add_option("--seed", o->seed, "random seed of the simulation")->capture_default_str();
  app->add_option("--resolution-scale", o->resolution_scale, "image size relative to 640 x 480")->capture_default_str();
  app->add_flag("--exact", o->exact, "integrate with exact ray casting instead of fast mode (slower)");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runDemo(*o); }};
}

}  // namespace chronomap::cli
