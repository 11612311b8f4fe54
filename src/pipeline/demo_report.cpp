#include "demo_report.h"

#include <algorithm>
#include <cstdio>
#include <iomanip>
#include <sstream>

#include <nlohmann/json.hpp>

#include "chronomap/analysis/change_preset.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"

namespace chronomap {

namespace {

std::string percent(double v) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << 100.0 * v << "%";
  return s.str();
}

/// "door opened", "chair moved": the kind in words, after the object's kind unless it names it.
std::string eventName(const ChangeEvent& e) {
  std::string kind = toString(e.kind);
  std::replace(kind.begin(), kind.end(), '_', ' ');
  const std::string object = toString(e.object_kind);
  return kind.rfind(object + " ", 0) == 0 ? kind : object + " " + kind;
}

void introduction(std::ostream& md, const DemoReportInput& in) {
  md << "# chronomap demo: the simulated office\n\n"
     << "The simulator built an office floor (a corridor, an office, a kitchen and a meeting room) and "
     << "recorded it " << in.sessions.size() << " times with a patrolling robot's Kinect-like camera ("
     << in.simulation.resolution_scale * 640 << " x " << in.simulation.resolution_scale * 480
     << " pixels, depth noise 1.4 mm z^2, localisation offset and drift). Between sessions doors opened and "
     << "closed, chairs and boxes moved, a person and another robot came and went: " << in.simulated.events
     << " change events, listed with their voxels in `data/scene.json`.\n\n"
     << "Each session was integrated into a session map (" << (in.settings.fast ? "fast" : "exact")
     << " mode, 0.05 m voxels, the estimated poses a real robot would have) and scored against the "
     << "simulator's true occupancy. Then every session was registered to the consensus of all of them and "
     << "integrated again with its correction (x, y and heading, and the drift from frame to frame, fitted on "
     << "the sessions' points: `chronomap build --register --register-drift " << in.drift_knots
     << " --register-planar --register-points`), scored again, and added to one 4D map, `office.cmap`.\n\n";
}

void sessionTable(std::ostream& md, const DemoReportInput& in) {
  md << "## Sessions\n\n"
     << "| session | time | frames | points | occupied voxels | precision, as recorded | recall, as recorded "
        "| precision, registered | recall, registered | nodes added to the 4D map |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (size_t s = 0; s < in.sessions.size(); ++s) {
    const DemoSession& d = in.sessions[s];
    md << "| " << s + 1 << " | " << formatTime(in.simulated.times_s[s]) << " | " << d.stats.frames << " | "
       << d.stats.points << " | " << d.registered_score.predicted << " | " << percent(d.score.precision) << " | "
       << percent(d.score.recall) << " | " << percent(d.registered_score.precision) << " | "
       << percent(d.registered_score.recall) << " | " << in.map.sessions()[s].nodes_added << " |\n";
  }
  md << "\nPrecision: occupied voxels of the session map that are occupied in the truth. Recall: truth "
     << "voxels the session observed that it found occupied. Both count exact voxels; the estimated "
     << "poses are off by a few centimetres, about a voxel, and registered by a few millimetres.\n\n";
}

void mapAndPictures(std::ostream& md, const DemoReportInput& in) {
  const TemporalCounts counts = in.map.counts();
  const DemoResult& r = in.result;
  md << "## The 4D map\n\n"
     << "- " << countOf(in.map.sessionCount(), "session") << ", " << counts.nodes() << " nodes (" << counts.inner_nodes
     << " inner, " << counts.entries << " history entries); the session maps on their own hold " << r.nodes_separate
     << " nodes, so the 4D map needs "
     << percent(static_cast<double>(counts.nodes()) / static_cast<double>(r.nodes_separate)) << " of that.\n"
     << "- " << r.changed_voxels << " voxels changed state at least once.\n"
     << "- " << humanBytes(static_cast<double>(in.map_file_bytes)) << " on disk.\n\n"
     << "![Nodes after each session](images/storage.png)\n\n"
     << "**[tour.html](tour.html)** opens the 4D map in a browser, from disk: drag the time slider (or "
     << "press play) to watch the office change, show what changed between two sessions with each object "
     << "framed and numbered, click a voxel for its history. `chronomap view " << r.map.string()
     << "` serves the same page for any map (docs/viewer.md).\n\n"
     << "## Pictures\n\n"
     << "The map as last observed, from above (each column shows its highest occupied voxel in its mean "
     << "colour; light grey is free space, dark is never observed):\n\n"
     << "![Top view of the latest snapshot](images/map_topview.png)\n\n"
     << "Session 1's points from above, as the camera saw them:\n\n"
     << "![Session 1 point cloud](images/session_01_cloud.png)\n\n"
     << "One recorded frame, colour and depth (black: no depth; blue near, red far):\n\n"
     << "![RGB frame](images/frame_rgb.png) ![Depth frame](images/frame_depth.png)\n\n"
     << "The camera path of session 1, true and as the localisation estimated it:\n\n"
     << "![Trajectory](images/trajectory.png)\n\n";
}

