// chronomap integrate DATASET -o SESSION.cmap

#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/dataset.h"
#include "commands.h"
#include "progress.h"

namespace chronomap::cli {

namespace {

struct IntegrateOptions {
  std::string dataset;
  std::string output;
  IntegrateSettings settings;
  bool json = false;
};

}  // namespace

io::DatasetOptions datasetOptions(const IntegrateSettings& o) {
  io::DatasetOptions dopt;
  dopt.format = io::parseDatasetFormat(o.format);
  if (o.depth_scale != 0.0) dopt.depth_scale = o.depth_scale;
  if (!o.intrinsics.empty()) dopt.intrinsics = io::parseIntrinsics(o.intrinsics);
  if (!o.pose.empty()) dopt.pose = parsePose(o.pose);
  if (!o.trajectory.empty()) dopt.trajectory = o.trajectory;
  return dopt;
}

IntegratorSettings integratorSettings(const IntegrateSettings& o) {
  IntegratorSettings settings;
  settings.max_range_m = o.max_range_m;
  settings.fast = o.fast;
  settings.threads = o.threads;
  settings.compress_free = !o.no_compress;
  settings.hit_positions = !o.no_positions;
  return settings;
}

IntegratedSession integrateDataset(const std::string& path, const IntegrateSettings& o, const std::string& label,
                                   const PoseCorrection& correction) {
  const io::DatasetOptions dopt = datasetOptions(o);
  const IntegratorSettings settings = integratorSettings(o);

  auto dataset = io::openDataset(path, dopt);
  IntegratedSession out{SessionMap(o.resolution_m), {}, dataset->recordedAt(), io::toString(dataset->format()),
                        dataset->framesDropped(), {}};
  ProgressBar bar(label, dataset->size());
  // Without a correction the dataset is read directly (frames already in memory are not copied).
  for (size_t i = 0; i < dataset->size(); ++i) out.sensor_positions.push_back(dataset->poseOf(i).translation());
  const bool corrected = !correction.isIdentity();
  const CorrectedFrames frames(*dataset, correction);
  out.stats = integrate(corrected ? static_cast<const FrameSource&>(frames) : *dataset, out.map, settings,
                        [&](size_t done, size_t) { bar.update(done); });
  bar.finish();
  if (out.stats.points == 0) {
    throw DataError(path + ": no valid points within " + std::to_string(o.max_range_m) + " m in " +
                    std::to_string(out.stats.frames) + " frame(s) (" + std::to_string(out.stats.pointsSkipped()) +
                    " skipped); nothing to write");
  }
  return out;
}

std::vector<PoseCorrection> registerDatasets(std::vector<SessionMap>& maps, const std::vector<std::string>& paths,
                                             std::span<const std::vector<Eigen::Vector3d>> sensor_positions,
                                             const IntegrateSettings& o, int rounds, const RegisterSettings& settings) {
  // Sessions are integrated again in parallel: no progress bars (they would overwrite each other).
  return registerSessions(
      maps, [&](size_t k, const PoseCorrection& c) { return integrateDataset(paths[k], o, "", c).map; }, rounds,
      settings, nullptr, sensor_positions,
      [&](size_t k) -> std::unique_ptr<FrameSource> { return io::openDataset(paths[k], datasetOptions(o)); });
}

void addIntegrateOptions(CLI::App* app, IntegrateSettings& o) {
  app->add_option("--resolution", o.resolution_m, "edge of a unit voxel, metres")->capture_default_str();
  app->add_option("--max-range", o.max_range_m, "points farther from the sensor are discarded, metres")
      ->capture_default_str();
  app->add_option("--format", o.format, "auto, tum, 3dmatch or clouds")->capture_default_str();
  app->add_flag("--fast", o.fast,
                "bundle the points of a frame that end in the same voxel into one weighted ray "
                "(much faster; see docs/integration.md for how far the counters may differ)");
  app->add_option("--threads", o.threads, "worker threads, 0 = all cores (the map does not depend on it)")
      ->capture_default_str();
  app->add_flag("--no-compress", o.no_compress, "keep every free unit voxel instead of merging free subtrees");
  app->add_flag("--no-positions", o.no_positions,
                "do not record where in each voxel the rays ended (fast mode about 7% faster; the diff's shift test "
                "then sees surfaces only to the voxel; docs/changes.md)");
  app->add_option("--depth-scale", o.depth_scale, "depth image units per metre (TUM 5000, 3DMatch 1000)");
  app->add_option("--intrinsics", o.intrinsics, "camera intrinsics fx,fy,cx,cy in pixels");
  app->add_option("--pose", o.pose, "pose of a single cloud: tx,ty,tz,qx,qy,qz,qw (sensor to map)");
  app->add_option("--trajectory", o.trajectory, "TUM: pose file to use instead of trajectory.txt/groundtruth.txt");
}

namespace {

int runIntegrate(const IntegrateOptions& o) {
  if (std::filesystem::path(o.output).extension() != ".cmap") {
    throw UsageError("output '" + o.output + "' must end in .cmap");
  }
  const IntegratedSession session = integrateDataset(o.dataset, o.settings, "integrating");
  const SessionMap& map = session.map;
  const IntegrationStats& stats = session.stats;
  const IntegratorSettings settings = integratorSettings(o.settings);
  nlohmann::json meta = {{"created_by", "chronomap integrate"},
                         {"dataset", std::filesystem::absolute(o.dataset).lexically_normal().string()},
                         {"format", session.format},
                         {"frames", stats.frames},
                         {"points", stats.points},
                         {"max_range_m", settings.max_range_m},
                         {"fast", settings.fast},
                         {"compressed", settings.compress_free},
                         {"hit_positions", settings.hit_positions}};
  if (session.recorded_at) meta["recorded_at"] = *session.recorded_at;
  io::writeSessionMap(o.output, map, meta);
  const SessionMapCounts counts = map.counts();
  const auto file_bytes = std::filesystem::file_size(o.output);
  if (o.json) {
    nlohmann::json j = {{"frames", stats.frames},
                        {"frames_dropped", session.frames_dropped},
                        {"points", stats.points},
                        {"points_skipped", stats.pointsSkipped()},
                        {"points_invalid", stats.points_invalid},
                        {"points_out_of_range", stats.points_out_of_range},
                        {"points_outside_map", stats.points_outside_map},
                        {"rays", stats.rays},
                        {"occupied", counts.occupied_voxels},
                        {"free", counts.free_voxels},
                        {"nodes", counts.inner_nodes + counts.leaves},
                        {"bytes", map.memoryBytes()},
                        {"file_bytes", file_bytes},
                        {"resolution_m", map.resolution_m()},
                        {"seconds", stats.seconds},
                        {"output", o.output}};
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "integrated " << stats.frames << " frame(s) of " << o.dataset << " (" << session.format << ")";
    if (session.frames_dropped) std::cout << ", " << session.frames_dropped << " frame(s) without pose or colour dropped";
    std::cout << "\n  points:  " << stats.points << " cast, " << stats.pointsSkipped() << " skipped ("
              << stats.points_invalid << " invalid, " << stats.points_out_of_range << " beyond "
              << settings.max_range_m << " m, " << stats.points_outside_map << " outside the map)\n"
              << "  voxels:  " << counts.occupied_voxels << " occupied, " << counts.free_voxels << " free at "
              << map.resolution_m() << " m\n"
              << "  nodes:   " << counts.inner_nodes + counts.leaves << " (" << counts.leaves << " leaves, "
              << counts.compressed_leaves << " compressed), " << humanBytes(static_cast<double>(map.memoryBytes()))
              << " in memory\n"
              << "  time:    " << stats.seconds << " s ("
              << (stats.seconds > 0 ? static_cast<double>(stats.points) / stats.seconds / 1e6 : 0.0)
              << " M points/s)\n"
              << "wrote " << o.output << " (" << humanBytes(static_cast<double>(file_bytes)) << ")\n";
  }
  return 0;
}

}  // namespace

Command addIntegrate(CLI::App& root) {
  auto o = std::make_shared<IntegrateOptions>();
  CLI::App* app = root.add_subcommand(
      "integrate",
      "Integrate one recording into a session map (.cmap).\n"
      "DATASET is a TUM RGB-D folder (depth.txt, rgb.txt, trajectory.txt or groundtruth.txt), a "
      "3DMatch/7-Scenes folder (frame-*.depth.png, frame-*.pose.txt, camera-intrinsics.txt), a single "
      "PCD/PLY/XYZ cloud (seen from the origin unless --pose), or a text list of clouds with poses "
      "('cloud.pcd tx ty tz qx qy qz qw' per line).");
  app->add_option("DATASET", o->dataset, "dataset folder or file")->required();
  app->add_option("-o,--output", o->output, "session map to write (.cmap)")->required();
  addIntegrateOptions(app, o->settings);
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runIntegrate(*o); }};
}

std::string humanBytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 4) {
    bytes /= 1024.0;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof(buf), u == 0 ? "%.0f %s" : "%.1f %s", bytes, units[u]);
  return buf;
}

}  // namespace chronomap::cli
