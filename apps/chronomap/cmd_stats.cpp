// chronomap stats FILE

#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/png.h"
#include "chronomap/render/plot.h"
#include "chronomap/store/temporal_file.h"
#include "commands.h"

namespace chronomap::cli {

namespace {

struct StatsOptions {
  std::string file;
  std::string plot;
  bool json = false;
};

/// What stats prints of a 4D map.
struct TemporalStats {
  const TemporalMap& map;
  const CmapFile& file;
  TemporalFileLayout layout;
  TemporalCounts counts;
  double nodes_separate = 0.0;
};

void printTemporalJson(const StatsOptions& o, const TemporalStats& s) {
  nlohmann::json times = nlohmann::json::array(), sessions = nlohmann::json::array();
  for (const auto& session : s.map.sessions()) {
    times.push_back(formatTime(session.time_s));
    sessions.push_back({{"time", formatTime(session.time_s)},
                        {"time_s", session.time_s},
                        {"name", session.name},
                        {"nodes_added", session.nodes_added},
                        {"nodes_separate", session.nodes_separate},
                        {"observed_voxels", session.coverage.voxelCount()}});
  }
  const auto& h = s.file.header;
  const TemporalCounts& c = s.counts;
  nlohmann::json j = {{"kind", toString(h.kind)},
                      {"format_version", h.version},
                      {"resolution_m", h.resolution_m},
                      {"sessions", s.map.sessionCount()},
                      {"times", times},
                      {"nodes", c.nodes()},
                      {"inner_nodes", c.inner_nodes},
                      {"entries", c.entries},
                      {"slots", c.slots},
                      {"bytes", s.map.memoryBytes()},
                      {"file_bytes", s.file.file_bytes},
                      {"appended_sessions", s.layout.appended_sessions},
                      {"appended_bytes", s.layout.appended_bytes},
                      {"incomplete_append_bytes", s.layout.incomplete_tail_bytes},
                      {"nodes_separate", static_cast<uint64_t>(s.nodes_separate)},
                      {"per_session", sessions},
                      {"bounds_min", {h.bounds_min_m.x(), h.bounds_min_m.y(), h.bounds_min_m.z()}},
                      {"bounds_max", {h.bounds_max_m.x(), h.bounds_max_m.y(), h.bounds_max_m.z()}}};
  if (!o.plot.empty()) j["plot"] = o.plot;
  j.update(upKeysOf(userMetadataOf(s.file)));
  std::cout << j.dump() << "\n";
}

/// The up line of a map whose recordings were turned (--up): which axis, how chosen, the rotation.
void printUp(const nlohmann::json& meta) {
  if (!meta.is_object() || !meta.contains("up")) return;
  std::cout << "  up:          " << meta["up"].get<std::string>() << " of the recordings";
  if (meta.contains("up_from")) std::cout << " (" << meta["up_from"].get<std::string>() << ")";
  std::cout << ", turned to +z";
  if (meta.contains("world_rotation")) std::cout << " by R = " << meta["world_rotation"].dump();
  std::cout << " (a point p of the recordings is R p here)\n";
}

void printTemporalText(const StatsOptions& o, const TemporalStats& s) {
  const auto& h = s.file.header;
  const TemporalMap& map = s.map;
  const TemporalCounts& c = s.counts;
  std::cout << o.file << ": 4D map, format version " << h.version << "\n"
            << "  resolution:  " << h.resolution_m << " m\n"
            << "  bounds:      [" << h.bounds_min_m.transpose() << "] .. [" << h.bounds_max_m.transpose() << "] m\n";
  printUp(userMetadataOf(s.file));
  std::cout << "  sessions:    " << map.sessionCount();
  if (map.sessionCount()) {
    std::cout << " (" << formatTime(map.sessions().front().time_s) << " .. " << formatTime(map.sessions().back().time_s)
              << ")";
  }
  std::cout << "\n  nodes:       " << c.nodes() << " (" << c.inner_nodes << " inner, " << c.entries
            << " history entries in " << c.slots << " slots)\n"
            << "  separately:  " << static_cast<uint64_t>(s.nodes_separate) << " nodes for the session maps on their own";
  if (s.nodes_separate > 0) {
    std::cout << " (the 4D map holds " << 100.0 * static_cast<double>(c.nodes()) / s.nodes_separate << "%)";
  }
  std::cout << "\n  memory:      " << humanBytes(static_cast<double>(map.memoryBytes())) << "\n"
            << "  file:        " << humanBytes(static_cast<double>(s.file.file_bytes));
  if (s.layout.appended_sessions) {
    std::cout << " (" << s.layout.appended_sessions << " session(s) appended by add: "
              << humanBytes(static_cast<double>(s.layout.appended_bytes))
              << ", folded in when it next writes the map whole)";
  }
  std::cout << "\n";
  if (s.layout.incomplete_tail_bytes) {
    std::cout << "  note:        " << s.layout.incomplete_tail_bytes
              << " bytes at the end are an interrupted add and not part of the map; the next add removes them\n";
  }
  if (map.sessionCount()) {
    std::cout << "  per session: time, nodes added, nodes on its own\n";
    for (const auto& session : map.sessions()) {
      std::cout << "    " << formatTime(session.time_s) << "  " << session.nodes_added << "  "
                << session.nodes_separate << "\n";
    }
  }
  if (!o.plot.empty()) std::cout << "wrote " << o.plot << "\n";
}

int runTemporalStats(const StatsOptions& o, const CmapFile& file) {
  const TemporalMap map = temporalMapFrom(file, o.file);
  TemporalStats s{map, file, layoutOf(file), map.counts(), 0.0};
  for (const auto& session : map.sessions()) s.nodes_separate += static_cast<double>(session.nodes_separate);
  if (!o.plot.empty()) {
    if (std::filesystem::path(o.plot).extension() != ".png") throw UsageError("--plot '" + o.plot + "' must end in .png");
    refuseOverwritingInputs(o.plot, {o.file});
    if (map.sessionCount() == 0) throw DataError(o.file + ": no sessions to plot");
    writePng(o.plot, renderStoragePlot(map));
  }
  if (o.json) {
    printTemporalJson(o, s);
  } else {
    printTemporalText(o, s);
  }
  return 0;
}

int runDiffStats(const StatsOptions& o, const CmapFile& file) {
  if (!o.plot.empty()) throw UsageError("--plot draws the storage of a 4D map; " + o.file + " is a diff");
  const DiffMap d = diffMapFrom(file, o.file);
  const uint64_t appeared = d.voxelCount(ChangeKind::Appeared), vanished = d.voxelCount(ChangeKind::Vanished);
  const auto& h = file.header;
  if (o.json) {
    std::cout << nlohmann::json{{"kind", toString(h.kind)},
                                {"format_version", h.version},
                                {"resolution_m", h.resolution_m},
                                {"mode", toString(d.settings().mode)},
                                {"alpha", d.settings().effectiveAlpha()},
                                {"cells", d.cells().size()},
                                {"changed_voxels", appeared + vanished},
                                {"appeared", appeared},
                                {"vanished", vanished},
                                {"file_bytes", file.file_bytes},
                                {"bounds_min", {h.bounds_min_m.x(), h.bounds_min_m.y(), h.bounds_min_m.z()}},
                                {"bounds_max", {h.bounds_max_m.x(), h.bounds_max_m.y(), h.bounds_max_m.z()}}}
                     .dump()
              << "\n";
    return 0;
  }
  std::cout << o.file << ": diff, format version " << h.version << "\n"
            << "  mode:        " << toString(d.settings().mode) << " (alpha " << d.settings().effectiveAlpha() << ")\n"
            << "  resolution:  " << h.resolution_m << " m\n"
            << "  changed:     " << appeared + vanished << " voxels (" << appeared << " appeared, " << vanished
            << " vanished) in " << d.cells().size() << " cells\n"
            << "  file:        " << humanBytes(static_cast<double>(file.file_bytes)) << "\n";
  return 0;
}

int runStats(const StatsOptions& o) {
  const CmapFile file = readCmap(o.file);
  if (file.header.kind == MapKind::Temporal) return runTemporalStats(o, file);
  if (file.header.kind == MapKind::Diff) return runDiffStats(o, file);
  if (file.header.kind != MapKind::Session) {
    throw DataError(o.file + ": stats for " + std::string(kindName(file.header.kind)) +
                    " maps are not supported by this build");
  }
  if (!o.plot.empty()) throw UsageError("--plot draws the storage of a 4D map; " + o.file + " is a session map");
  const SessionMap map = sessionMapFrom(file, o.file);
  const SessionMapCounts c = map.counts();
  const nlohmann::json meta = metadataOf(file);
  const size_t nodes = c.inner_nodes + c.leaves;
  const double per_leaf = c.leaves ? static_cast<double>(map.memoryBytes()) / static_cast<double>(c.leaves) : 0.0;
  const auto& h = file.header;
  if (o.json) {
    nlohmann::json j = {{"kind", toString(h.kind)},
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
  std::cout << o.file << ": " << kindName(h.kind) << " map, format version " << h.version << "\n"
            << "  resolution:  " << h.resolution_m << " m\n"
            << "  bounds:      [" << h.bounds_min_m.transpose() << "] .. [" << h.bounds_max_m.transpose() << "] m\n"
            << "  voxels:      " << c.occupied_voxels << " occupied, " << c.free_voxels << " free\n"
            << "  nodes:       " << nodes << " (" << c.inner_nodes << " inner, " << c.leaves << " leaves, "
            << c.compressed_leaves << " compressed)\n"
            << "  memory:      " << humanBytes(static_cast<double>(map.memoryBytes())) << " (" << per_leaf
            << " bytes per leaf)\n"
            << "  file:        " << humanBytes(static_cast<double>(file.file_bytes)) << "\n";
  printUp(meta);
  if (!meta.empty()) std::cout << "  metadata:    " << meta.dump() << "\n";
  return 0;
}

}  // namespace

Command addStats(CLI::App& root) {
  auto o = std::make_shared<StatsOptions>();
  CLI::App* app = root.add_subcommand("stats", "Print what a .cmap file holds: kind, resolution, voxels, nodes, bytes; for a 4D map also the "
      "sessions and the nodes each added.");
  app->add_option("FILE", o->file, "a .cmap file")->required();
  app->add_option("--plot", o->plot,
                  "4D maps: draw nodes against sessions, stored separately and as the 4D map, into this PNG");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runStats(*o); }};
}

}  // namespace chronomap::cli
