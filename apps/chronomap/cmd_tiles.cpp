// chronomap tile | untile: a 4D map cut into a folder of tiles, and joined back.

#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/pipeline/tiles.h"
#include "commands.h"

namespace chronomap::cli {

TileCacheSettings tileCacheSettings(const std::optional<double>& gib) {
  TileCacheSettings s;
  if (gib) s.memory_limit_bytes = gibToBytes(*gib);
  return s;
}

namespace {

struct TileCmdOptions {
  std::string map;
  std::string output;
  std::optional<double> tile_size_m;
  uint32_t tile_windows = kDefaultWindowSessions;
  bool windowed_tiles = false;
  bool json = false;
};

int runTile(const TileCmdOptions& o) {
  checkOutputs({{o.output, "-o", true}}, {o.map});
  TileSettings s;
  s.map = o.map;
  s.folder = o.output;
  s.tile_size_m = o.tile_size_m;
  s.window_sessions = o.tile_windows;
  s.windowed_tiles = o.windowed_tiles;
  const TileResult r = tileMap(s);
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output},         {"tile_size_m", r.tile_size_m},
                                {"tile_level", r.tile_level}, {"tiles", r.tiles},
                                {"top_lists", r.top_lists},   {"index_bytes", r.index_bytes},
                                {"tile_bytes", r.tile_bytes}, {"map_bytes", r.map_bytes},
                                {"windows", r.windows}}
                     .dump()
              << "\n";
  } else {
    std::cout << "wrote " << o.output << ": " << r.tiles << " tile(s) of " << r.tile_size_m << " m ("
              << (1 << r.tile_level) << " voxels), " << r.tile_bytes << " bytes";
    if (r.windows > 0) std::cout << " with " << r.windows << " history window(s)";
    std::cout << ", index " << r.index_bytes << " bytes (the map: " << r.map_bytes << " bytes)\n";
  }
  return 0;
}

struct UntileCmdOptions {
  std::string folder;
  std::string output;
  bool json = false;
};

int runUntile(const UntileCmdOptions& o) {
  requireExtension(o.output, ".cmap", "output");
  const size_t sessions = untileMap(o.folder, o.output);
  if (o.json) {
    std::cout << nlohmann::json{{"output", o.output}, {"sessions", sessions}}.dump() << "\n";
  } else {
    std::cout << "wrote " << o.output << ": the 4D map of " << sessions << " session(s) joined from " << o.folder
              << "\n";
  }
  return 0;
}

}  // namespace

Command addTile(CLI::App& root) {
  auto o = std::make_shared<TileCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "tile",
      "Cut a 4D map into a folder of tiles (a grid of cubes, each an independent 4D map, and an index): "
      "snapshot, history and diff then read only the tiles they need, under --memory-limit (docs/scale.md).");
  app->add_option("MAP", o->map, "the 4D map (.cmap)")->required();
  app->add_option("-o,--output", o->output, "the folder to write (replaced as a whole)")->required();
  app->add_option("--tile-size", o->tile_size_m,
                  "tile edge in metres: a power-of-two number of voxels (default 128 voxels, 6.4 m at 5 cm)")
      ->check(numberIn(1e-6, 1e6));
  app->add_option("--tile-windows", o->tile_windows,
                  "sessions per window file of a tile's history (0: none): a snapshot of an older time reads the "
                  "window that holds it, not the whole history (docs/scale.md)")
      ->default_val(kDefaultWindowSessions)
      ->check(CLI::Range(0, 65535));
  app->add_flag("--windowed-tiles", o->windowed_tiles,
                "keep each tile as windows of --tile-windows sessions (the last one open), the layout in which "
                "`build --tiles` reads and writes a tile's last window only (docs/scale.md)");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runTile(*o); }};
}

Command addUntile(CLI::App& root) {
  auto o = std::make_shared<UntileCmdOptions>();
  CLI::App* app = root.add_subcommand("untile", "Join a tiled map folder back into one 4D map (.cmap).");
  app->add_option("FOLDER", o->folder, "the tiled map folder (chronomap tile)")->required();
  app->add_option("-o,--output", o->output, "the 4D map to write (.cmap)")->required();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runUntile(*o); }};
}

}  // namespace chronomap::cli
