// chronomap predict | costmap: the place at any time from temporal models of its 4D map, and
// where a ground robot should drive then.

#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/io/file.h"
#include "chronomap/io/map_server.h"
#include "chronomap/io/png.h"
#include "chronomap/io/rhythm_file.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/pipeline/maps.h"
#include "commands.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

/// Fits the models to the flags' learning range, or reads a saved model, and saves it when asked.
RhythmModels modelsFor(const TemporalMap& map, const std::string& rhythm_in, const std::string& rhythm_out,
                       const std::string& learn_from, const std::string& learn_to, uint32_t min_changes) {
  if (!rhythm_in.empty() && (!learn_from.empty() || !learn_to.empty() || !rhythm_out.empty())) {
    throw UsageError("--rhythm reads a fitted model: it takes no --learn-from, --learn-to or --save-rhythm");
  }
  if (!rhythm_in.empty()) return io::readRhythmModels(rhythm_in);
  const double from = learn_from.empty() ? -std::numeric_limits<double>::infinity() : parseTime(learn_from);
  const double to = learn_to.empty() ? std::numeric_limits<double>::infinity() : parseTime(learn_to);
  RhythmModels models = fitRhythm(map, from, to, min_changes);
  if (!rhythm_out.empty()) io::writeRhythmModels(rhythm_out, models);
  return models;
}

/// The learning flags shared by predict and costmap.
struct LearnFlags {
  std::string model = "combined", learn_from, learn_to, rhythm_in, rhythm_out;
  uint32_t min_changes = 1;
};

void addLearnFlags(CLI::App* app, LearnFlags& f) {
  app->add_option("--model", f.model, "latest, mean, markov, periodic, hourly or combined")->capture_default_str();
  app->add_option("--learn-from", f.learn_from, "learn from sessions at or after this time (default: the first)");
  app->add_option("--learn-to", f.learn_to, "learn from sessions up to this time (default: the last)");
  app->add_option("--min-changes", f.min_changes, "model voxels that changed at least this often while learning")
      ->check(numberIn(1, 1e6))
      ->capture_default_str();
  app->add_option("--rhythm", f.rhythm_in, "use a model saved by --save-rhythm instead of fitting one");
  app->add_option("--save-rhythm", f.rhythm_out, "also save the fitted model (.rhythm) for later use");
}

struct PredictCmdOptions {
  std::string map, at, output;
  LearnFlags learn;
  bool json = false;
};

int runPredict(const PredictCmdOptions& o) {
  const std::string ext = fs::path(o.output).extension().string();
  if (ext != ".cmap" && ext != ".ply" && ext != ".ot" && ext != ".png") {
    throw UsageError("output '" + o.output + "' must end in .cmap, .ply, .ot or .png");
  }
  std::vector<std::filesystem::path> inputs = {o.map};
  if (!o.learn.rhythm_in.empty()) inputs.emplace_back(o.learn.rhythm_in);
  io::refuseOverwritingInputs(o.output, inputs);
  if (!o.learn.rhythm_out.empty()) io::refuseOverwritingInputs(o.learn.rhythm_out, inputs);
  const RhythmModel model = parseRhythmModel(o.learn.model);
  const double t = parseTime(o.at);
  const TemporalMap map = io::readTemporalMap(o.map);
  const RhythmModels models =
      modelsFor(map, o.learn.rhythm_in, o.learn.rhythm_out, o.learn.learn_from, o.learn.learn_to, o.learn.min_changes);
  const SessionMap predicted = predictMap(map, models, model, t);
  pipeline::ExportSettings settings;
  settings.metadata = {{"created_by", "chronomap predict"}, {"prediction_of", o.map}, {"time_s", t},
                       {"model", toString(model)}};
  pipeline::exportSessionMap(o.output, predicted, settings);
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
  if (o.json) {
    std::cout << summary.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << ": the place predicted at " << formatTime(t) << " by the " << toString(model)
              << " model (" << models.voxels.size() << " voxel(s) that changed in " << models.sessions
              << " session(s) from " << formatTime(models.from_s) << " to " << formatTime(models.to_s) << "; "
              << c.occupied_voxels << " occupied, " << c.free_voxels << " free voxels)\n";
    if (!o.learn.rhythm_out.empty()) std::cout << "wrote " << o.learn.rhythm_out << " (" << models.bytes() << " bytes)\n";
  }
  return 0;
}

