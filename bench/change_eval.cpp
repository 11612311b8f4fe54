// change_eval: how well chronomap finds what changed and which objects, against ground truth.
//
// 1. The simulated office (and floor66 when given): every consecutive pair of sessions is
//    integrated (fast mode), diffed in every mode, segmented and scored against the
//    simulator's change events: voxel precision and recall, object recall (an event counts as
//    found when a component overlaps its voxels), false components per pair. With estimated
//    poses (what a robot has) and true poses (what the sensor alone gives).
// 2. Real data from ../shared/data: mOSD group A (objects re-arranged on a table between five
//    shots, per-point labels: is every changed placement of an object found?), nvblox's human_dataset (the share
//    of frame 2's pixels flagged changed after frame 1; nvblox's test accepts 5-20 %), and the
//    PCL grabber sequence of a static scene (the false change rate).
//
// Usage: change_eval [--office DIR] [--floor66 DIR] [--data DIR] [--quick] [--register-model M] [--drift-knots N]
//                    [--keep-mean] [--drift-path M] [--register-to-truth]
//   --seeds A-B    simulate seeds A to B (with --sensor NAME, through that sensor) and run once on each;
//                  prints every figure's mean, min and max (seeds.h). Train on 1-5, report 6-15.
//                    [--register-rounds N] [--register-radius R] [--drift-rounds N] [--not-planar]
//                    [--drift-voxels] [--kept-surface R] [--kept-share F] [--dark-surface R]
//                    [--dark-below B] [--dark-contrast C] [--dark-share F]
//   --office DIR   a `chronomap simulate --preset office` output (default: simulate one at half
//                  resolution into a temporary folder)
//   --floor66 DIR  also evaluate a floor66 simulation (not simulated by default: ~7 minutes)
//   --quick        only the recommended settings, no sweep
//   --min-shift S  the shift test's threshold, voxels (default DiffSettings::kRecommendedMinShift)
//   --shift-plane R  the shift test counts only a flat surface's move across it, a plane being
//                  a least spread under R of the next (DiffSettings::shift_plane_ratio; default
//                  kRecommendedShiftPlaneRatio, as the recommended diff; 0: the whole move)
//   --sensor NAME  ideal (default), kinect or realsense: the sensor of the simulations made here
//                  (SimulationSettings::sensor); a folder given keeps its own
//   --register-preset NAME  first if at all: the registration of `build --register-preset NAME`
//                  (localiser, the default here, or odometry); the flags after it change it
//   --register-model  world (default) or per-pose: the registration's correction model
//                  (align/register.h) for the "register" and "reg+align" rows
//   --register-rounds N  rigid registration rounds (default 3, as `chronomap build --register`)
//   --drift-knots N  the registration also corrects drift, knots every N frames (default 20, as
//                  `chronomap build --register --register-drift 20`; 0: rigid corrections only)
//   --register-radius R, --drift-rounds N  the registration's neighbourhood (voxels) and rounds
//                  of drift correction (RegisterSettings; defaults as the library's)
//   --fine-radius R  the neighbourhood of the drift rounds after the first
//                  (RegisterSettings::fine_radius_voxels, as `build --register-fine-radius`)
//   --register-to-truth  a diagnostic: each session registered alone against the consensus of the
//                  true-pose maps (the fit's own error, with an exact target)
//   --drift-path M  knots every M metres of the sensor's path instead (as `build --register
//                  --register-drift-path M`); --drift-path-m S, --drift-path-yaw DEG its prior per
//                  square root of a metre (RegisterSettings::drift_per_m, drift_yaw_per_m_deg)
//   --drift-per-frame M, --drift-yaw-per-frame DEG  the drift fit's smoothness prior: the random
//                  walk's step per frame (RegisterSettings::drift_per_frame_m, _yaw_per_frame_deg)
//   --nightly      also register the sessions one at a time in time order, each against the
//                  consensus of those before it (the streaming build's registration, one recording
//                  a night: `build DIR --tiles --register ...` per session), and score them ("nightly")
//   --keep-mean    take the motion all sessions' corrections share out after every round
//                  (RegisterSettings::keep_mean, as `build --register-keep-mean`)
//   --not-planar   also fit a vertical offset (without RegisterSettings::planar, which the
//                  default registration, as --register-planar, uses)
//   --drift-voxels  the drift fit on voxel centres (without RegisterSettings::drift_points, which
//                  the default registration, as --register-points, uses)
//   --kept-surface R  the weak-change rule's radius in the recommended diff (DiffSettings::
//                  kept_surface_radius_voxels; default 3, as `diff --kept-surface 3`; 0: off)
//   --kept-share F  its share (DiffSettings::kept_surface_share; default 0.9)
//   --dark-surface R  the dark-surface rule's radius in the recommended diff
//                  (DiffSettings::dark_surface_radius_voxels; default 2, as `diff --dark-surface 2`; 0: off)
//   --dark-below B  its brightness (DiffSettings::dark_surface_brightness; default 40)
//   --dark-contrast C  its contrast (DiffSettings::dark_surface_contrast; default 0.6)
//   --dark-share F  the share of an object's voxels it needs dark (DiffSettings::dark_surface_share;
//                  default 0.5)
// The last line of output is one JSON object with the headline figures: the office sessions
// registered to their consensus (as `chronomap build --register --register-drift 20
// --register-planar --register-points`) at the recommended settings (band mode, neighbourhood 1,
// the shift test at half a voxel, vertex connectivity, at least 20 voxels), and the same
// without the shift test (office_no_shift_...). The real data (single shots without pose error)
// are diffed without the shift test.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <unistd.h>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <tuple>
#include <unordered_set>
#include <vector>

