// chronomap diff | segment: what changed, and which objects.

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/analysis/changes.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/core/format.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/export/export.h"
#include "chronomap/core/file.h"
#include "chronomap/pipeline/maps.h"
#include "commands.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

// ------------------------------------------------------------------------------------------
// diff

struct DiffCmdOptions {
  std::string before;
  std::string after;
  std::string preset = "recommended";
  // Each setting unset: the preset's.
  std::optional<std::string> mode;
  std::optional<double> alpha;
  std::optional<int> neighbourhood;
  std::optional<double> min_shift_voxels;
  std::optional<double> shift_plane;
  std::optional<int> kept_surface;
  std::optional<double> kept_share;
  std::optional<int> dark_surface;
  std::optional<double> dark_below;
  std::optional<double> dark_contrast;
  std::optional<double> dark_share;
  bool seen_at_both = false;
  bool last_observed = false;
  std::optional<std::string> connectivity;
  std::optional<uint64_t> min_voxels;
  bool moves = false;
  bool no_moves = false;
  std::string output;
  std::string ply;
  std::optional<double> colour_distance;  ///< set: also compare colours
  bool lighting_invariant = false;
  std::optional<double> memory_limit_gib;
  bool json = false;
};

/// The colour part of a diff: two times of one 4D map, their colours compared.
nlohmann::json colourDiff(const DiffCmdOptions& o, const MapRef& before, const MapRef& after) {
  ColourDiffSettings cs;
  cs.distance = *o.colour_distance;
  cs.lighting_invariant = o.lighting_invariant;
  const ColourDiffReport r = colourDiffMaps(before, after, cs);
  nlohmann::json j;
  if (r.model) {
    j["colour_model"] = {{"voxels", r.model->keys.size()}, {"sessions", r.model->sessions}, {"rms_error", r.model->rms_error}};
  }
  j["colour_distance"] = cs.distance;
  j["lighting_invariant"] = cs.lighting_invariant;
  j["colour_compared"] = r.diff.compared;
  j["colour_changed"] = r.diff.changes.size();
  return j;
}

template <class T, class V>
void setIfGiven(T& field, const std::optional<V>& value) {
  if (value) field = static_cast<T>(*value);
}

/// The settings of the command: the preset's, each flag given replacing one, checked.
ChangeSettings changeSettingsOf(const DiffCmdOptions& o) {
  ChangeSettings s = changeSettingsNamed(o.preset);
  DiffSettings& d = s.diff;
  if (o.mode) {
    const DiffMode mode = parseDiffMode(*o.mode);
    if (mode != d.mode) d.alpha = -1.0;  // the new mode's own default
    d.mode = mode;
  }
  if (o.alpha) {
    if (d.mode != DiffMode::Threshold && d.mode != DiffMode::Band) {
      throw UsageError(std::string("--alpha applies to the threshold and band modes only (the ") + toString(d.mode) +
                       " mode has none)");
    }
    d.alpha = *o.alpha;
  }
  setIfGiven(d.neighbourhood_voxels, o.neighbourhood);
  setIfGiven(d.min_shift_voxels, o.min_shift_voxels);
  setIfGiven(d.shift_plane_ratio, o.shift_plane);
  setIfGiven(d.kept_surface_radius_voxels, o.kept_surface);
  setIfGiven(d.kept_surface_share, o.kept_share);
  setIfGiven(d.dark_surface_radius_voxels, o.dark_surface);
  setIfGiven(d.dark_surface_brightness, o.dark_below);
  setIfGiven(d.dark_surface_contrast, o.dark_contrast);
  setIfGiven(d.dark_surface_share, o.dark_share);
  if (o.seen_at_both && o.last_observed) throw UsageError("--seen-at-both and --last-observed were both given; give one");
  if (o.seen_at_both) d.seen_at_both = true;
  if (o.last_observed) d.seen_at_both = false;
  if (o.connectivity) s.segment.connectivity = parseConnectivity(*o.connectivity);
  setIfGiven(s.segment.min_voxels, o.min_voxels);
  if (o.moves && o.no_moves) throw UsageError("--moves and --no-moves were both given; give one");
  if (o.moves) s.moves.pair = true;
  if (o.no_moves) s.moves.pair = false;
  s.validate();
  return s;
}