struct CostmapCmdOptions {
  std::string map, at, output;
  LearnFlags learn;
  CostmapSettings settings;
  bool json = false;
};

/// The costmap as a picture: unknown grey, free white to cost red, inscribed dark red, lethal black.
ImageRgb costImage(const Costmap& c) {
  ImageRgb img{static_cast<uint32_t>(c.width), static_cast<uint32_t>(c.height), {}};
  img.pixels.reserve(c.cost.size());
  for (int j = c.height - 1; j >= 0; --j) {
    for (int i = 0; i < c.width; ++i) {
      const int8_t v = c.at(i, j);
      if (v < 0) {
        img.pixels.push_back({128, 128, 128});
      } else if (v == Costmap::kLethal) {
        img.pixels.push_back({0, 0, 0});
      } else if (v == Costmap::kInscribed) {
        img.pixels.push_back({110, 20, 20});
      } else {
        const auto fade = static_cast<uint8_t>(255 - v * 2);
        img.pixels.push_back({255, fade, fade});
      }
    }
  }
  return img;
}

int runCostmap(const CostmapCmdOptions& o) {
  if (fs::path(o.output).extension() != ".yaml") throw UsageError("output '" + o.output + "' must end in .yaml");
  fs::path pgm = o.output, png = o.output;
  pgm.replace_extension(".pgm");
  png.replace_extension(".png");
  std::vector<std::filesystem::path> inputs = {o.map};
  if (!o.learn.rhythm_in.empty()) inputs.emplace_back(o.learn.rhythm_in);
  for (const fs::path& out : {fs::path(o.output), pgm, png}) io::refuseOverwritingInputs(out, inputs);
  const RhythmModel model = parseRhythmModel(o.learn.model);
  const double t = parseTime(o.at);
  const TemporalMap map = io::readTemporalMap(o.map);
  const RhythmModels models =
      modelsFor(map, o.learn.rhythm_in, o.learn.rhythm_out, o.learn.learn_from, o.learn.learn_to, o.learn.min_changes);
  const Costmap c = costmap(predictMap(map, models, model, t), o.settings, &models);
  if (c.width == 0) throw DataError(o.map + ": nothing is known between --z-min and --z-max");
  io::writeMapServer(o.output, c);
  io::writePng(png, costImage(c));
  size_t counts[4] = {0, 0, 0, 0};  // unknown, free (0), costly, blocked (inscribed or lethal)
  for (int8_t v : c.cost) ++counts[v < 0 ? 0 : v == 0 ? 1 : v < Costmap::kInscribed ? 2 : 3];
  const nlohmann::json summary = {{"output", o.output}, {"pgm", pgm.string()}, {"png", png.string()},
                                  {"time", formatTime(t)}, {"time_s", t}, {"model", toString(model)},
                                  {"width", c.width}, {"height", c.height}, {"resolution_m", c.resolution_m},
                                  {"origin_m", {c.origin_m.x(), c.origin_m.y()}}, {"unknown", counts[0]},
                                  {"free", counts[1]}, {"costly", counts[2]}, {"blocked", counts[3]}};
  if (o.json) {
    std::cout << summary.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << ", " << pgm.string() << " and " << png.string() << ": " << c.width << " x "
              << c.height << " cells of " << c.resolution_m << " m at " << formatTime(t) << " (" << counts[1]
              << " free, " << counts[2] << " costly, " << counts[3] << " blocked, " << counts[0] << " unknown)\n";
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
      "files (OUT.yaml and OUT.pgm: -1/205 unknown, 0..100 cost) and OUT.png.");
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
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runPredict(*o); }};
}

}  // namespace chronomap::cli