#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/align/register.h"
#include "chronomap/analysis/change_preset.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/png.h"
#include "chronomap/sim/building.h"
#include "chronomap/sim/change_truth.h"
#include "bench_sim.h"
#include "seeds.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

using bench::seconds;

// The settings the documentation recommends for registered robot sessions (see
// docs/changes.md): band mode, a surface within one voxel is no change unless it moved by half a
// voxel or more (the shift test), the weak-change rule at 3 voxels, vertex connectivity,
// components of at least 20 voxels.
int g_kept_surface = DiffSettings::kRecommendedKeptSurfaceRadius;  // --kept-surface
double g_kept_share = DiffSettings::kDefaultKeptSurfaceShare;       // --kept-share
int g_dark_surface = DiffSettings::kDarkSurfaceRadius;  // --dark-surface
double g_dark_below = DiffSettings::kDefaultDarkSurfaceBrightness;   // --dark-below
double g_dark_contrast = DiffSettings::kDefaultDarkSurfaceContrast;  // --dark-contrast
double g_dark_share = DiffSettings::kDefaultDarkSurfaceShare;        // --dark-share
double g_min_shift = DiffSettings::kRecommendedMinShift;             // --min-shift
double g_shift_plane = DiffSettings::kRecommendedShiftPlaneRatio;    // --shift-plane
bool g_nightly = false;  // --nightly
bool g_to_truth = false;  // --register-to-truth

DiffSettings defaultDiff() {
  DiffSettings d = recommendedChangeSettings().diff;
  d.kept_surface_radius_voxels = g_kept_surface;
  d.kept_surface_share = g_kept_share;
  d.dark_surface_radius_voxels = g_dark_surface;
  d.dark_surface_brightness = g_dark_below;
  d.dark_surface_contrast = g_dark_contrast;
  d.dark_surface_share = g_dark_share;
  d.min_shift_voxels = g_min_shift;
  d.shift_plane_ratio = g_shift_plane;
  return d;
}

SegmentSettings defaultSegment() { return recommendedChangeSettings().segment; }

// Without the shift test: every surface within one voxel is no change (for maps whose poses
// were not registered: the demo's sessions, the real data's single shots).
DiffSettings noShiftDiff() {
  DiffSettings d = defaultDiff();
  d.min_shift_voxels = 0.0;
  return d;
}

// ------------------------------------------------------------------------------------------
// Simulated buildings

using bench::loadSimulation;
using bench::SimSessions;

ChangeScore scorePairs(const std::vector<SessionMap>& maps, const std::vector<ChangeEvent>& events,
                            const DiffSettings& ds, const SegmentSettings& ss, size_t* pairs_with_false = nullptr) {
  ChangeScore total;
  for (size_t k = 1; k < maps.size(); ++k) {
    const std::vector<ChangeEvent> pair = eventsFrom(events, static_cast<uint32_t>(k - 1));
    const DiffMap d = diff(maps[k - 1], maps[k], ds);
    const Segmentation seg = segment(d, ss);
    const ChangeScore s = scoreChanges(d, seg, pair, maps[k - 1], maps[k]);
    if (pairs_with_false && s.false_components > 1) ++*pairs_with_false;
    total += s;
  }
  return total;
}

// The one call every front door asks (findChanges), on each consecutive pair: of the two
// session maps, or of the 4D map holding all sessions (its states at the two sessions' times,
// each voxel as last observed). Both are scored against the same truth (the events between the
// two sessions, observable in both session maps). Moves are counted as objects.
struct OneCallScore {
  ChangeScore score;
  size_t objects = 0, moves = 0;
  size_t nodes = 0;  // of the 4D map
  // Moves against the truth: a move whose two components overlap the same "moved" event most
  // (true), one that pairs anything else (false), and moved events whose vanished and appeared
  // halves are both objects of their own, unpaired (missed).
  // A door that opened is its leaf gone from one place and come to another: a pair of halves on
  // one event of another kind is one object too (same_event), not a move the truth names.
  size_t true_moves = 0, false_moves = 0, missed_moves = 0, same_event = 0;
};

// How the 4D map is read: the defaults, or one of them off.
enum class FourD { No, Defaults, FirstPositions, LastObserved };

