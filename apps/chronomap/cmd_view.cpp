// chronomap view MAP.cmap [--port N] [--host ADDR]: the 4D viewer in the browser (a 4D map or a session map).

#include <iostream>
#include <memory>

#include "chronomap/analysis/fitted_on.h"
#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/pipeline/maps.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/view/server.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

struct ViewOptions {
  std::string map;
  ServerSettings server;
  size_t budget = ApiSettings{}.default_max_voxels;
  std::string rhythm;
  bool allow_other_map = false;
};

int runView(ViewOptions o) {
  requireExtension(o.map, ".cmap", "4D map or session map");
  const TemporalMap map = temporalMapOfFile(o.map);
  o.server.api.default_max_voxels = o.budget;
  if (!o.rhythm.empty()) {
    o.server.api.rhythm = std::make_shared<const RhythmModels>(readRhythmModels(o.rhythm));
    const FittedOnCheck check{o.rhythm, o.map, "leave out --rhythm (the viewer then fits the models on this map)",
                              "--allow-other-map", o.allow_other_map};
    if (const std::string warning = checkFittedOn(*o.server.api.rhythm, map, check); !warning.empty()) {
      printWarning(warning);
    }
  }
  Server server(map, std::filesystem::path(o.map).filename().string(), o.server);
  const int port = server.bind();
  if (const auto warning = exposureWarning(o.server.host, port)) std::cerr << "chronomap view: " << *warning << std::endl;
  std::cout << "chronomap view: " << o.map << " (" << countOf(map.sessionCount(), "session") << ") at " << server.url()
            << "\nopen that address in a browser; Ctrl-C stops the server" << std::endl;
  server.serve();
  return 0;
}

}  // namespace

Command addView(CLI::App& root) {
  auto o = std::make_shared<ViewOptions>();
  CLI::App* app = root.add_subcommand(
      "view",
      "Serve a 4D map (or a session map, as a 4D map of one time) to a web browser: a local server for the map and the viewer's page (built into "
      "chronomap), where a time slider plays the sessions, changed objects are framed and numbered, and "
      "a click on a voxel shows its history. Listens on 127.0.0.1 unless --host names another address.");
  app->add_option("MAP", o->map, "a 4D map or a session map (.cmap)")->required();
  app->add_option("--port", o->server.port, "port to listen on (0: any free port)")
      ->check(numberIn(0, 65535))
      ->capture_default_str();
  app->add_option("--host", o->server.host,
                  "address to listen on (0.0.0.0: every interface, reachable from other machines, which prints a "
                  "warning: the viewer has no authentication); requests addressed to other names than localhost, "
                  "127.0.0.1, [::1] and this address are refused")
      ->capture_default_str();
  app->add_option("--budget", o->budget, "cells per snapshot unless the page asks for another number; more "
                                         "occupied voxels are drawn as coarser octree cubes")
      ->check(numberIn(1, static_cast<double>(ApiSettings{}.max_voxels_limit)))
      ->capture_default_str();
  app->add_option("--rhythm", o->rhythm,
                  "temporal models saved by `chronomap predict --save-rhythm`, for colouring by predicted "
                  "occupancy (without it, the models are fitted to every session when the page first asks); it must "
                  "have been fitted on MAP");
  app->add_flag("--allow-other-map", o->allow_other_map,
                "use the --rhythm models even when they were fitted on another map or other sessions of the same "
                "resolution: a warning instead of an error");
  return {app, [o] { return runView(*o); }};
}

}  // namespace chronomap::cli
