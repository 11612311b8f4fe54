// chronomap export MAP.cmap -o OUT.ply|.ot|.png [--at T], -o TOUR.html or -o MAP.mcap: MAP a session map or a 4D map

#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/export/foxglove.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/pipeline/maps.h"
#include "chronomap/view/tour.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

struct ExportOptions {
  std::string input;
  std::string output;
  std::string at;
  int pixels_per_voxel = 2;
  size_t max_voxels = TourSettings{}.max_voxels;
  size_t max_diff_cells = TourSettings{}.max_diff_cells;
  bool json = false;
};

int runTour(const ExportOptions& o) {
  TourSettings settings;
  settings.max_voxels = o.max_voxels;
  settings.max_diff_cells = o.max_diff_cells;
  if (!o.at.empty()) throw UsageError("--at picks the time of a .ply, .ot or .png; a tour (.html) holds every session");
  const TemporalMap map = temporalMapOfFile(o.input);
  const auto r = writeTour(o.output, map, std::filesystem::path(o.input).filename().string(), settings);
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output}, {"format", "html"}, {"elements", r.cells},
                                {"level", r.level},   {"diffs", r.diffs},  {"diff_cells", r.diff_cells}, {"bytes", r.bytes}}
                     .dump()
              << "\n";
  } else {
    std::cout << "wrote " << o.output << " (" << humanBytes(static_cast<double>(r.bytes)) << ": " << countOf(map.sessionCount(), "session")
              << ", " << countOf(r.cells, "cell") << (r.level > 0 ? " of " + std::to_string(1 << r.level) + "^3 voxels" : "")
              << ", objects of " << countOf(r.diffs, "session pair") << "); it opens in a browser with no server\n";
  }
  return 0;
}

int runFoxglove(const ExportOptions& o) {
  if (!o.at.empty()) throw UsageError("--at picks the time of a .ply, .ot or .png; a .mcap holds every session");
  const FoxgloveExport r = exportFoxglove(o.output, temporalMapOfFile(o.input));
  if (o.json) {
    nlohmann::json topics = nlohmann::json::array();
    for (const FoxgloveTopic& t : r.topics) topics.push_back({{"topic", t.topic}, {"schema", t.schema}, {"messages", t.messages}});
    std::cout << nlohmann::json{{"output", o.output}, {"format", "mcap"}, {"sessions", r.sessions}, {"points", r.points},
                                {"objects", r.objects}, {"topics", topics}, {"bytes", r.bytes}}
                     .dump()
              << "\n";
  } else {
    std::cout << "wrote " << o.output << " (" << humanBytes(static_cast<double>(r.bytes)) << ": " << countOf(r.sessions, "session")
              << ", " << countOf(r.points, "occupied voxel") << " over them, " << countOf(r.objects, "changed object")
              << "); Foxglove plays it (docs/foxglove.md)\n";
  }
  return 0;
}

void printExported(const ExportOptions& o, const std::string& ext, size_t n, std::optional<double> time_s) {
  const std::string what = ext == ".ply"  ? " occupied voxel centres"
                           : ext == ".ot" ? " OctoMap ColorOcTree leaves"
                                          : " pixels, top view";
  if (o.json) {
    nlohmann::json j{{"output", o.output}, {"format", ext.substr(1)}, {"elements", n}};
    if (time_s) j["time"] = formatTime(*time_s), j["time_s"] = *time_s;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << " (" << n << what << ")"
              << (time_s ? ": the 4D map as last observed at " + formatTime(*time_s) : "") << "\n";
  }
}

int runExport(const ExportOptions& o) {
  const std::string ext = std::filesystem::path(o.output).extension().string();
  if (ext != ".ply" && ext != ".ot" && ext != ".png" && ext != ".html" && ext != ".mcap") {
    throw UsageError("output '" + o.output + "' must end in .ply, .ot, .png, .html or .mcap");
  }
  if (o.pixels_per_voxel < 1 || o.pixels_per_voxel > 64) throw UsageError("--scale must be 1 to 64");
  refuseOverwritingInputs(o.output, {o.input});
  if (ext == ".html") return runTour(o);
  if (ext == ".mcap") return runFoxglove(o);
  ExportSettings settings;
  settings.pixels_per_voxel = o.pixels_per_voxel;
  const OneState state = stateOfMap(o.input, o.at.empty() ? std::nullopt : std::optional(parseTime(o.at)));
  printExported(o, ext, exportSessionMap(o.output, state.map, settings), state.time_s);
  return 0;
}

}  // namespace

Command addExport(CLI::App& root) {
  auto o = std::make_shared<ExportOptions>();
  CLI::App* app = root.add_subcommand(
      "export",
      "Export a session map, or a 4D map as last observed (at its last session, or --at): .ply writes the "
      "centres of occupied voxels with their mean colour; "
      ".ot writes an OctoMap ColorOcTree that octovis opens; .png draws the map seen from above "
      "(highest occupied voxel per column in its colour, floor seen free with nothing hit in a quiet "
      "floor tone, unobserved dark; axes in metres, a scale bar and a legend around it). "
      "Export a 4D map or a session map as .html: the viewer of `chronomap view` with the map inside, one "
      "file that opens in a browser from disk (every session, the objects changed between sessions). "
      "Export a 4D map as .mcap: a file Foxglove plays as a time series (per session its occupied voxels in "
      "their colour and its cost map, per pair of sessions the changed objects as labelled boxes; docs/foxglove.md).");
  app->add_option("MAP", o->input, "a session map or a 4D map (.cmap); .mcap: a 4D map")->required();
  app->add_option("-o,--output", o->output, "file to write (.ply, .ot, .png, .html or .mcap)")->required();
  app->add_option("--at", o->at,
                  ".ply, .ot, .png of a 4D map: the map as last observed at this time (ISO-8601 or epoch seconds; "
                  "default: its last session)");
  app->add_option("--scale", o->pixels_per_voxel, ".png: pixels per voxel edge")->capture_default_str();
  app->add_option("--max-voxels", o->max_voxels, ".html: most cells drawn; more voxels become coarser octree cubes")
      ->check(numberIn(1, 5e6))
      ->capture_default_str();
  app->add_option("--max-diff-cells", o->max_diff_cells,
                  ".html: most changed cells drawn per pair of sessions (the objects' list is always whole); "
                  "the file holds at most 48 MiB of map data")
      ->check(numberIn(0, 5e6))
      ->capture_default_str();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runExport(*o); }};
}

}  // namespace chronomap::cli
