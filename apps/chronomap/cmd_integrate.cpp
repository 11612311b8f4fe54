// chronomap integrate DATASET -o SESSION.cmap

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"
#include "chronomap/core/pose.h"
#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/core/file.h"
#include "chronomap/pipeline/session.h"
#include "commands.h"
#include "progress.h"

namespace chronomap::cli {

namespace {

struct IntegrateCmdOptions {
  std::string dataset;
  std::string output;
  IntegrateFlags flags;
  bool json = false;
  bool list = false;
  bool list_formats = false;
};

/// `integrate run.bag --list`: the bag's topics, types and message counts.
int listBagTopics(const IntegrateCmdOptions& o) {
  std::string note;
  const std::vector<BagTopic> topics = chronomap::listBagTopics(o.dataset, &note);
  if (o.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& t : topics) {
      out.push_back({{"topic", t.name}, {"type", t.type}, {"messages", t.messages}, {"encoding", t.encoding}});
    }
    std::cout << out.dump() << "\n";
    if (!note.empty()) std::cerr << "chronomap: warning: " << note << "\n";
    return 0;
  }
  std::cout << o.dataset << ": " << topics.size() << " topic(s)" << (note.empty() ? "" : " (" + note + ")") << "\n";
  for (const auto& t : topics) {
    std::cout << "  " << t.name << "  " << t.type << "  " << t.messages << " message(s)";
    if (!t.encoding.empty()) std::cout << "  " << t.encoding;
    std::cout << "\n";
  }
  return 0;
}

/// `integrate --list-formats`: every reader of the registry, in detection order.
int listFormats(bool json) {
  const std::vector<DatasetReader> readers = registerReaders();
  if (json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& r : readers) {
      out.push_back({{"name", r.name}, {"aliases", r.aliases}, {"description", r.description}});
    }
    std::cout << out.dump() << "\n";
    return 0;
  }
  std::cout << "formats, in the order detection tries them (--format NAME skips detection):\n";
  for (const auto& r : readers) {
    std::string names = r.name;
    for (const auto& a : r.aliases) names += ", " + a;
    std::cout << "  " << names << "\n      " << r.description << "\n";
  }
  return 0;
}

}  // namespace

nlohmann::json upJson(const ChosenUp& up) {
  nlohmann::json j = {{"up", toString(up.axis)}, {"up_from", up.from}};
  if (up.estimate) {
    j["up_floor_share"] = up.estimate->floor_share[static_cast<size_t>(up.axis)];
    j["up_sampled_cells"] = up.estimate->points;
    nlohmann::json scores = nlohmann::json::object();
    for (size_t k = 0; k < kUpAxes.size(); ++k) scores[toString(kUpAxes[k])] = up.estimate->scores[k];
    j["up_scores"] = scores;
  }
  return j;
}

std::string upLine(const ChosenUp& up) {
  std::ostringstream line;
  line << toString(up.axis) << " (" << (up.from == "auto" ? "estimated" : up.from == "map" ? "the map's" : "given");
  if (up.estimate) {
    line << ": a floor of " << static_cast<int>(std::lround(100 * up.estimate->floor_share[static_cast<size_t>(up.axis)]))
         << "% of " << up.estimate->points << " sampled cells in " << up.estimate->frames << " frame(s)";
  }
  line << "), turned to +z";
  return line.str();
}

