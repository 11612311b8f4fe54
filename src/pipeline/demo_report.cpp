#include "demo_report.h"

#include <algorithm>
#include <cstdio>
#include <iomanip>
#include <sstream>

#include "chronomap/analysis/change_preset.h"
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
     << "![Session 1 point cloud](images/session_00_cloud.png)\n\n"
     << "One recorded frame, colour and depth (black: no depth; blue near, red far):\n\n"
     << "![RGB frame](images/frame_rgb.png) ![Depth frame](images/frame_depth.png)\n\n"
     << "The camera path of session 1, true and as the localisation estimated it:\n\n"
     << "![Trajectory](images/trajectory.png)\n\n";
}

void componentTable(std::ostream& md, const DemoPair& p) {
  if (!p.segmentation.components.empty()) {
    md << "| id | kind | voxels | volume (litres) | centroid x, y, z (m) | size x, y, z (m) | colour | truth |\n"
       << "|---|---|---|---|---|---|---|---|\n";
  }
  for (size_t c = 0; c < p.segmentation.components.size(); ++c) {
    const Component& comp = p.segmentation.components[c];
    const Eigen::Vector3d size = comp.bbox_max_m - comp.bbox_min_m;
    char line[256];
    std::snprintf(line, sizeof line, "| %u | %s | %llu | %.1f | %.2f, %.2f, %.2f | %.2f, %.2f, %.2f | #%02x%02x%02x | ",
                  comp.id, toString(comp.kind), static_cast<unsigned long long>(comp.voxels), comp.volume_m3 * 1000.0,
                  comp.centroid_m.x(), comp.centroid_m.y(), comp.centroid_m.z(), size.x(), size.y(), size.z(),
                  comp.mean_colour.r, comp.mean_colour.g, comp.mean_colour.b);
    const int e = p.score.component_event[c];
    md << line << (e >= 0 ? eventName(p.events[static_cast<size_t>(e)]) : std::string("no event (false)")) << " |\n";
  }
  md << "\n";
}

void pairSection(std::ostream& md, const DemoPair& p, const SegmentSettings& segment) {
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
  md << " The diff holds " << countOf(p.score.changed_voxels, "changed voxel") << ", in "
     << countOf(p.segmentation.components.size(), "component") << " of at least " << segment.min_voxels
     << " voxels (" << p.segmentation.dropped << " smaller ones dropped).\n\n"
     << "![Changes from session " << from << " to " << to << "](images/" << p.name << ".png)\n\n";
  componentTable(md, p);
}

void changes(std::ostream& md, const DemoReportInput& in) {
  const ChangeScore& total = in.changes;
  const SegmentSettings segment = demoChangeSettings().segment;
  md << "## What changed, and which objects\n\n"
     << "Each pair of consecutive registered session maps was compared (`chronomap diff`, band mode: "
     << "probabilities within 0.5 ± 0.1 count as unknown; a voxel is no change when the other session saw a "
     << "surface within one voxel, unless that surface moved by half a voxel or more, measured from where in "
     << "the voxels the rays ended, nor when the surface the other session saw within three voxels is still seen "
     << "there, nor when the object lies within two voxels of the other session's surface and is mostly dark and "
     << "darker than it: "
     << "`--neighbourhood 1 --min-shift 0.5 --kept-surface 3 --dark-surface 2`) and the changed voxels split into "
     << "objects "
     << "(`chronomap segment`, vertex connectivity, at least " << segment.min_voxels << " voxels). "
     << "Green appeared, red vanished; each object is framed and numbered. Over all pairs: " << total.events_found
     << " of " << total.events_observable << " observable change events found, " << total.false_components
     << " components that match no event, voxel precision " << percent(total.precision()) << " and recall "
     << percent(total.recall()) << " (within one voxel of the truth). The diffs are in `changes/`.\n\n";
  for (const DemoPair& p : in.pairs) pairSection(md, p, segment);
}

}  // namespace

DemoChangeSettings demoChangeSettings() {
  const ChangeSettings preset = recommendedChangeSettings();
  return {preset.diff, preset.segment};
}

std::string demoReport(const DemoReportInput& in) {
  std::ostringstream md;
  introduction(md, in);
  sessionTable(md, in);
  mapAndPictures(md, in);
  changes(md, in);
  const std::string map = in.result.map.string();
  md << "## Try next\n\n```sh\n"
     << "chronomap view " << map << "                 # the viewer at http://127.0.0.1:8765/\n"
     << "chronomap stats " << map << "\n"
     << "chronomap snapshot " << map << " --at " << formatTime(in.simulated.times_s.front()) << " -o first.ply\n"
     << "chronomap changes " << map << " --min 2 -o busy.ply\n"
     << "chronomap segment " << (in.settings.output / "changes" / "diff_00_01.cmap").string()
     << " --connectivity vertex --min-voxels 20\n```\n";
  return md.str();
}

}  // namespace chronomap
