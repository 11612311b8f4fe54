// chronomap export SESSION.cmap -o OUT.ply|.ot

#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/file.h"
#include "chronomap/pipeline/maps.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

struct ExportOptions {
  std::string input;
  std::string output;
  int pixels_per_voxel = 2;
  bool json = false;
};

int runExport(const ExportOptions& o) {
  const std::string ext = std::filesystem::path(o.output).extension().string();
  if (ext != ".ply" && ext != ".ot" && ext != ".png") {
    throw UsageError("output '" + o.output + "' must end in .ply, .ot or .png");
  }
  if (o.pixels_per_voxel < 1 || o.pixels_per_voxel > 64) throw UsageError("--scale must be 1 to 64");
  io::refuseOverwritingInputs(o.output, {o.input});
  pipeline::ExportSettings settings;
  settings.pixels_per_voxel = o.pixels_per_voxel;
  const size_t n = pipeline::exportSessionMap(o.output, io::readSessionMap(o.input), settings);
  const std::string what = ext == ".ply"  ? " occupied voxel centres"
                           : ext == ".ot" ? " OctoMap ColorOcTree leaves"
                                          : " pixels, top view";
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output}, {"format", ext.substr(1)}, {"elements", n}}.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << " (" << n << what << ")\n";
  }
  return 0;
}

}  // namespace

Command addExport(CLI::App& root) {
  auto o = std::make_shared<ExportOptions>();
  CLI::App* app = root.add_subcommand(
      "export",
      "Export a session map: .ply writes the centres of occupied voxels with their mean colour; "
      ".ot writes an OctoMap ColorOcTree that octovis opens; .png draws the map seen from above "
      "(highest occupied voxel per column in its colour, free space light, unobserved dark).");
  app->add_option("SESSION", o->input, "a session map (.cmap)")->required();
  app->add_option("-o,--output", o->output, "file to write (.ply, .ot or .png)")->required();
  app->add_option("--scale", o->pixels_per_voxel, ".png: pixels per voxel edge")->capture_default_str();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runExport(*o); }};
}

}  // namespace chronomap::cli