/// The truth events the object's components overlap most, in words; "no event (false)" if none.
std::string objectTruth(const DemoPair& p, const ChangedObject& o) {
  std::vector<int> events;
  for (uint32_t id : o.components) {
    const auto& comps = p.changes.segmentation.components;
    for (size_t c = 0; c < comps.size(); ++c) {
      const int e = comps[c].id == id ? p.score.component_event[c] : -1;
      if (e >= 0 && std::find(events.begin(), events.end(), e) == events.end()) events.push_back(e);
    }
  }
  if (events.empty()) return "no event (false)";
  std::string out;
  for (int e : events) out += (out.empty() ? "" : ", ") + eventName(p.events[static_cast<size_t>(e)]);
  return out;
}

void objectTable(std::ostream& md, const DemoPair& p) {
  if (p.changes.objects.empty()) return;
  md << "| object | kind | voxels | centroid x, y, z (m) | size x, y, z (m) | colour | truth |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (const ChangedObject& o : p.changes.objects) {
    const Eigen::Vector3d size = o.size_m();
    char line[320];
    std::snprintf(line, sizeof line, "| %u | %s | %llu | %.2f, %.2f, %.2f | %.2f, %.2f, %.2f | #%02x%02x%02x | ", o.id,
                  toString(o.kind), static_cast<unsigned long long>(o.voxels), o.centroid_m.x(), o.centroid_m.y(),
                  o.centroid_m.z(), size.x(), size.y(), size.z(), o.mean_colour.r, o.mean_colour.g, o.mean_colour.b);
    md << line;
    if (o.kind == ObjectChange::Moved) {
      std::snprintf(line, sizeof line, "%.2f m from %.2f, %.2f; ", o.distance_m, o.from.centroid_m.x(),
                    o.from.centroid_m.y());
      md << line;
    }
    md << objectTruth(p, o) << " |\n";
  }
  md << "\n";
}

/// "3 objects: 1 appeared, 1 vanished, 1 moved".
std::string objectCounts(const std::vector<ChangedObject>& objects) {
  size_t n[3] = {0, 0, 0};
  for (const ChangedObject& o : objects) ++n[static_cast<int>(o.kind)];
  std::string out = countOf(objects.size(), "object");
  if (objects.empty()) return out;
  out += ":";
  const char* sep = " ";
  for (ObjectChange k : {ObjectChange::Appeared, ObjectChange::Vanished, ObjectChange::Moved}) {
    if (!n[static_cast<int>(k)]) continue;
    out += sep + std::to_string(n[static_cast<int>(k)]) + " " + toString(k);
    sep = ", ";
  }
  return out;
}

