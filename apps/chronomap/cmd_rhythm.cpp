// chronomap predict | costmap: the place at any time from temporal models of its 4D map, and
// where a ground robot should drive then.

#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/maps.h"
#include "chronomap/pipeline/rhythm.h"
#include "commands.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

/// The learning flags shared by predict and costmap.
struct LearnFlags {
  std::string model = "combined", learn_from, learn_to, rhythm_in, rhythm_out;
  uint32_t min_changes = 1;
  bool allow_other_map = false;
};

/// The flags as the library's learning settings (times parsed) for the map `map`.
LearnSettings learnSettings(const LearnFlags& f, const std::string& map) {
  LearnSettings s;
  s.map_name = map;
  s.allow_other_map = f.allow_other_map;
  s.warn = printWarning;
  if (!f.rhythm_in.empty()) s.saved = f.rhythm_in;
  if (!f.rhythm_out.empty()) s.save = f.rhythm_out;
  if (!f.learn_from.empty()) s.from_s = parseTime(f.learn_from);
  if (!f.learn_to.empty()) s.to_s = parseTime(f.learn_to);
  s.range_given = !f.learn_from.empty() || !f.learn_to.empty();
  s.min_changes = f.min_changes;
  return s;
}

void addLearnFlags(CLI::App* app, LearnFlags& f) {
  app->add_option("--model", f.model, "latest, mean, markov, periodic, hourly or combined")->capture_default_str();
  app->add_option("--learn-from", f.learn_from, "learn from sessions at or after this time (default: the first)");
  app->add_option("--learn-to", f.learn_to, "learn from sessions up to this time (default: the last)");
  app->add_option("--min-changes", f.min_changes, "model voxels that changed at least this often while learning")
      ->check(numberIn(1, 1e6))
      ->capture_default_str();
  app->add_option("--rhythm", f.rhythm_in, "use a model saved by --save-rhythm instead of fitting one");
  app->add_option("--save-rhythm", f.rhythm_out, "also save the fitted model (.rhythm) for later use");
  app->add_flag("--allow-other-map", f.allow_other_map,
                "use a saved model (--rhythm, --colour-model) even when it was fitted on another map or other sessions "
                "of the same resolution (a map rebuilt from the same recordings, say): a warning instead of an error");
}

/// What predict --colour learned, for --json.
nlohmann::json colourSummary(const ColourModel& c, double t) {
  return {{"voxels", c.keys.size()},         {"components", c.components},
          {"observations", c.observations},  {"rms_error", c.rms_error},
          {"bytes", c.bytes()},              {"bytes_per_voxel", c.bytesPerVoxel()},
          {"hour", hourOfDay(t)}};
}

/// The same for people.
void printColourSummary(const ColourModel& c, double t) {
  std::cout << "colour model: " << c.keys.size() << " voxel(s) from " << c.observations << " observation(s) in "
            << c.sessions << " session(s), " << c.components << " light curve(s), fit RMS " << c.rms_error
            << " per channel, " << c.bytes() << " bytes (" << c.bytesPerVoxel()
            << " per voxel); colours predicted at hour " << hourOfDay(t) << " UTC\n";
}

struct PredictCmdOptions {
  std::string map, at, output;
  LearnFlags learn;
  bool colour = false;
  ColourSettings colour_settings;
  std::string colour_in, colour_out;
  bool json = false;
};

/// predict's colour flags as the library's settings: the learning range and the saved model's
/// check as for the rhythm models.
ColourLearnSettings colourLearnSettings(const PredictCmdOptions& o) {
  const LearnSettings range = learnSettings(o.learn, o.map);
  ColourLearnSettings c;
  if (!o.colour_in.empty()) c.saved = o.colour_in;
  if (!o.colour_out.empty()) c.save = o.colour_out;
  c.from_s = range.from_s;
  c.to_s = range.to_s;
  c.range_given = range.range_given;
  c.fit = o.colour_settings;
  c.map_name = range.map_name;
  c.allow_other_map = range.allow_other_map;
  c.warn = range.warn;
  return c;
}

