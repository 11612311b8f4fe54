#include "chronomap/core/format.h"
#include "chronomap/pipeline/demo.h"

#include <chrono>
#include <cstdio>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "chronomap/analysis/change_frequency.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/diff.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/render/colour.h"
#include "chronomap/render/plot.h"
#include "chronomap/render/top_view.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/change_truth.h"
#include "chronomap/view/tour.h"
#include "demo_pictures.h"
#include "demo_report.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

std::string numbered(const char* pattern, size_t n) {
  char name[64];
  std::snprintf(name, sizeof name, pattern, n);
  return name;
}

/// Step 2: every session integrated with the estimated poses and scored against the truth.
std::vector<DemoSession> integrateSessions(const DemoSettings& s, const SimulationSummary& simulated,
                                           const SessionSettings& session_settings) {
  std::vector<DemoSession> sessions;
  for (size_t k = 0; k < simulated.session_dirs.size(); ++k) {
    IntegratedSession i = integrateDataset(simulated.session_dirs[k], session_settings, {}, s.progress,
                                           "session " + std::to_string(k + 1));
    const SessionMap truth_map =
        readSessionMap(s.output / "data" / "truth" / numbered("occupancy_%02zu.cmap", k));
    std::vector<VoxelKey> truth;
    truth_map.forEachLeaf([&](const LeafView& l) { truth.push_back(l.key); });
    const OccupancyScore score = scoreOccupancy(i.map, truth);
    sessions.push_back({std::move(i.map), i.stats, score, {}, std::move(truth), std::move(i.sensor_positions)});
  }
  return sessions;
}

/// Step 3: registration to the consensus of all sessions (recommendedRegistration(), as the
/// README's `build --register ...`), each integrated again with its correction, scored again and
/// written to sessions/.
void registerAll(const DemoSettings& s, const SimulationSummary& simulated,
                      const SessionSettings& session_settings, std::vector<DemoSession>& sessions) {
  const RegistrationSettings registration = recommendedRegistration();
  std::vector<SessionMap> maps;
  std::vector<std::vector<Eigen::Vector3d>> positions;
  for (DemoSession& d : sessions) {
    maps.push_back(std::move(d.map));
    positions.push_back(std::move(d.sensor_positions));
  }
  registerDatasets(maps, simulated.session_dirs, positions, session_settings, registration);
  for (size_t k = 0; k < sessions.size(); ++k) {
    sessions[k].map = std::move(maps[k]);
    sessions[k].registered_score = scoreOccupancy(sessions[k].map, sessions[k].truth);
    writeSessionMap(s.output / "sessions" / numbered("session_%02zu.cmap", k + 1), sessions[k].map,
                        {{"created_by", "chronomap demo"}, {"recorded_at", simulated.times_s[k]}, {"registered", true}});
  }
}

/// Step 4: the 4D map of the registered sessions.
TemporalMap buildMap(const SimulationSummary& simulated, const std::vector<DemoSession>& sessions,
                     const fs::path& path) {
  TemporalMap map(sessions.front().map.resolution_m());
  for (size_t k = 0; k < sessions.size(); ++k) {
    map.add(simulated.times_s[k], sessions[k].map, AddSettings{false, numbered("session_%02zu", k + 1)});
  }
  writeTemporalMap(path, map, {{"created_by", "chronomap demo"}});
  return map;
}