void pairSection(std::ostream& md, const DemoPair& p, const DemoReportInput& in) {
  // Sessions are numbered from 1 here, as the viewer and people count them.
  const size_t from = p.from + 1, to = p.from + 2;
  md << "### Session " << from << " → " << to << "\n\n";
  if (p.events.empty()) {
    md << "The simulator made no change.";
  } else {
    md << "The simulator made " << countOf(p.events.size(), "change") << " (";
    for (size_t i = 0; i < p.events.size(); ++i) md << (i ? ", " : "") << eventName(p.events[i]);
    md << "); " << p.score.events_observable << " of them " << (p.score.events_observable == 1 ? "was" : "were")
       << " observed in both sessions and " << p.score.events_found << " found.";
  }
  const Changes& c = p.changes;
  md << " " << countOf(c.appeared_voxels + c.vanished_voxels, "voxel") << " changed (" << c.appeared_voxels
     << " appeared, " << c.vanished_voxels << " vanished): " << objectCounts(c.objects);
  if (c.segmentation.dropped) md << " (and " << countOf(c.segmentation.dropped, "smaller piece") << " left out)";
  md << ". `chronomap diff " << in.result.map.filename().string() << "@" << formatTime(in.simulated.times_s[p.from])
     << " " << in.result.map.filename().string() << "@" << formatTime(in.simulated.times_s[p.from + 1])
     << " --json` lists the same objects.\n\n"
     << "![Changes from session " << from << " to " << to << "](images/" << p.name << ".png)\n\n";
  objectTable(md, p);
  if (p.pictures.size() > 1) {
    md << "Close-ups, by object:\n\n";
    for (size_t i = 1; i < p.pictures.size() && i - 1 < p.changes.objects.size(); ++i) {
      md << "![Object " << p.changes.objects[i - 1].id << "](images/" << p.pictures[i] << ") ";
    }
    md << "\n\n";
  }
}

void changes(std::ostream& md, const DemoReportInput& in) {
  const ChangeScore& total = in.changes;
  const ChangeSettings settings = recommendedChangeSettings();
  md << "## What changed, and which objects\n\n"
     << "Each pair of consecutive sessions was compared in the 4D map, each voxel as last observed at the "
     << "two sessions' times, by the one call every front door asks (`findChanges`: `chronomap diff "
     << "MAP@T1 MAP@T2`, the viewer, `alerts`, Python's `chronomap.changes`) with the recommended settings "
     << "(docs/changes.md): band mode, a voxel is no change when the other time saw a surface within one voxel "
     << "unless it moved by half a voxel or more, nor when a weak change lies by a surface that is still seen, "
     << "nor when a dark object lies by a darker surface; the changed voxels form objects (vertex connectivity, "
     << "at least " << settings.segment.min_voxels << " voxels), and a vanished and an appeared object that look "
     << "alike are one object moved, drawn as an arrow from its old place to its new (the legend of each picture "
     << "names the colours); each object is framed and numbered as in the "
     << "tables and in `report.json`. Over all pairs: " << total.events_found << " of " << total.events_observable
     << " observable change events found, " << countOf(total.false_components, "piece")
     << " that match no event, voxel precision " << percent(total.precision()) << " and recall "
     << percent(total.recall()) << " (within one voxel of the truth). The diffs, each with its objects, are in "
     << "`changes/`.\n\n";
  for (const DemoPair& p : in.pairs) pairSection(md, p, in);
}

}  // namespace

std::string demoReport(const DemoReportInput& in) {
  std::ostringstream md;
  introduction(md, in);
  sessionTable(md, in);
  mapAndPictures(md, in);
  changes(md, in);
  const std::string map = in.result.map.string();
  const std::string t1 = formatTime(in.simulated.times_s[0]), t2 = formatTime(in.simulated.times_s[1]);
  md << "## Try next\n\n```sh\n"
     << "chronomap view " << map << "                 # the viewer at http://127.0.0.1:8765/\n"
     << "chronomap stats " << map << "\n"
     << "chronomap snapshot " << map << " --at " << t1 << " -o first.ply\n"
     << "chronomap changes " << map << " --min 2 -o busy.ply\n"
     << "chronomap diff " << map << "@" << t1 << " " << map << "@" << t2 << " -o d.cmap --json   # sessions 1 -> 2\n"
     << "```\n";
  return md.str();
}

std::string demoReportJson(const DemoReportInput& in) {
  nlohmann::json pairs = nlohmann::json::array();
  for (const DemoPair& p : in.pairs) {
    pairs.push_back({{"from", p.from + 1},
                     {"to", p.from + 2},
                     {"from_time", formatTime(in.simulated.times_s[p.from])},
                     {"to_time", formatTime(in.simulated.times_s[p.from + 1])},
                     {"changed_voxels", p.changes.appeared_voxels + p.changes.vanished_voxels},
                     {"objects", changedObjectsJson(p.changes.objects)}});
  }
  const nlohmann::json out = {{"map", in.result.map.filename().string()},
                              {"numbering", "sessions are numbered from 1"},
                              {"settings", changeSettingsJson(recommendedChangeSettings())},
                              {"pairs", pairs}};
  return out.dump(2) + "\n";
}

}  // namespace chronomap
