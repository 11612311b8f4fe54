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
  bool json = false;
};

int runExport(const ExportOptions& o) {
  const std::string ext = std::filesystem::path(o.output).extension().string();
  if (ext != ".ply" && ext != ".ot") throw UsageError("output '" + o.output + "' must end in .ply or .ot");
  const SessionMap map = io::readSessionMap(o.input);
  const size_t n = ext == ".ply" ? io::exportOccupiedPly(o.output, map) : io::exportOctomap(o.output, map);
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output}, {"format", ext.substr(1)}, {"elements", n}}.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << " ("
              << (ext == ".ply" ? std::to_string(n) + " occupied voxel centres"
                                : std::to_string(n) + " OctoMap ColorOcTree leaves")
              << ")\n";
  }
  return 0;
}

}  // namespace

Command addExport(CLI::App& root) {
  auto o = std::make_shared<ExportOptions>();
  CLI::App* app = root.add_subcommand(
      "export",
      "Export a session map: .ply writes the centres of occupied voxels with their mean colour; "
      ".ot writes an OctoMap ColorOcTree that octovis opens.");
  app->add_option("SESSION", o->input, "a session map (.cmap)")->required();
  app->add_option("-o,--output", o->output, "file to write (.ply or .ot)")->required();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runExport(*o); }};
}

}  // namespace chronomap::cli