/// The preset's name, and whether flags changed its settings.
std::string presetLabel(const DiffCmdOptions& o, const ChangeSettings& settings) {
  const bool same = changeSettingsJson(settings) == changeSettingsJson(changeSettingsNamed(o.preset));
  return same ? o.preset : o.preset + ", changed by flags";
}

/// "3 objects: 1 appeared, 1 vanished, 1 moved", then one line per object.
void printObjects(const std::vector<ChangedObject>& objects) {
  size_t count[3] = {0, 0, 0};
  for (const ChangedObject& c : objects) ++count[static_cast<int>(c.kind)];
  std::cout << countOf(objects.size(), "object") << ": " << count[0] << " appeared, " << count[1] << " vanished, "
            << count[2] << " moved\n";
  std::cout << std::fixed << std::setprecision(2);
  for (const ChangedObject& c : objects) {
    const Eigen::Vector3d p = c.centroid_m, size = c.size_m();
    std::cout << std::setw(6) << c.id << "  " << std::left << std::setw(8) << toString(c.kind) << std::right
              << std::setw(8) << c.voxels << " voxels at (" << p.x() << ", " << p.y() << ", " << p.z() << ") m, "
              << size.x() << " x " << size.y() << " x " << size.z() << " m";
    if (c.kind == ObjectChange::Moved) {
      const Eigen::Vector3d f = c.from.centroid_m;
      std::cout << ", from (" << f.x() << ", " << f.y() << ", " << f.z() << "), " << c.distance_m << " m";
    }
    std::cout << "\n";
  }
  std::cout.unsetf(std::ios::floatfield);
  std::cout << std::setprecision(6);
}

/// The summary --json prints.
nlohmann::json diffJson(const DiffCmdOptions& o, const ChangeSettings& settings, const Changes& c, double seconds) {
  return {{"mode", toString(settings.diff.mode)},
          {"alpha", settings.diff.effectiveAlpha()},
          {"preset", presetLabel(o, settings)},
          {"settings", changeSettingsJson(settings)},
          {"changed_voxels", c.appeared_voxels + c.vanished_voxels},
          {"appeared", c.appeared_voxels},
          {"vanished", c.vanished_voxels},
          {"cells", c.diff.cells().size()},
          {"objects", changedObjectsJson(c.objects)},
          {"objects_dropped", c.segmentation.dropped},
          {"output", o.output},
          {"seconds", seconds}};
}

void printDiff(const DiffCmdOptions& o, const ChangeSettings& settings, const Changes& c,
               const nlohmann::json& colour) {
  if (o.colour_distance) {
    std::cout << "colour: " << colour["colour_changed"].get<size_t>() << " of " << colour["colour_compared"].get<size_t>()
              << " voxels occupied at both times changed colour by more than " << *o.colour_distance
              << (o.lighting_invariant ? " beyond what the change of light explains" : "") << "\n";
  }
  std::cout << toString(settings.diff.mode) << " diff (" << presetLabel(o, settings)
            << " settings): " << c.appeared_voxels + c.vanished_voxels << " voxels changed (" << c.appeared_voxels
            << " appeared, " << c.vanished_voxels << " vanished)";
  if (settings.diff.mode == DiffMode::Continuous) std::cout << "; " << c.diff.voxelCount() << " voxels known in both";
  std::cout << "\n";
  printObjects(c.objects);
  std::cout << "wrote " << o.output << (o.ply.empty() ? "" : " and " + o.ply) << "\n";
}

int runDiff(const DiffCmdOptions& o) {
  const ChangeSettings settings = changeSettingsOf(o);
  requireExtension(o.output, ".cmap", "output");
  if (!o.ply.empty()) requireExtension(o.ply, ".ply", "--ply");
  const MapRef before = parseMapRef(o.before), after = parseMapRef(o.after);
  const std::vector<fs::path> inputs = {before.path, after.path};
  checkOutputs({{o.output, "-o"}, {o.ply, "--ply"}}, inputs);
  const auto start = std::chrono::steady_clock::now();
  if (o.lighting_invariant && !o.colour_distance) throw UsageError("--lighting-invariant applies to --colour");
  const nlohmann::json colour = o.colour_distance ? colourDiff(o, before, after) : nlohmann::json::object();
  const Changes c = changesBetween(before, after, settings, tileCacheSettings(o.memory_limit_gib));
  writeDiffMap(o.output, c, settings, presetLabel(o, settings),
               {{"created_by", "chronomap diff"}, {"before", o.before}, {"after", o.after}});
  std::vector<ChangeCell> changed;
  for (const ChangeCell& cell : c.diff.cells()) {
    if (cell.kind != ChangeKind::Unchanged) changed.push_back(cell);
  }
  if (!o.ply.empty()) exportDiffPly(o.ply, c.diff, changed);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (o.json) {
    nlohmann::json j = diffJson(o, settings, c, seconds);
    j.update(colour);
    std::cout << j.dump() << "\n";
  } else {
    printDiff(o, settings, c, colour);
  }
  return 0;
}

