// chronomap predict: the place's state at any time from temporal models of its 4D map.

#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/io/file.h"
#include "chronomap/io/rhythm_file.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/pipeline/maps.h"
#include "commands.h"

namespace chronomap::cli {

namespace fs = std::filesystem;

namespace {

struct PredictCmdOptions {
  std::string map, at, output, model = "combined", learn_from, learn_to, rhythm_in, rhythm_out;
  uint32_t min_changes = 1;
  bool json = false;
};

int runPredict(const PredictCmdOptions& o) {
  const std::string ext = fs::path(o.output).extension().string();
  if (ext != ".cmap" && ext != ".ply" && ext != ".ot" && ext != ".png") {
    throw UsageError("output '" + o.output + "' must end in .cmap, .ply, .ot or .png");
  }
  if (!o.rhythm_in.empty() && (!o.learn_from.empty() || !o.learn_to.empty() || !o.rhythm_out.empty())) {
    throw UsageError("--rhythm reads a fitted model: it takes no --learn-from, --learn-to or --save-rhythm");
  }
  std::vector<std::filesystem::path> inputs = {o.map};
  if (!o.rhythm_in.empty()) inputs.emplace_back(o.rhythm_in);
  io::refuseOverwritingInputs(o.output, inputs);
  if (!o.rhythm_out.empty()) io::refuseOverwritingInputs(o.rhythm_out, inputs);
  const RhythmModel model = parseRhythmModel(o.model);
  const double t = parseTime(o.at);
  const TemporalMap map = io::readTemporalMap(o.map);
  RhythmModels models;
  if (!o.rhythm_in.empty()) {
    models = io::readRhythmModels(o.rhythm_in);
  } else {
    const double from = o.learn_from.empty() ? -std::numeric_limits<double>::infinity() : parseTime(o.learn_from);
    const double to = o.learn_to.empty() ? std::numeric_limits<double>::infinity() : parseTime(o.learn_to);
    models = fitRhythm(map, from, to, o.min_changes);
    if (!o.rhythm_out.empty()) io::writeRhythmModels(o.rhythm_out, models);
  }
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
    if (!o.rhythm_out.empty()) std::cout << "wrote " << o.rhythm_out << " (" << models.bytes() << " bytes)\n";
  }
  return 0;
}

}  // namespace

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
  app->add_option("--model", o->model, "latest, mean, markov, periodic, hourly or combined")->capture_default_str();
  app->add_option("--learn-from", o->learn_from, "learn from sessions at or after this time (default: the first)");
  app->add_option("--learn-to", o->learn_to, "learn from sessions up to this time (default: the last)");
  app->add_option("--min-changes", o->min_changes, "model voxels that changed at least this often while learning")
      ->check(numberIn(1, 1e6))
      ->capture_default_str();
  app->add_option("--rhythm", o->rhythm_in, "use a model saved by --save-rhythm instead of fitting one");
  app->add_option("--save-rhythm", o->rhythm_out, "also save the fitted model (.rhythm) for later predictions");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runPredict(*o); }};
}

}  // namespace chronomap::cli
