// chronomap stats FILE

#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/io/cmap.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

struct StatsOptions {
  std::string file;
  bool json = false;
};

int runStats(const StatsOptions& o) {
  const io::CmapFile file = io::readCmap(o.file);
  if (file.header.kind != io::MapKind::Session) {
    throw DataError(o.file + ": stats for " + std::string(io::toString(file.header.kind)) +
                    " maps are not supported by this build");
  }
  const SessionMap map = io::sessionMapFrom(file, o.file);
  const SessionMapCounts c = map.counts();
  const nlohmann::json meta = io::metadataOf(file);
  const size_t nodes = c.inner_nodes + c.leaves;
  const double per_leaf = c.leaves ? static_cast<double>(map.memoryBytes()) / static_cast<double>(c.leaves) : 0.0;
  const auto& h = file.header;
  if (o.json) {
    nlohmann::json j = {{"kind", io::toString(h.kind)},
                        {"format_version", h.version},
                        {"resolution_m", h.resolution_m},
                        {"sessions", 1},
                        {"times", nlohmann::json::array()},
                        {"nodes", nodes},
                        {"inner_nodes", c.inner_nodes},
                        {"leaves", c.leaves},
                        {"compressed_leaves", c.compressed_leaves},
                        {"occupied", c.occupied_voxels},
                        {"free", c.free_voxels},
                        {"bytes", map.memoryBytes()},
                        {"bytes_per_leaf", per_leaf},
                        {"file_bytes", file.file_bytes},
                        {"nodes_separate", nodes},
                        {"bounds_min", {h.bounds_min_m.x(), h.bounds_min_m.y(), h.bounds_min_m.z()}},
                        {"bounds_max", {h.bounds_max_m.x(), h.bounds_max_m.y(), h.bounds_max_m.z()}},
                        {"metadata", meta}};
    std::cout << j.dump() << "\n";
    return 0;
  }
  std::cout << o.file << ": " << io::toString(h.kind) << " map, format version " << h.version << "\n"
            << "  resolution:  " << h.resolution_m << " m\n"
            << "  bounds:      [" << h.bounds_min_m.transpose() << "] .. [" << h.bounds_max_m.transpose() << "] m\n"
            << "  voxels:      " << c.occupied_voxels << " occupied, " << c.free_voxels << " free\n"
            << "  nodes:       " << nodes << " (" << c.inner_nodes << " inner, " << c.leaves << " leaves, "
            << c.compressed_leaves << " compressed)\n"
            << "  memory:      " << humanBytes(static_cast<double>(map.memoryBytes())) << " (" << per_leaf
            << " bytes per leaf)\n"
            << "  file:        " << humanBytes(static_cast<double>(file.file_bytes)) << "\n";
  if (!meta.empty()) std::cout << "  metadata:    " << meta.dump() << "\n";
  return 0;
}

}  // namespace

Command addStats(CLI::App& root) {
  auto o = std::make_shared<StatsOptions>();
  CLI::App* app = root.add_subcommand("stats", "Print what a .cmap file holds: kind, resolution, voxels, nodes, bytes.");
  app->add_option("FILE", o->file, "a .cmap file")->required();
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runStats(*o); }};
}

}  // namespace chronomap::cli