OneCallScore scoreOneCall(const std::vector<SessionMap>& maps, const std::vector<ChangeEvent>& events,
                          ChangeSettings cs, FourD four_d) {
  OneCallScore out;
  ChangeCriterion criterion;
  if (four_d == FourD::FirstPositions) criterion.surface_shift_voxels = 0.0;
  if (four_d == FourD::LastObserved) cs.diff.seen_at_both = false;
  TemporalMap map(maps.front().resolution_m(), criterion);
  if (four_d != FourD::No) {
    for (size_t k = 0; k < maps.size(); ++k) map.add(3600.0 * double(k + 1), maps[k]);
  }
  for (size_t k = 1; k < maps.size(); ++k) {
    const std::vector<ChangeEvent> pair = eventsFrom(events, static_cast<uint32_t>(k - 1));
    const Changes c = four_d != FourD::No ? findChanges(map, 3600.0 * double(k), 3600.0 * double(k + 1), cs)
                                          : findChanges(maps[k - 1], maps[k], cs);
    const ChangeScore score = scoreChanges(c.diff, c.segmentation, pair, maps[k - 1], maps[k]);
    out.score += score;
    out.objects += c.objects.size();
    auto eventOf = [&](uint32_t component) {
      for (size_t i = 0; i < c.segmentation.components.size(); ++i) {
        if (c.segmentation.components[i].id == component) return score.component_event[i];
      }
      return -1;
    };
    std::map<int, std::pair<bool, bool>> unpaired;  // moved event -> (a vanished object, an appeared one)
    for (const ChangedObject& o : c.objects) {
      if (o.kind == ObjectChange::Moved) {
        ++out.moves;
        const int a = eventOf(o.components[0]), b = eventOf(o.components[1]);
        if (a >= 0 && a == b) {
          ++(pair[size_t(a)].kind == EventKind::Moved ? out.true_moves : out.same_event);
        } else {
          ++out.false_moves;
        }
      } else if (const int e = eventOf(o.components[0]); e >= 0 && pair[size_t(e)].kind == EventKind::Moved) {
        (o.kind == ObjectChange::Vanished ? unpaired[e].first : unpaired[e].second) = true;
      }
    }
    for (const auto& [e, halves] : unpaired) out.missed_moves += halves.first && halves.second;
  }
  if (four_d != FourD::No) out.nodes = map.counts().nodes();
  return out;
}

void printOneCall(const char* poses, const std::vector<SessionMap>& maps, const std::vector<ChangeEvent>& events,
                  const ChangeSettings& cs) {
  const double pairs = double(maps.size() - 1);
  const std::pair<FourD, const char*> rows[] = {{FourD::No, "session maps"},
                                                {FourD::Defaults, "4D map"},
                                                {FourD::FirstPositions, "4D, 1st pos"},
                                                {FourD::LastObserved, "4D, last obs"}};
  for (const auto& [four_d, name] : rows) {
    const auto t = std::chrono::steady_clock::now();
    const OneCallScore o = scoreOneCall(maps, events, cs, four_d);
    const ChangeScore& c = o.score;
    std::printf("%-9s %-13s | %9.3f %9.3f | %4zu/%-4zu | %10.2f | %11.2f %9.2f | %3zu %3zu %3zu %3zu | %9zu | %6.2f\n",
                poses, name, c.precision(), c.recall(), c.events_found, c.events_observable,
                double(c.false_components) / pairs, double(o.objects) / pairs, double(o.moves) / pairs, o.true_moves,
                o.same_event, o.false_moves, o.missed_moves, o.nodes, seconds(t));
    for (const std::string& m : c.missed_events) std::printf("            missed: %s\n", m.c_str());
  }
}

struct SimSummary {
  double segment_speedup = 0.0;        // flood fill time / segment time on the largest input
  double diff_ms_first = 0.0, diff_ms_last = 0.0;  // 4D diff time with the fewest and most sessions
  double object_recall = 0.0;
  double false_components_per_pair = 0.0;
  double voxel_precision = 0.0, voxel_recall = 0.0;
  double no_shift_object_recall = 0.0, no_shift_false_components_per_pair = 0.0;  // with noShiftDiff()
  double relative_pose_mm = 0.0, relative_heading_deg = 0.0;  // registered sessions against each other
};

template <class Fn>
double bestMs(int repeats, Fn&& fn) {
  double best = 1e300;
  for (int i = 0; i < repeats; ++i) {
    const auto t = std::chrono::steady_clock::now();
    fn();
    best = std::min(best, seconds(t) * 1000.0);
  }
  return best;
}

// Segmentation against the flood fill on growing inputs: the unfiltered diffs of consecutive
// sessions (the largest diffs the data gives), merged one pair after another.
double benchSegmentation(const std::vector<SessionMap>& maps) {
  std::printf("\nsegmentation (vertex connectivity) vs the flood fill on unions of hard diffs:\n"
              "changed_voxels  components  segment_ms  floodfill_ms  speedup  segment_ns_per_voxel\n");
  std::map<uint64_t, ChangeCell> merged;
  double speedup = 0.0;
  for (size_t k = 1; k < maps.size(); ++k) {
    const DiffMap d = diff(maps[k - 1], maps[k]);
    for (const ChangeCell& c : d.cells()) merged.emplace(mortonEncode(c.key), c);
    std::vector<ChangeCell> cells;
    for (const auto& [code, c] : merged) cells.push_back(c);
    const DiffMap input = DiffMap::fromCells(d.resolution_m(), {}, std::move(cells));
    SegmentSettings ss;
    ss.connectivity = Connectivity::Vertex;
    size_t n = 0;
    const double fast = bestMs(5, [&] { n = segment(input, ss).components.size(); });
    const double slow = bestMs(2, [&] { segmentByFloodFill(input, ss); });
    speedup = slow / fast;
    std::printf("%14llu  %10zu  %10.2f  %12.2f  %7.1f  %20.0f\n",
                static_cast<unsigned long long>(input.voxelCount()), n, fast, slow, speedup,
                fast * 1e6 / double(input.voxelCount()));
  }
  return speedup;
}

