// chronomap export SESSION.cmap -o OUT.ply|.ot

#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/export.h"
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
  const SessionMap map = io::readSessionMap(o.input);
  size_t n = 0;
  std::string what;
  if (ext == ".ply") {
    n = io::exportOccupiedPly(o.output, map);
    what = " occupied voxel centres";
  } else if (ext == ".ot") {
    n = io::exportOctomap(o.output, map);
    what = " OctoMap ColorOcTree leaves";
  } else {
    io::TopViewSettings settings;
    settings.pixels_per_voxel = o.pixels_per_voxel;
    const io::ImageRgb img = io::renderTopView(map, settings);
    io::writePng(o.output, img);
    n = size_t{img.width} * img.height;
    what = " pixels, top view";
  }
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