int runPredict(const PredictCmdOptions& o) {
  const std::string ext = fs::path(o.output).extension().string();
  if (ext != ".cmap" && ext != ".ply" && ext != ".ot" && ext != ".png") {
    throw UsageError("output '" + o.output + "' must end in .cmap, .ply, .ot or .png");
  }
  std::vector<std::filesystem::path> inputs = {o.map};
  if (!o.learn.rhythm_in.empty()) inputs.emplace_back(o.learn.rhythm_in);
  if (!o.colour_in.empty()) inputs.emplace_back(o.colour_in);
  checkOutputs({{o.output, "-o"}, {o.learn.rhythm_out, "--save-rhythm"}, {o.colour_out, "--save-colour"}}, inputs);
  const bool colour = o.colour || !o.colour_in.empty() || !o.colour_out.empty();
  const RhythmModel model = parseRhythmModel(o.learn.model);
  const double t = parseTime(o.at);
  const TemporalMap map = readTemporalMap(o.map);
  const RhythmModels models = learnRhythm(map, learnSettings(o.learn, o.map));
  SessionMap predicted = predictMap(map, models, model, t);
  std::optional<ColourModel> colours;
  if (colour) {
    colours = learnColour(map, colourLearnSettings(o));
    predicted = recolour(predicted, *colours, t);
  }
  ExportSettings settings;
  settings.metadata = {{"created_by", "chronomap predict"}, {"prediction_of", o.map}, {"time_s", t},
                       {"model", toString(model)}};
  exportSessionMap(o.output, predicted, settings);
  const SessionMapCounts c = predicted.counts();
  const nlohmann::json summary = {{"output", o.output},
                                  {"time", formatTime(t)},
                                  {"time_s", t},
                                  {"model", toString(model)},
                                  {"learned_from", {formatTime(models.from_s), formatTime(models.to_s)}},
                                  {"learning_sessions", models.sessions},
                                  {"modelled_voxels", models.voxels.size()},
                                  {"model_bytes", models.bytes()},
                                  {"occupied", c.occupied_voxels},
                                  {"free", c.free_voxels}};
  nlohmann::json out = summary;
  if (colours) out["colour"] = colourSummary(*colours, t);
  if (o.json) {
    std::cout << out.dump() << "\n";
  } else {
    if (colours) printColourSummary(*colours, t);
    std::cout << "wrote " << o.output << ": the place predicted at " << formatTime(t) << " by the " << toString(model)
              << " model (" << models.voxels.size() << " voxel(s) that changed in " << models.sessions
              << " session(s) from " << formatTime(models.from_s) << " to " << formatTime(models.to_s) << "; "
              << c.occupied_voxels << " occupied, " << c.free_voxels << " free voxels)\n";
    if (!o.learn.rhythm_out.empty()) std::cout << "wrote " << o.learn.rhythm_out << " (" << models.bytes() << " bytes)\n";
    if (!o.colour_out.empty()) std::cout << "wrote " << o.colour_out << " (the colour model)\n";
  }
  return 0;
}

struct CostmapCmdOptions {
  std::string map, at, output;
  LearnFlags learn;
  CostmapSettings settings;
  bool json = false;
};

int runCostmap(const CostmapCmdOptions& o) {
  const CostmapFiles files = costmapFiles(o.output);
  std::vector<std::filesystem::path> inputs = {o.map};
  if (!o.learn.rhythm_in.empty()) inputs.emplace_back(o.learn.rhythm_in);
  checkOutputs({{files.yaml, "-o"},
                {files.pgm, "the PGM beside -o"},
                {files.png, "the PNG beside -o"},
                {o.learn.rhythm_out, "--save-rhythm"}},
               inputs);
  const RhythmModel model = parseRhythmModel(o.learn.model);
  const double t = parseTime(o.at);
  const TemporalMap map = readTemporalMap(o.map);
  const RhythmModels models = learnRhythm(map, learnSettings(o.learn, o.map));
  const Costmap c = costmap(predictMap(map, models, model, t), o.settings, &models);
  const CostmapCounts n = writeCostmap(files, c, o.map);
  const nlohmann::json summary = {{"output", o.output}, {"pgm", files.pgm.string()}, {"png", files.png.string()},
                                  {"time", formatTime(t)}, {"time_s", t}, {"model", toString(model)},
                                  {"width", c.width}, {"height", c.height}, {"resolution_m", c.resolution_m},
                                  {"origin_m", {c.origin_m.x(), c.origin_m.y()}}, {"unknown", n.unknown},
                                  {"free", n.free}, {"costly", n.costly}, {"blocked", n.blocked}};
  if (o.json) {
    std::cout << summary.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << ", " << files.pgm.string() << " and " << files.png.string() << ": " << c.width
              << " x " << c.height << " cells of " << c.resolution_m << " m at " << formatTime(t) << " (" << n.free
              << " free, " << n.costly << " costly, " << n.blocked << " blocked, " << n.unknown << " unknown)\n";
  }
  return 0;
}

}  // namespace