// A 4D diff across one session as the map grows: the office's sessions added again and again
// (every added session changes about as much as its predecessor did).
std::pair<double, double> benchTemporalDiff(const std::vector<SessionMap>& maps) {
  std::printf("\n4D diff across the last session as sessions accumulate (hard mode):\n"
              "sessions  nodes_4d  changed_voxels  inner_nodes_visited  diff_ms  diff_of_snapshots_ms\n");
  TemporalMap m(maps.front().resolution_m());
  double first = 0.0, last = 0.0;
  size_t next_report = 6;
  for (size_t i = 0; i < 48; ++i) {
    m.add(3600.0 * static_cast<double>(i), maps[i % maps.size()]);
    if (i + 1 != next_report) continue;
    next_report *= 2;
    const double t1 = 3600.0 * static_cast<double>(i - 1), t2 = 3600.0 * static_cast<double>(i);
    diff(m, t1, t2);  // builds the change summary once
    DiffStats st;
    size_t changed = 0;
    const double ms = bestMs(5, [&] { changed = diff(m, t1, t2, {}, &st).voxelCount(); });
    const double snap_ms = bestMs(1, [&] { diff(m.snapshot(t1), m.snapshot(t2)); });
    std::printf("%8zu  %8zu  %14zu  %19zu  %7.2f  %20.1f\n", i + 1, m.counts().nodes(), changed,
                st.inner_nodes_visited, ms, snap_ms);
    if (first == 0.0) first = ms;
    last = ms;
  }
  return {first, last};
}