/// Step 5: what changed between consecutive sessions, and which objects: the one call every
/// front door asks (findChanges on the 4D map, recommended settings), scored against the truth.
/// Sessions are numbered from 1 in every name, as in the report and the viewer.
std::vector<DemoPair> changesStep(const DemoSettings& s, const SimulationSummary& simulated,
                                  const std::vector<DemoSession>& sessions, const TemporalMap& map,
                                  const fs::path& images) {
  fs::create_directories(s.output / "changes");
  const std::vector<ChangeEvent> truth_events = readTruthEvents(s.output / "data" / "scene.json");
  const ChangeSettings settings = recommendedChangeSettings();
  const std::vector<Room> rooms = readRooms(s.output / "data" / "scene.json");
  std::vector<DemoPair> pairs;
  for (size_t k = 1; k < sessions.size(); ++k) {
    DemoPair p;
    p.from = k - 1;
    p.name = numbered("diff_%02zu", k) + numbered("_%02zu", k + 1);
    p.events = eventsFrom(truth_events, static_cast<uint32_t>(k - 1));
    p.changes = findChanges(map, simulated.times_s[k - 1], simulated.times_s[k], settings);
    p.score = scoreChanges(p.changes.diff, p.changes.segmentation, p.events, sessions[k - 1].map, sessions[k].map);
    writeDiffMap(s.output / "changes" / (p.name + ".cmap"), p.changes, settings, "recommended",
                 {{"created_by", "chronomap demo"}});
    p.pictures = drawChangePictures(images, p.name, map.snapshot(simulated.times_s[k]), p.changes, rooms);
    pairs.push_back(std::move(p));
  }
  return pairs;
}

/// Session 1's points from above, every second point of every frame.
ImageRgb sessionCloudView(const fs::path& dir) {
  const auto dataset = openRecording(dir);
  std::vector<Eigen::Vector3f> points;
  std::vector<Rgb> colours;
  for (size_t i = 0; i < dataset->size(); ++i) {
    const Frame f = dataset->load(i);
    for (size_t k = 0; k < f.cloud.size(); k += 2) {
      const Eigen::Vector3f& p = f.cloud.points[k];
      if (!p.allFinite()) continue;
      points.push_back((f.T_world_sensor * p.cast<double>()).cast<float>());
      colours.push_back(f.cloud.hasColours() ? f.cloud.colours[k] : Rgb{200, 200, 200});
    }
  }
  return renderPointsTopView(points, colours, 0.02);
}

std::vector<Eigen::Vector3d> trajectoryPositions(const fs::path& path) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : parseTumTrajectory(readTextFile(path), path.string())) out.push_back(p.pose.translation());
  return out;
}

/// Session 1's camera path, true and estimated.
ImageRgb trajectoryPlot(const fs::path& dir) {
  PlotSeries truth{"true path", Rgb{40, 90, 200}, {}, {}}, estimate{"estimated path", Rgb{220, 80, 40}, {}, {}};
  for (const auto& p : trajectoryPositions(dir / "groundtruth.txt")) {
    truth.x.push_back(p.x());
    truth.y.push_back(p.y());
  }
  for (const auto& p : trajectoryPositions(dir / "trajectory.txt")) {
    estimate.x.push_back(p.x());
    estimate.y.push_back(p.y());
  }
  PlotSettings ps;
  ps.title = "Session 1: camera path";
  ps.x_label = "x (m)";
  ps.y_label = "y (m)";
  return renderLinePlot({truth, estimate}, ps);
}

/// Step 6: the pictures beside the changes.
void drawPictures(const SimulationSummary& simulated, const TemporalMap& map, const fs::path& images) {
  drawMapPicture(images / "map_topview.png", map.snapshot(simulated.times_s.back()),
                 readRooms(simulated.session_dirs.front().parent_path() / "scene.json"));
  const fs::path& first = simulated.session_dirs.front();
  writePng(images / "session_01_cloud.png", sessionCloudView(first));
  // One frame as recorded: colour and depth (from the middle of the first session).
  const auto names = parseStampedList(readTextFile(first / "depth.txt"), "depth.txt");
  const auto& mid = names[names.size() / 2];
  fs::copy_file(first / ("rgb/" + mid.name.substr(6)), images / "frame_rgb.png", fs::copy_options::overwrite_existing);
  writePng(images / "frame_depth.png", colourizeDepth(readPngU16(first / mid.name), 5000.0));
  writePng(images / "trajectory.png", trajectoryPlot(first));
  writePng(images / "storage.png", renderStoragePlot(map));
}