namespace {

nlohmann::json integrateJson(const IntegrateCmdOptions& o, const IntegratedSession& session,
                             uint64_t file_bytes) {
  const IntegrationStats& stats = session.stats;
  const SessionMapCounts counts = session.map.counts();
  nlohmann::json j = {{"frames", stats.frames},
          {"frames_dropped", session.frames_dropped},
          {"points", stats.points},
          {"points_skipped", stats.pointsSkipped()},
          {"points_invalid", stats.points_invalid},
          {"points_depth_edges", stats.points_depth_edges},
          {"points_out_of_range", stats.points_out_of_range},
          {"points_outside_map", stats.points_outside_map},
          {"rays", stats.rays},
          {"occupied", counts.occupied_voxels},
          {"free", counts.free_voxels},
          {"nodes", counts.inner_nodes + counts.leaves},
          {"bytes", session.map.memoryBytes()},
          {"file_bytes", file_bytes},
          {"resolution_m", session.map.resolution_m()},
          {"seconds", stats.seconds},
          {"output", o.output},
          {"warnings", session.warnings}};
  if (session.up.from != "default") j.update(upJson(session.up));
  return j;
}

void printIntegrated(const IntegrateCmdOptions& o, const IntegratedSession& session, uint64_t file_bytes,
                     double max_range_m) {
  const IntegrationStats& stats = session.stats;
  const SessionMap& map = session.map;
  const SessionMapCounts counts = map.counts();
  std::cout << "integrated " << stats.frames << " frame(s) of " << o.dataset << " (" << session.format << ")";
  if (session.frames_dropped || !session.dropped_reasons.empty()) {
    std::cout << ", " << session.frames_dropped << " frame(s) dropped ("
              << (session.dropped_reasons.empty() ? "without pose or colour" : session.dropped_reasons) << ")";
  }
  std::cout << "\n  points:  " << stats.points << " cast, " << stats.pointsSkipped() << " skipped ("
            << stats.points_invalid << " invalid, " << stats.points_out_of_range << " beyond " << max_range_m
            << " m, " << stats.points_outside_map << " outside the map"
            << (stats.points_depth_edges ? ", " + std::to_string(stats.points_depth_edges) + " at depth edges" : "")
            << ")\n"
            << "  voxels:  " << counts.occupied_voxels << " occupied, " << counts.free_voxels << " free at "
            << map.resolution_m() << " m\n"
            << "  nodes:   " << counts.inner_nodes + counts.leaves << " (" << counts.leaves << " leaves, "
            << counts.compressed_leaves << " compressed), " << humanBytes(static_cast<double>(map.memoryBytes()))
            << " in memory\n"
            << "  time:    " << stats.seconds << " s ("
            << (stats.seconds > 0 ? static_cast<double>(stats.points) / stats.seconds / 1e6 : 0.0) << " M points/s)"
            << "\n";
  if (session.up.from != "default") std::cout << "  up:      " << upLine(session.up) << "\n";
  std::cout << "wrote " << o.output << " (" << humanBytes(static_cast<double>(file_bytes)) << ")\n";
}

int runIntegrate(const IntegrateCmdOptions& o) {
  if (o.list_formats) return listFormats(o.json);
  if (o.dataset.empty()) throw UsageError("integrate: DATASET is required");
  if (o.list) return listBagTopics(o);
  if (o.output.empty()) throw UsageError("integrate: --output is required");
  requireExtension(o.output, ".cmap", "output");
  refuseOverwritingInputs(o.output, {o.dataset});
  const SessionSettings settings = sessionSettings(o.flags);
  const IntegratedSession session =
      integrateDataset(o.dataset, settings, {}, terminalProgress(o.json));
  writeSessionMap(o.output, session.map, sessionMetadata(o.dataset, session, settings));
  const auto file_bytes = std::filesystem::file_size(o.output);
  for (const std::string& w : session.warnings) printWarning(o.dataset + ": " + w);
  if (o.json) {
    std::cout << integrateJson(o, session, file_bytes).dump() << "\n";
  } else {
    printIntegrated(o, session, file_bytes, settings.integrator.max_range_m);
  }
  return 0;
}

}  // namespace

CLI::Validator numberIn(double lo, double hi) {
  std::ostringstream range;
  range << "[" << lo << ", " << hi << "]";
  return CLI::Validator(
      [lo, hi, limits = range.str()](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0' || !std::isfinite(v)) return text + ": not a finite number";
        if (v < lo || v > hi) return text + ": must lie in " + limits;
        return {};
      },
      "in " + range.str());
}

void requireExtension(const std::string& path, const std::string& ext, const std::string& what) {
  if (std::filesystem::path(path).extension() != ext) throw UsageError(what + " '" + path + "' must end in " + ext);
}

std::vector<std::string> splitCommas(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) parts.push_back(item);
  return parts;
}

namespace {

/// --carve-level: "auto" (kCarveAuto) or one digit from 0 to kMaxCarveLevel.
int parseCarveLevel(const std::string& v) {
  if (v == "auto") return kCarveAuto;
  if (v.size() != 1 || v[0] < '0' || v[0] > '0' + kMaxCarveLevel) {
    throw UsageError("--carve-level must be auto or a level from 0 to " + std::to_string(kMaxCarveLevel) + ", not '" +
                     v + "'");
  }
  return v[0] - '0';
}

}  // namespace

/// --format's help, from the readers this build has.
static std::string formatHelp() {
  std::string names = "auto (detect)";
  for (const DatasetReader& r : registerReaders()) names += ", " + r.name;
  return names + " (--list-formats says what each reads)";
}