SimSummary evaluateSimulation(const std::string& name, const fs::path& dir, bool sweep,
                              const RegisterSettings& reg, int rounds) {
  std::printf("\n== %s (%s) ==\n", name.c_str(), dir.c_str());
  const auto start = std::chrono::steady_clock::now();
  const SimSessions s = loadSimulation(dir, true);
  const size_t pairs = s.estimated.size() - 1;
  std::printf("%zu sessions, %zu change events, integrated in %.1f s\n", s.estimated.size(), s.events.size(),
              seconds(start));
  // Noise reduction (docs/realign.md): every session registered to the consensus of all
  // (`rounds` rounds, re-integrated with its correction), then also re-aligned voxel by voxel.
  const auto reg_start = std::chrono::steady_clock::now();
  std::vector<PoseCorrection> corrections;
  const std::vector<SessionMap> registered = g_to_truth
                                                 ? bench::registerSimulationToTruth(s, reg, rounds, &corrections)
                                                 : bench::registerSimulation(s, reg, rounds, &corrections);
  if (g_to_truth) std::printf("each session registered alone against the consensus of the true-pose maps\n");
  std::vector<SessionMap> realigned;
  {
    const SessionMap avg = consensus(std::span<const SessionMap>(registered));
    for (const SessionMap& m : registered) realigned.push_back(realign(m, avg));
  }
  char path_knots[96];
  std::snprintf(path_knots, sizeof path_knots, "%.2f m of path (prior %.3f m, %.2f deg per m^0.5)", reg.drift_knot_m,
                reg.drift_per_m, reg.drift_yaw_per_m_deg);
  const std::string drift =
      !reg.drift() ? ""
                   : ", then " + std::to_string(reg.drift_rounds) + " rounds of drift knots every " +
                         (reg.drift_knot_m > 0.0 ? std::string(path_knots)
                                                 : std::to_string(reg.drift_knot_frames) + " frames");
  const std::string options =
      std::string(reg.planar ? ", planar" : "") + (reg.drift_points ? ", drift on points" : "") +
      (reg.fine_radius_voxels > 0.0 ? ", later drift rounds at " + std::to_string(reg.fine_radius_voxels).substr(0, 4) + " voxels" : "") +
      (reg.keep_mean ? ", mean kept" : "");
  std::printf("registered (%d rounds, %s corrections%s; radius %.2f voxels%s) and re-aligned in %.1f s\n", rounds,
              toString(reg.model), drift.c_str(), reg.radius_voxels, options.c_str(),
              seconds(reg_start));
  const bench::RelativePoseError relative = bench::printPoseErrors(s.dirs, corrections);
  std::vector<SessionMap> nightly;
  if (g_nightly) {
    const auto night_start = std::chrono::steady_clock::now();
    std::vector<PoseCorrection> night_corrections;
    nightly = bench::registerSimulationNightly(s, reg, rounds, &night_corrections);
    std::printf("registered night by night (each session against the consensus of those before it, as the "
                "streaming build registers one recording a night) in %.1f s\n",
                seconds(night_start));
    bench::printPoseErrors(s.dirs, night_corrections);
  }

  auto row = [&](const char* poses, const std::vector<SessionMap>& maps, const DiffSettings& ds,
                 const SegmentSettings& ss, bool verbose = false) {
    size_t bad_pairs = 0;
    const auto t = std::chrono::steady_clock::now();
    const ChangeScore c = scorePairs(maps, s.events, ds, ss, &bad_pairs);
    std::printf("%-9s %-10s %5.2f %5d %5.2f %-7s %5llu | %9.3f %9.3f | %4zu/%-4zu %7.3f | %10.2f %9zu | %6.2f\n",
                poses, toString(ds.mode), ds.effectiveAlpha(), ds.neighbourhood_voxels, ds.min_shift_voxels,
                toString(ss.connectivity),
                static_cast<unsigned long long>(ss.min_voxels), c.precision(), c.recall(), c.events_found,
                c.events_observable,
                c.events_observable ? double(c.events_found) / double(c.events_observable) : 1.0,
                double(c.false_components) / double(pairs), bad_pairs, seconds(t));
    if (verbose) {
      for (const std::string& m : c.missed_events) std::printf("            missed: %s\n", m.c_str());
    }
    return c;
  };
  std::printf("poses     mode       alpha nbhd shift  conn    min_v | voxel_prec voxel_rec | objects  recall | "
              "false/pair >1 false | seconds\n");
  const ChangeScore headline = row("register", registered, defaultDiff(), defaultSegment(), true);
  if (g_nightly) row("nightly", nightly, defaultDiff(), defaultSegment(), true);
  row("true", s.truth_pose, defaultDiff(), defaultSegment(), true);
  row("reg+align", realigned, defaultDiff(), defaultSegment(), true);
  row("estimated", s.estimated, defaultDiff(), defaultSegment(), true);
  std::printf("findChanges with the defaults, of two session maps or of the 4D map of all sessions:\n"
              "(4D, 1st pos: the map keeps a voxel's first hit positions while its state stays; 4D, last obs: each voxel "
              "as last observed, not as the two sessions saw it)\n"
              "poses     answered from | voxel_prec voxel_rec | objects   | false/pair | objects/pair moves/pair | moves: true same_event false missed | 4D nodes  | seconds\n");
  ChangeSettings cs = recommendedChangeSettings();
  cs.diff = defaultDiff();
  printOneCall("register", registered, s.events, cs);
  if (g_nightly) printOneCall("nightly", nightly, s.events, cs);
  printOneCall("true", s.truth_pose, s.events, cs);
  std::printf("moves with alike footprints (MoveSettings::alike_footprints):\n");
  ChangeSettings footprints = cs;
  footprints.moves.alike_footprints = true;
  printOneCall("register", registered, s.events, footprints);
  printOneCall("true", s.truth_pose, s.events, footprints);
  std::printf("without the shift test (min shift 0):\n");
  const ChangeScore unshifted = row("register", registered, noShiftDiff(), defaultSegment(), true);
  row("true", s.truth_pose, noShiftDiff(), defaultSegment(), true);
  row("reg+align", realigned, noShiftDiff(), defaultSegment(), true);
  row("estimated", s.estimated, noShiftDiff(), defaultSegment(), true);
  if (sweep) {
    for (const char* poses : {"estimated", "true", "register", "reg+align"}) {
      const auto& maps = std::strcmp(poses, "true") == 0        ? s.truth_pose
                         : std::strcmp(poses, "register") == 0  ? registered
                         : std::strcmp(poses, "reg+align") == 0 ? realigned
                                                                : s.estimated;
      for (DiffMode m : {DiffMode::Hard, DiffMode::Threshold, DiffMode::Band, DiffMode::Continuous}) {
        for (int nb : {0, 1, 2}) {
          DiffSettings ds;
          ds.mode = m;
          ds.neighbourhood_voxels = nb;
          if (m == DiffMode::Continuous && nb > 0) continue;
          row(poses, maps, ds, defaultSegment());
        }
      }
      for (Connectivity c : {Connectivity::Face, Connectivity::Edge}) {
        SegmentSettings ss = defaultSegment();
        ss.connectivity = c;
        row(poses, maps, defaultDiff(), ss);
      }
      for (uint64_t mv : {1, 10, 50}) {
        SegmentSettings ss = defaultSegment();
        ss.min_voxels = mv;
        row(poses, maps, defaultDiff(), ss);
      }
      // The shift test's threshold and the component size.
      for (double shift : {0.3, 0.4, 0.5, 0.6, 0.7}) {
        for (uint64_t mv : {20, 30, 40}) {
          DiffSettings ds = defaultDiff();
          ds.min_shift_voxels = shift;
          SegmentSettings ss = defaultSegment();
          ss.min_voxels = mv;
          row(poses, maps, ds, ss, true);
        }
      }
      // Without the neighbourhood rule (which hides one-voxel moves), larger components only.
      for (uint64_t mv : {30, 50, 100}) {
        DiffSettings ds = noShiftDiff();
        ds.neighbourhood_voxels = 0;
        SegmentSettings ss = defaultSegment();
        ss.min_voxels = mv;
        row(poses, maps, ds, ss, true);
      }
    }
  }
  SimSummary out;
  out.segment_speedup = benchSegmentation(s.estimated);
  std::tie(out.diff_ms_first, out.diff_ms_last) = benchTemporalDiff(s.estimated);
  out.object_recall =
      headline.events_observable ? double(headline.events_found) / double(headline.events_observable) : 1.0;
  out.false_components_per_pair = double(headline.false_components) / double(pairs);
  out.voxel_precision = headline.precision();
  out.voxel_recall = headline.recall();
  out.no_shift_object_recall =
      unshifted.events_observable ? double(unshifted.events_found) / double(unshifted.events_observable) : 1.0;
  out.no_shift_false_components_per_pair = double(unshifted.false_components) / double(pairs);
  out.relative_pose_mm = 1e3 * relative.rms_m;
  out.relative_heading_deg = relative.heading_deg;
  return out;
}