Command addCostmap(CLI::App& root) {
  auto o = std::make_shared<CostmapCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "costmap",
      "Where a ground robot should drive at a time: the predicted map at --at (as chronomap predict) seen "
      "from above over a height band, each cell lethal where occupied, else costing its probability of "
      "occupancy and how often its space changes, inflated by the robot's radius. Writes ROS map_server "
      "files (OUT.yaml and OUT.pgm in mode raw: each grey level the cost, 0 free .. 100 lethal, 255 "
      "unknown) and OUT.png, a picture.");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("--at", o->at, "time: ISO-8601 or seconds since the epoch")->required();
  app->add_option("-o,--output", o->output, "the map_server YAML to write (the PGM and PNG go beside it)")->required();
  app->add_option("--z-min", o->settings.z_min_m, "lowest height the robot occupies, metres")
      ->check(numberIn(-1e4, 1e4))
      ->capture_default_str();
  app->add_option("--z-max", o->settings.z_max_m, "highest height the robot occupies, metres")
      ->check(numberIn(-1e4, 1e4))
      ->capture_default_str();
  app->add_option("--robot-radius", o->settings.robot_radius_m, "cells this close to an obstacle are blocked, metres")
      ->check(numberIn(0, 100))
      ->capture_default_str();
  app->add_option("--change-weight", o->settings.change_weight,
                  "weight of how often a place changes against its probability of occupancy (0 to 1)")
      ->check(numberIn(0, 1))
      ->capture_default_str();
  app->add_option("--lethal", o->settings.lethal_probability,
                  "probability of occupancy above which a cell is an obstacle; below it the cost rises with it "
                  "(above 0.5, space as likely free as not stays passable at a high cost)")
      ->check(numberIn(0.01, 0.99))
      ->capture_default_str();
  app->add_option("--min-occupied-sessions", o->settings.min_occupied_sessions,
                  "a voxel that changed while learning is an obstacle only where the learning sessions saw it "
                  "occupied at least this often; below, a stray hit, it stays passable at a high cost (0: off)")
      ->check(numberIn(0, 1e6))
      ->capture_default_str();
  addLearnFlags(app, o->learn);
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runCostmap(*o); }};
}

Command addPredict(CLI::App& root) {
  auto o = std::make_shared<PredictCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "predict",
      "The place at any time, past or future, predicted from how each part changed: temporal models are "
      "fitted to every voxel that changed (docs/rhythm.md), and each such voxel gets its predicted "
      "probability of occupancy at --at; the rest keep their last observed state. Output by extension: "
      ".cmap (a session map whose counters carry the probabilities), .ply, .ot or .png.");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("--at", o->at, "time to predict: ISO-8601 or seconds since the epoch")->required();
  app->add_option("-o,--output", o->output, "file to write (.cmap, .ply, .ot or .png)")->required();
  addLearnFlags(app, o->learn);
  app->add_flag("--colour,--color", o->colour,
                "also predict each surface's colour at the hour of --at: per voxel weights under a few light curves "
                "of the day shared by the map, learned from the colour changes the map keeps (it must have been "
                "created with --color-distance; docs/colour.md); the learning range is --learn-from/--learn-to");
  app->add_option("--colour-components", o->colour_settings.components,
                  "light curves of the colour model (1: one light, albedo per voxel; 2: two lights mixed per voxel)")
      ->check(numberIn(1, 3))
      ->capture_default_str();
  app->add_option("--colour-model,--color-model", o->colour_in,
                  "predict colours with a model saved by --save-colour instead of fitting one (implies --colour)");
  app->add_option("--save-colour,--save-color", o->colour_out,
                  "also save the fitted colour model (.colour) for later use (implies --colour)");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runPredict(*o); }};
}

}  // namespace chronomap::cli