// ------------------------------------------------------------------------------------------
// segment

struct SegmentCmdOptions {
  std::string input;
  std::string connectivity = "face";
  double colour_tolerance = -1.0;
  uint64_t min_voxels = 1;
  double min_value = SegmentSettings{}.min_value;
  std::string output_dir;
  bool json = false;
};

int runSegment(const SegmentCmdOptions& o) {
  SegmentSettings settings;
  settings.connectivity = parseConnectivity(o.connectivity);
  settings.colour_tolerance = o.colour_tolerance;
  settings.min_voxels = o.min_voxels;
  settings.min_value = o.min_value;
  settings.validate();
  checkOutputs({{o.output_dir, "-o", true}}, {o.input});
  const DiffMap d = readDiffMap(o.input);
  const auto start = std::chrono::steady_clock::now();
  const Segmentation seg = segment(d, settings);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  nlohmann::json summary = segmentationJson(seg, settings);
  summary["seconds"] = seconds;
  if (!o.output_dir.empty()) writeComponents(o.output_dir, d, seg, o.input, summary);
  if (o.json) {
    std::cout << summary.dump() << "\n";
    return 0;
  }
  std::cout << seg.components.size() << " components (" << toString(settings.connectivity) << " connectivity";
  if (settings.colour_tolerance >= 0) std::cout << ", colour tolerance " << settings.colour_tolerance;
  std::cout << ")";
  if (seg.dropped) std::cout << ", " << seg.dropped << " smaller than " << settings.min_voxels << " voxels dropped";
  std::cout << "\n";
  if (!seg.components.empty()) {
    std::cout << "    id  kind      voxels   volume m3   centroid x, y, z (m)        size x, y, z (m)      colour\n";
  }
  std::cout << std::fixed;
  for (const Component& c : seg.components) {
    const Eigen::Vector3d size = c.bbox_max_m - c.bbox_min_m;
    std::cout << std::setw(6) << c.id << "  " << std::left << std::setw(8) << toString(c.kind) << std::right
              << std::setw(8) << c.voxels << std::setw(12) << std::setprecision(4) << c.volume_m3 << "   "
              << std::setprecision(2) << std::setw(6) << c.centroid_m.x() << ", " << std::setw(6) << c.centroid_m.y()
              << ", " << std::setw(6) << c.centroid_m.z() << "   " << std::setw(5) << size.x() << ", "
              << std::setw(5) << size.y() << ", " << std::setw(5) << size.z() << "   #" << std::hex
              << std::setfill('0') << std::setw(2) << int{c.mean_colour.r} << std::setw(2) << int{c.mean_colour.g}
              << std::setw(2) << int{c.mean_colour.b} << std::dec << std::setfill(' ') << "\n";
  }
  if (!o.output_dir.empty()) {
    std::cout << "wrote " << seg.components.size() << " components (.cmap and .ply each) and components.json to "
              << o.output_dir << "\n";
  }
  return 0;
}

}  // namespace