// ------------------------------------------------------------------------------------------
// Real data

SessionMap integrateCloud(const PointCloud& cloud, double resolution_m, double max_range_m) {
  Frame f;
  f.cloud = cloud;
  SessionMap m(resolution_m);
  IntegratorSettings is;
  is.max_range_m = max_range_m;
  integrate(FrameVector({f}), m, is);
  return m;
}

struct MosdResult {
  size_t found = 0, total = 0, false_components = 0, pairs = 0;
  size_t observable = 0, observable_found = 0;  // placements with >= 20 voxels known in both shots
};

// mOSD group A: objects (labels 10k..10k+9) re-arranged between shots of an unmoved camera.
MosdResult evaluateMosd(const fs::path& dir) {
  constexpr double kResolution = 0.01;  // the objects are boxes and cans of 5-20 cm
  std::printf("\n== mOSD group A (%s) ==\n", dir.c_str());
  std::vector<PointCloud> clouds;
  for (int i = 0; i < 5; ++i) clouds.push_back(readPcd(dir / ("test" + std::to_string(i) + ".pcd")));
  std::vector<SessionMap> maps;
  // Per shot: object number -> the voxels its points fall in.
  std::vector<std::map<uint32_t, std::set<VoxelKey>>> objects;
  for (const PointCloud& c : clouds) {
    maps.push_back(integrateCloud(c, kResolution, 3.0));
    std::map<uint32_t, std::set<VoxelKey>> objs;
    for (size_t i = 0; i < c.points.size(); ++i) {
      if (i >= c.labels.size() || c.labels[i] < 10 || !c.points[i].allFinite()) continue;
      if (auto k = maps.back().grid().keyOf(c.points[i].cast<double>())) objs[c.labels[i] / 10].insert(*k);
    }
    objects.push_back(std::move(objs));
  }
  auto iou = [](const std::set<VoxelKey>& a, const std::set<VoxelKey>& b) {
    size_t inter = 0;
    for (const auto& k : a) inter += b.count(k);
    return double(inter) / double(a.size() + b.size() - inter);
  };
  MosdResult r;
  // Objects are numbered anew in every shot, so a moved object is two placements: where it was
  // (no object of the next shot there) and where it is (no object of the previous shot there).
  std::printf("pair  changed_placements  observable  found  observable_found  components  false_components\n");
  for (size_t k = 1; k < maps.size(); ++k) {
    const DiffMap d = diff(maps[k - 1], maps[k], noShiftDiff());
    SegmentSettings ss = defaultSegment();
    ss.min_voxels = 10;
    const Segmentation seg = segment(d, ss);
    // An object moved when no object of the other shot occupies nearly the same voxels.
    std::vector<const std::set<VoxelKey>*> moved;
    for (size_t side = 0; side < 2; ++side) {
      const auto& mine = objects[k - 1 + side];
      const auto& other = objects[k - side];
      for (const auto& [id, vox] : mine) {
        double best = 0.0;
        for (const auto& [id2, vox2] : other) best = std::max(best, iou(vox, vox2));
        if (best < 0.5) moved.push_back(&vox);
      }
    }
    // Found: a component holds a voxel within one voxel of the object's.
    std::vector<uint8_t> component_used(seg.components.size(), 0);
    size_t found = 0, observable = 0, observable_found = 0;
    for (const auto* vox : moved) {
      // As for the simulator's events: a placement whose voxels one shot never saw (hidden
      // behind another object) cannot show in a diff, where unknown is never a change.
      const size_t known = static_cast<size_t>(std::count_if(vox->begin(), vox->end(), [&](const VoxelKey& o) {
        return maps[k - 1].stateOf(o) != VoxelState::Unknown && maps[k].stateOf(o) != VoxelState::Unknown;
      }));
      const bool is_observable = known >= 20;
      bool hit = false;
      for (size_t c = 0; c < seg.components.size(); ++c) {
        for (uint32_t idx : seg.components[c].cells) {
          const VoxelKey& key = d.cells()[idx].key;
          for (const VoxelKey& o : *vox) {
            if (std::abs(key.x - o.x) <= 1 && std::abs(key.y - o.y) <= 1 && std::abs(key.z - o.z) <= 1) {
              hit = true;
              component_used[c] = 1;
              break;
            }
          }
          if (component_used[c]) break;
        }
      }
      found += hit;
      observable += is_observable;
      observable_found += is_observable && hit;
      if (!hit) {
        std::printf("      missed: a placement of %zu voxels, %zu of them known in both shots\n", vox->size(), known);
      }
    }
    const size_t false_components =
        static_cast<size_t>(std::count(component_used.begin(), component_used.end(), uint8_t{0}));
    std::printf("%zu->%zu  %18zu  %10zu  %5zu  %16zu  %10zu  %16zu\n", k - 1, k, moved.size(), observable, found,
                observable_found, seg.components.size(), false_components);
    r.found += found;
    r.observable += observable;
    r.observable_found += observable_found;
    r.total += moved.size();
    r.false_components += false_components;
    ++r.pairs;
  }
  return r;
}