/// The result's means and totals; @return the change score over all pairs.
ChangeScore summarise(const std::vector<DemoSession>& sessions, const std::vector<DemoPair>& pairs,
                           DemoResult& r) {
  const double w = 1.0 / static_cast<double>(sessions.size());
  for (const DemoSession& d : sessions) {
    r.precision += w * d.registered_score.precision;
    r.recall += w * d.registered_score.recall;
    r.precision_as_recorded += w * d.score.precision;
    r.recall_as_recorded += w * d.score.recall;
  }
  ChangeScore total;
  for (const DemoPair& p : pairs) total += p.score;
  r.events_observable = total.events_observable;
  r.events_found = total.events_found;
  r.false_components = total.false_components;
  return total;
}

}  // namespace

DemoResult runDemo(const DemoSettings& settings) {
  const auto started = std::chrono::steady_clock::now();
  // Written whole or not at all: every step writes into a staging folder beside the output,
  // moved into place at the end; the report and the result name the final places.
  StagedFolder staged(settings.output);
  DemoSettings s = settings;
  s.output = staged.path();
  DemoResult r;
  r.images = s.output / "images";
  r.map = s.output / "office.cmap";
  std::error_code ec;
  fs::create_directories(r.images, ec);
  if (ec) throw IoError(s.output.string() + ": cannot create folder (" + ec.message() + ")");

  s.progress.say("[1/6] simulating the 'office' preset: a corridor, an office, a kitchen and a meeting room");
  SimulationSettings sim_settings;
  sim_settings.preset = "office";
  sim_settings.seed = s.seed;
  sim_settings.resolution_scale = s.resolution_scale;
  const SimulationSummary simulated = chronomap::simulate(
      sim_settings, s.output / "data", [&](size_t done, size_t) { s.progress.advance("simulating", done, 6); });

  s.progress.say("[2/6] integrating " + countOf(simulated.session_dirs.size(), "session") + " (" +
                 (s.fast ? "fast" : "exact") + " mode, estimated poses)");
  fs::create_directories(s.output / "sessions", ec);
  SessionSettings session_settings;
  session_settings.integrator.fast = s.fast;
  std::vector<DemoSession> sessions = integrateSessions(s, simulated, session_settings);

  s.progress.say("[3/6] registering the sessions to their consensus (x, y and heading; drift per frame, fitted on "
                 "points)");
  registerAll(s, simulated, session_settings, sessions);

  s.progress.say("[4/6] building the 4D map of the registered sessions");
  const TemporalMap map = buildMap(simulated, sessions, r.map);

  s.progress.say("[5/6] finding what changed between consecutive sessions");
  const std::vector<DemoPair> pairs = changesStep(s, simulated, sessions, map, r.images);

  s.progress.say("[6/6] drawing the report");
  drawPictures(simulated, map, r.images);
  writeTour(s.output / "tour.html", map, "office.cmap");
  r.sessions = sessions.size();
  r.frames = simulated.frames;
  r.events = simulated.events;
  r.nodes_4d = map.counts().nodes();
  for (const auto& session : map.sessions()) r.nodes_separate += session.nodes_separate;
  for (uint64_t n : changeHistogram(map, -1e300, 1e300)) r.changed_voxels += n;
  const ChangeScore changes = summarise(sessions, pairs, r);
  const uint64_t map_bytes = fs::file_size(r.map);
  r.images = settings.output / "images";
  r.map = settings.output / "office.cmap";
  r.report = settings.output / "report.md";
  r.tour = settings.output / "tour.html";
  const DemoReportInput input{settings, sim_settings, simulated, sessions, pairs, map, r, changes, map_bytes,
                              recommendedRegistration().align.drift_knot_frames};
  const std::string report = demoReport(input), json = demoReportJson(input);
  writeFileAtomic(s.output / "report.md", std::vector<uint8_t>(report.begin(), report.end()));
  writeFileAtomic(s.output / "report.json", std::vector<uint8_t>(json.begin(), json.end()));
  staged.commit();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return r;
}

}  // namespace chronomap