/// The one line --help gives for a preset: its settings as the flags that would set them.
std::string presetFlags(const ChangeSettings& s) {
  const DiffSettings& d = s.diff;
  std::string text = std::string("--mode ") + toString(d.mode);
  if (d.mode == DiffMode::Threshold || d.mode == DiffMode::Band) text += " --alpha " + exactNumber(d.effectiveAlpha());
  text += " --neighbourhood " + std::to_string(d.neighbourhood_voxels) + " --min-shift " +
          exactNumber(d.min_shift_voxels) + " --shift-plane " + exactNumber(d.shift_plane_ratio) +
          " --kept-surface " + std::to_string(d.kept_surface_radius_voxels) + " --kept-share " +
          exactNumber(d.kept_surface_share) + " --dark-surface " + std::to_string(d.dark_surface_radius_voxels) +
          " --dark-below " + exactNumber(d.dark_surface_brightness) + " --dark-contrast " +
          exactNumber(d.dark_surface_contrast) + " --dark-share " + exactNumber(d.dark_surface_share) +
          (d.seen_at_both ? " --seen-at-both" : " --last-observed") + "; objects: --connectivity " +
          toString(s.segment.connectivity) + " --min-voxels " + std::to_string(s.segment.min_voxels) +
          (s.moves.pair ? " --moves" : " --no-moves");
  return text;
}

/// The rules that keep surfaces measured differently from counting as changes.
void addFalseChangeRules(CLI::App* app, DiffCmdOptions& o) {
  app->add_option("--neighbourhood", o.neighbourhood,
                  "ignore a voxel that appeared (vanished) when the other map is occupied within this many voxels: "
                  "surfaces shifted by localisation error are not changes (0..4; 0 compares twins only)");
  app->add_option("--min-shift", o.min_shift_voxels,
                  "voxels: with --neighbourhood, keep a voxel near a surface when that surface moved at least this far "
                  "(the mean position of the hits around it, from where in each voxel the rays ended); 0 drops them "
                  "all. 0.5 tells a chair pushed by 4 cm from a centimetre of pose error, in sessions registered with "
                  "build --register --register-drift 20 --register-planar --register-points (docs/changes.md)");
  app->add_option("--shift-plane", o.shift_plane,
                  "with --min-shift: where the hits around a voxel lie on a plane (their least spread at most this "
                  "share of the next), count only the plane's move across itself: a flat surface seen from "
                  "elsewhere, at a grazing angle or measured deeper slides along itself without moving (0..1; 0: "
                  "the whole move; docs/changes.md)");
  app->add_option("--kept-surface", o.kept_surface,
                  "voxels: a voxel that appeared (vanished) is no change when the surface the other map holds within "
                  "this many voxels is still seen, unchanged, by this map (--kept-share of its occupied voxels): "
                  "the same surface measured at another depth by some of a session's frames, as dark glossy "
                  "materials give on real depth cameras (0..4; 0: off; docs/changes.md)");
  app->add_option("--kept-share", o.kept_share, "the share --kept-surface needs still occupied, in (0, 1]");
  app->add_option("--dark-surface", o.dark_surface,
                  "voxels: an object (touching voxels that appeared, or that vanished) is no change when every one "
                  "of its voxels lies within this many voxels of a surface the other map sees and at least "
                  "--dark-share of them are dark (colour darker than --dark-below) and darker than that surface: "
                  "active depth cameras measure dark surfaces centimetres off (0..4; 0: off; docs/changes.md)");
  app->add_option("--dark-below", o.dark_below, "the mean colour (0..255) below which --dark-surface calls a surface dark");
  app->add_option("--dark-contrast", o.dark_contrast,
                  "--dark-surface needs the surface darker than this share of the other map's surface around it, "
                  "in (0, 1]");
  app->add_option("--dark-share", o.dark_share,
                  "the share of an object's voxels --dark-surface needs dark (and darker), in (0, 1]");
  app->add_flag("--seen-at-both", o.seen_at_both,
                "MAP@T1 MAP@T2: compare what the sessions in effect at T1 and T2 observed, as a diff of those two "
                "session maps does (a voxel neither saw is unknown)");
  app->add_flag("--last-observed", o.last_observed,
                "MAP@T1 MAP@T2: compare each voxel as last observed up to each time, so a change that the "
                "sessions between missed shows up at the first session that saw it");
}

/// The objects' settings: how changes join, the smallest object, moves.
void addObjectOptions(CLI::App* app, DiffCmdOptions& o) {
  app->add_option("--connectivity", o.connectivity, "objects: changes join across faces (face), edges (edge) or corners (vertex)");
  app->add_option("--min-voxels", o.min_voxels, "objects: smaller ones are none (their voxels stay in the diff)")
      ->check(numberIn(0, 1e18));
  app->add_flag("--moves", o.moves, "objects: pair a vanished and an appeared object that look alike as one moved");
  app->add_flag("--no-moves", o.no_moves, "objects: list the two halves of a move as a vanished and an appeared object");
}