// nvblox's human_dataset: a static camera, a person walking. Share of frame 2's pixels whose
// point falls in a voxel that appeared after frame 1.
double evaluateHuman(const fs::path& dir) {
  std::printf("\n== human_dataset (%s) ==\n", dir.c_str());
  const CameraIntrinsics k = readIntrinsicsFile(dir / "camera-intrinsics.txt");
  const ImageU16 d1 = readPngU16(dir / "depth_image_1.png");
  const ImageU16 d2 = readPngU16(dir / "depth_image_2.png");
  const PointCloud c1 = depthToCloud(d1, nullptr, k, 1000.0, "depth_image_1.png");
  const PointCloud c2 = depthToCloud(d2, nullptr, k, 1000.0, "depth_image_2.png");
  constexpr double kResolution = 0.05, kRange = 9.0;  // depth reaches 8.2 m
  const SessionMap m1 = integrateCloud(c1, kResolution, kRange), m2 = integrateCloud(c2, kResolution, kRange);
  const DiffMap d = diff(m1, m2, noShiftDiff());
  std::unordered_set<uint64_t> appeared;
  for (const ChangeCell& c : d.cells()) {
    if (c.kind == ChangeKind::Appeared) appeared.insert(mortonEncode(c.key));
  }
  size_t flagged = 0;
  for (const auto& p : c2.points) {
    if (!p.allFinite()) continue;
    const auto key = m2.grid().keyOf(p.cast<double>());
    if (key && appeared.count(mortonEncode(*key))) ++flagged;
  }
  const double fraction = double(flagged) / double(c2.points.size());
  std::printf("frame 2: %zu of %zu pixels flagged changed (%.1f %%; nvblox's test accepts 5-20 %%); diff: %llu "
              "appeared, %llu vanished voxels\n",
              flagged, c2.points.size(), 100.0 * fraction,
              static_cast<unsigned long long>(d.voxelCount(ChangeKind::Appeared)),
              static_cast<unsigned long long>(d.voxelCount(ChangeKind::Vanished)));
  return fraction;
}