/// --up: an axis, auto, or nothing given.
static UpSettings upSettings(const std::string& v) {
  if (v.empty()) return {};
  if (v == "auto") return {std::nullopt, true};
  try {
    return {parseUpAxis(v), false};
  } catch (const UsageError&) {
    throw UsageError("--up must be +x, -x, +y, -y, +z, -z or auto, not '" + v + "'");
  }
}

SessionSettings sessionSettings(const IntegrateFlags& f) {
  SessionSettings s;
  s.resolution_m = f.resolution_m;
  s.dataset.format = parseRecordingFormat(f.format);
  s.dataset.depth_scale = f.depth_scale;
  if (!f.intrinsics.empty()) s.dataset.intrinsics = parseIntrinsics(f.intrinsics);
  if (!f.pose.empty()) {
    try {
      s.dataset.pose = parsePose(f.pose);
    } catch (const DataError& e) {
      throw UsageError(std::string("--pose: ") + e.what());
    }
  }
  if (!f.trajectory.empty()) s.dataset.trajectory = f.trajectory;
  s.dataset.bag = f.bag;
  if (f.pose_tolerance_s) s.dataset.bag.pose_tolerance_s = *f.pose_tolerance_s;
  s.integrator.max_range_m = f.max_range_m;
  s.integrator.carve_beyond_range = f.carve_beyond_range;
  s.integrator.depth_edge_ratio = f.depth_edge_ratio;
  s.integrator.fast = f.fast;
  s.integrator.threads = f.threads;
  s.integrator.compress_free = !f.no_compress;
  s.integrator.hit_positions = !f.no_positions;
  s.integrator.carve_level = parseCarveLevel(f.carve_level);
  if (f.memory_limit_gib) s.integrator.memory_limit_bytes = memoryLimitFromGib(*f.memory_limit_gib);
  s.up = upSettings(f.up);
  return s;
}

namespace {

std::string memoryLimitHelp() {
  std::string help(
      "most memory integration may take, GiB: the session map with the frames' scratch, and one frame's scratch "
      "per thread (this over the threads); past it, integration stops and says what it needed. 0 = no limit; "
      "default half the memory this process may use (physical memory, ulimit -v, the cgroup's limit: ");
  return help.append(humanBytes(static_cast<double>(defaultMemoryLimitBytes()))).append(" here)");
}

}  // namespace

namespace {

void addBagFlags(CLI::App* app, IntegrateFlags& f) {
  const std::string detected = " (detected when the bag has only one)";
  app->add_option("--depth-topic", f.bag.depth_topic, "ROS bag: depth image topic, 16UC1 mm or 32FC1 m, or a compressedDepth CompressedImage topic" + detected);
  app->add_option("--color-topic,--colour-topic", f.bag.colour_topic, "ROS bag: colour image topic (Image, or a JPEG/PNG CompressedImage); 'none' for no colour" + detected);
  app->add_option("--info-topic", f.bag.info_topic,
                  "ROS bag: CameraInfo of the depth camera (default: camera_info beside the depth topic)");
  app->add_option("--cloud-topic", f.bag.cloud_topic, "ROS bag: PointCloud2 topic, read instead of depth images");
  app->add_option("--pose-topic", f.bag.pose_topic,
                  "ROS bag: nav_msgs/Odometry or geometry_msgs/PoseStamped topic with the sensor's pose");
  app->add_option("--fixed-frame", f.bag.fixed_frame,
                  "ROS bag: poses from /tf and /tf_static, of each message's frame in this frame (e.g. map)");
  app->add_option("--pose-tolerance", f.pose_tolerance_s,
                  "ROS bag: most seconds between a frame and the poses it is interpolated from (default 0.1); "
                  "frames without are dropped and counted")
      ->check(numberIn(0.0, 3600.0));
}

}  // namespace