Command addDiff(CLI::App& root) {
  auto o = std::make_shared<DiffCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "diff",
      "What changed from A to B (thesis §3.1), and which objects (appeared, vanished or moved, §3.2). A and B "
      "are session maps or MAP.cmap@TIME (a 4D map at a time; two times of one map compare only what changed "
      "in between). Unknown on either side is never a change. The recommended settings are the default; each "
      "flag below changes one of them, --preset raw gives the plain hard diff. Modes: hard (occupied <-> "
      "free), threshold (|P1 - P2| > alpha, default 0.4), band (hard with P in 0.5 +- alpha unknown, default "
      "0.1), continuous (|P1 - P2| for every voxel known in both). The settings and the objects are written "
      "into the diff's metadata.");
  app->add_option("A", o->before, "the earlier map: SESSION.cmap, MAP.cmap@TIME or TILED_FOLDER@TIME")->required();
  app->add_option("B", o->after, "the later map: SESSION.cmap, MAP.cmap@TIME or TILED_FOLDER@TIME")->required();
  app->add_option("--preset", o->preset,
                  "recommended (the default: " + presetFlags(recommendedChangeSettings()) +
                      ") or raw (the plain thesis diff, every real-data rule off: " +
                      presetFlags(rawChangeSettings()) + ")")
      ->capture_default_str();
  app->add_option("--mode", o->mode, "hard, threshold, band or continuous (default: the preset's)");
  app->add_option("--alpha", o->alpha,
                  "threshold (threshold mode, 0 to 1) or half band width (band mode, 0 to 0.5); other modes have none")
      ->check(numberIn(0, 1));
  addFalseChangeRules(app, *o);
  addObjectOptions(app, *o);
  app->add_option("-o,--output", o->output, "the diff to write (.cmap)")->required();
  app->add_option("--ply", o->ply, "also write the changed voxels as a PLY, coloured by what they show");
  app->add_option("--colour,--color", o->colour_distance,
                  "also count the voxels occupied at both times whose mean colour moved farther than this (8-bit RGB "
                  "units); A and B must be two times of one 4D map")
      ->check(numberIn(0.001, 442));
  app->add_option("--memory-limit", o->memory_limit_gib, kTileMemoryHelp)->check(numberIn(0, 1e6));
  app->add_flag("--lighting-invariant", o->lighting_invariant,
                "with --colour: a colour change that the change of light between the two hours explains is none "
                "(a sunset is not a change, a repainted box is). The light is a colour model learned from the map's "
                "sessions before the later time (chronomap predict --colour, docs/colour.md)");
  app->add_flag("--json", o->json, "print a JSON summary on stdout, with the objects");
  return {app, [o] { return runDiff(*o); }};
}

Command addSegment(CLI::App& root) {
  auto o = std::make_shared<SegmentCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "segment",
      "Split a diff into connected objects (thesis §3.2): voxel count, volume, bounding box, centroid, mean "
      "colour and whether it appeared or vanished, per component; -o writes each as its own .cmap and .ply "
      "at the original coordinates.");
  app->add_option("DIFF", o->input, "a diff written by chronomap diff (.cmap)")->required();
  app->add_option("--connectivity", o->connectivity, "face (6 neighbours), edge (18) or vertex (26)")
      ->capture_default_str();
  app->add_option("--color-tolerance,--colour-tolerance", o->colour_tolerance,
                  "join neighbours only when their colours differ by at most this (RGB distance, 0..441; "
                  "leave it out to ignore colour)")
      ->check(numberIn(0, std::numeric_limits<double>::max()));
  app->add_option("--min-voxels", o->min_voxels, "drop components with fewer voxels")
      ->check(numberIn(0, 1e18))
      ->capture_default_str();
  app->add_option("--min-value", o->min_value, "continuous diffs: voxels that take part have |P1 - P2| above this")
      ->capture_default_str();
  app->add_option("-o,--output", o->output_dir, "folder for one .cmap and .ply per component and components.json");
  app->add_flag("--json", o->json, "print the components as JSON on stdout");
  return {app, [o] { return runSegment(*o); }};
}

}  // namespace chronomap::cli