// PCL grabber sequence: three frames of a static scene. Changed voxels / voxels known in both.
double evaluateGrabber(const fs::path& dir) {
  std::printf("\n== grabber_sequences (%s) ==\n", dir.c_str());
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".pcd") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  std::vector<SessionMap> maps;
  for (const auto& f : files) maps.push_back(integrateCloud(readPcd(f), 0.05, 3.0));
  uint64_t changed = 0, known = 0;
  for (size_t k = 1; k < maps.size(); ++k) {
    const DiffMap d = diff(maps[k - 1], maps[k], noShiftDiff());
    DiffSettings all;
    all.mode = DiffMode::Continuous;
    const uint64_t both = diff(maps[k - 1], maps[k], all).voxelCount();
    const uint64_t ch = d.voxelCount(ChangeKind::Appeared) + d.voxelCount(ChangeKind::Vanished);
    std::printf("frame %zu->%zu: %llu of %llu voxels known in both flagged changed\n", k - 1, k,
                static_cast<unsigned long long>(ch), static_cast<unsigned long long>(both));
    changed += ch;
    known += both;
  }
  return known ? double(changed) / double(known) : 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  {  // --seeds A-B: this program once per simulated seed, and the spread of its figures (seeds.h)
    SimulationSettings s;
    s.preset = "office";
    s.resolution_scale = 0.5;
    if (const int rc = bench::runOverSeeds(argc, argv, "--office", s); rc >= 0) return rc;
  }
  fs::path office, floor66, data = CHRONOMAP_DEFAULT_DATA_DIR;
  bool quick = false;
  int rounds = recommendedRegistration().rounds;
  RegisterSettings reg = recommendedRegistration().align;  // as the README's `build --register ...`
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--register-preset") && i + 1 < argc) {
      if (i != 1) {
        std::fprintf(stderr, "change_eval: --register-preset must come first (the flags after it change it)\n");
        return 2;
      }
      try {
        const RegistrationSettings named = registrationNamed(argv[++i]);
        reg = named.align;
        rounds = named.rounds;
      } catch (const UsageError& e) {
        std::fprintf(stderr, "change_eval: %s\n", e.what());
        return 2;
      }
    } else if (!std::strcmp(argv[i], "--drift-knots") && i + 1 < argc) {
      reg.drift_knot_frames = std::atoi(argv[++i]);
      reg.drift_knot_m = 0.0;
    } else if (!std::strcmp(argv[i], "--drift-path") && i + 1 < argc) {
      reg.drift_knot_m = std::atof(argv[++i]);
      reg.drift_knot_frames = 0;
    } else if (!std::strcmp(argv[i], "--drift-path-m") && i + 1 < argc) {
      reg.drift_per_m = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--drift-path-yaw") && i + 1 < argc) {
      reg.drift_yaw_per_m_deg = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--register-radius") && i + 1 < argc) {
      reg.radius_voxels = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--drift-rounds") && i + 1 < argc) {
      reg.drift_rounds = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--fine-radius") && i + 1 < argc) {
      reg.fine_radius_voxels = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--drift-per-frame") && i + 1 < argc) {
      reg.drift_per_frame_m = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--drift-yaw-per-frame") && i + 1 < argc) {
      reg.drift_yaw_per_frame_deg = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--kept-surface") && i + 1 < argc) {
      g_kept_surface = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--kept-share") && i + 1 < argc) {
      g_kept_share = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--dark-surface") && i + 1 < argc) {
      g_dark_surface = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--dark-below") && i + 1 < argc) {
      g_dark_below = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--dark-contrast") && i + 1 < argc) {
      g_dark_contrast = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--min-shift") && i + 1 < argc) {
      g_min_shift = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--shift-plane") && i + 1 < argc) {
      g_shift_plane = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--dark-share") && i + 1 < argc) {
      g_dark_share = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--register-to-truth")) {
      g_to_truth = true;
    } else if (!std::strcmp(argv[i], "--nightly")) {
      g_nightly = true;
    } else if (!std::strcmp(argv[i], "--keep-mean")) {
      reg.keep_mean = true;
    } else if (!std::strcmp(argv[i], "--not-planar")) {
      reg.planar = false;
    } else if (!std::strcmp(argv[i], "--drift-voxels")) {
      reg.drift_points = false;
    } else if (!std::strcmp(argv[i], "--register-rounds") && i + 1 < argc) {
      rounds = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--register-model") && i + 1 < argc) {
      reg.model = parseCorrectionModel(argv[++i]);
    } else if (!std::strcmp(argv[i], "--office") && i + 1 < argc) {
      office = argv[++i];
    } else if (!std::strcmp(argv[i], "--floor66") && i + 1 < argc) {
      floor66 = argv[++i];
    } else if (!std::strcmp(argv[i], "--data") && i + 1 < argc) {
      data = argv[++i];
    } else if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--sensor") && i + 1 < argc) {
      bench::setSimSensor(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: change_eval [--office DIR] [--floor66 DIR] [--data DIR] [--quick] [--sensor ideal|kinect|realsense] "
                   "[--register-preset localiser|odometry (first)] [--register-model world|per-pose] [--drift-knots FRAMES] [--drift-path M] [--keep-mean] [--register-rounds N] "
                   "[--register-radius VOXELS] [--drift-rounds N] [--fine-radius VOXELS] [--not-planar] [--drift-voxels] [--kept-surface R] "
                   "[--kept-share F] [--min-shift S] [--shift-plane R] [--dark-surface R] [--dark-below B] [--dark-contrast C] [--dark-share F] [--nightly]\n");
      return 2;
    }
  }
  try {
    fs::path tmp;
    if (office.empty()) {
      tmp = bench::simulateTemporary("office", "change_eval");
      office = tmp;
    }
    reg.validate();
    const SimSummary o = evaluateSimulation("office", office, !quick, reg, rounds);
    if (!floor66.empty()) evaluateSimulation("floor66", floor66, false, reg, rounds);
    const MosdResult mosd = evaluateMosd(data / "mosd-a" / "test");
    const double human = evaluateHuman(data / "3dmatch" / "human_dataset");
    const double grabber = evaluateGrabber(data / "pcl-kinect" / "grabber_sequences" / "pcd");
    if (!tmp.empty()) fs::remove_all(tmp);
    std::printf("\n%s\n", nlohmann::json{{"office_object_recall", o.object_recall},
                                         {"office_segment_speedup_vs_floodfill", o.segment_speedup},
                                         {"office_4d_diff_ms_6_sessions", o.diff_ms_first},
                                         {"office_4d_diff_ms_48_sessions", o.diff_ms_last},
                                         {"office_false_components_per_pair", o.false_components_per_pair},
                                         {"office_voxel_precision", o.voxel_precision},
                                         {"office_voxel_recall", o.voxel_recall},
                                         {"office_no_shift_object_recall", o.no_shift_object_recall},
                                         {"office_no_shift_false_components_per_pair",
                                          o.no_shift_false_components_per_pair},
                                         {"office_relative_pose_mm", o.relative_pose_mm},
                                         {"office_relative_heading_deg", o.relative_heading_deg},
                                         {"mosd_a_found", mosd.found},
                                         {"mosd_a_total", mosd.total},
                                         {"mosd_a_observable", mosd.observable},
                                         {"mosd_a_observable_found", mosd.observable_found},
                                         {"mosd_a_false_components_per_pair",
                                          mosd.pairs ? double(mosd.false_components) / double(mosd.pairs) : 0.0},
                                         {"human_changed_fraction", human},
                                         {"grabber_false_change_rate", grabber}}
                                  .dump()
                                  .c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "change_eval: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