void addIntegrateFlags(CLI::App* app, IntegrateFlags& f) {
  std::ostringstream extent;
  extent << "edge of a unit voxel, metres (" << kMinResolution_m << " to " << kMaxResolution_m << "; a map spans "
         << kKeysPerAxis << " voxels per axis)";
  app->add_option("--resolution", f.resolution_m, extent.str())
      ->check(numberIn(kMinResolution_m, kMaxResolution_m))
      ->capture_default_str();
  app->add_option("--max-range", f.max_range_m,
                  "points farther from the sensor are discarded, metres (any positive range; beyond the map's "
                  "diagonal, sqrt(3) * 65536 voxels, it keeps every point in the map)")
      ->capture_default_str();
  app->add_flag("--carve-beyond-range", f.carve_beyond_range,
                "carve free space along the rays of points beyond --max-range, up to the range, instead of discarding "
                "them whole (as OctoMap does): space seen through, such as an open doorway before a far wall, is then "
                "observed free");
  app->add_option("--depth-edges", f.depth_edge_ratio,
                  "depth images: drop a point whose range differs from a neighbouring pixel's by more than this "
                  "share of its own (0.05: 5 cm at 1 m): the flying pixels a depth camera makes at the edges of "
                  "objects (docs/integration.md); 0 = off")
      ->check(numberIn(0.0, 1e6))
      ->capture_default_str();
  app->add_option("--format", f.format, formatHelp())->capture_default_str();
  app->add_option("--up", f.up,
                  "which axis of the recording's world frame is up: +x, -x, +y, -y, +z or -z (a camera's optical "
                  "frame: -y), or auto (estimated from the floor: docs/frames.md); the frames are turned so that it "
                  "becomes +z and the map records the turn. Default +z (build: the map's own)");
  app->add_flag("--fast", f.fast,
                "bundle the points of a frame that end in the same voxel into one weighted ray "
                "(much faster; see docs/integration.md for how far the counters may differ)");
  app->add_option("--threads", f.threads, "worker threads, 0 = all cores (the map does not depend on it)")
      ->check(numberIn(0, kMaxThreads))
      ->capture_default_str();
  app->add_flag("--no-compress", f.no_compress, "keep every free unit voxel instead of merging free subtrees");
  app->add_flag("--no-positions", f.no_positions,
                "do not record where in each voxel the rays ended (fast mode about 7% faster; the diff's shift test "
                "then sees surfaces only to the voxel; docs/changes.md)");
  app->add_option("--carve-level", f.carve_level,
                  "with --fast: carve free space far from the surfaces in cubes of 2^L voxels per axis (0 = off; "
                  "auto = 2 at 0.025 m and finer, where it is about 1.7x faster, 0 above); hits and colours stay "
                  "those of --fast (docs/integration.md)")
      ->capture_default_str();
  app->add_option("--memory-limit", f.memory_limit_gib, memoryLimitHelp());
  app->add_option("--depth-scale", f.depth_scale, "depth image units per metre (TUM 5000, 3DMatch 1000)");
  app->add_option("--intrinsics", f.intrinsics, "camera intrinsics fx,fy,cx,cy in pixels");
  app->add_option("--pose", f.pose, "pose of a single cloud: tx,ty,tz,qx,qy,qz,qw (sensor to map)");
  app->add_option("--trajectory", f.trajectory, "TUM: pose file to use instead of trajectory.txt/groundtruth.txt");
  addBagFlags(app, f);
}

Command addIntegrate(CLI::App& root) {
  auto o = std::make_shared<IntegrateCmdOptions>();
  CLI::App* app = root.add_subcommand(
      "integrate",
      "Integrate one recording into a session map (.cmap).\n"
      "DATASET is a TUM RGB-D folder (depth.txt, rgb.txt, trajectory.txt or groundtruth.txt), a "
      "3DMatch/7-Scenes folder (frame-*.depth.png, frame-*.pose.txt, camera-intrinsics.txt), a ScanNet export "
      "(color/N.jpg, depth/N.png, pose/N.txt, intrinsic/), a ROS 1 bag (.bag) or a ROS 2 bag (.mcap or .db3 storage, or its folder with "
      "metadata.yaml; --list shows a bag's topics), a single "
      "PCD/PLY/XYZ cloud (seen from the origin unless --pose), or a text list of clouds with poses "
      "('cloud.pcd tx ty tz qx qy qz qw' per line). --list-formats lists every reader and what it looks for.");
  app->add_option("DATASET", o->dataset, "dataset folder or file");
  app->add_option("-o,--output", o->output, "session map to write (.cmap)");
  addIntegrateFlags(app, o->flags);
  app->add_flag("--list", o->list, "ROS bag: list its topics, their types and message counts, and stop");
  app->add_flag("--list-formats", o->list_formats,
                "list the formats this chronomap reads (--format's names), in the order detection tries them, "
                "and stop");
  app->add_flag("--json", o->json, "print a JSON summary on stdout");
  return {app, [o] { return runIntegrate(*o); }};
}

}  // namespace chronomap::cli
