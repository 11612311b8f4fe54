// The public dynamic-map benchmark's scores (docs/benchmarks.md, "Dynamic points"): chronomap's
// static map (staticPoints, what `chronomap clean` writes) and the OctoMap baseline as the
// benchmark runs it (every frame inserted by ray casting into an octomap::OcTree at the same
// resolution; the points in voxels occupied at the end kept), scored in the same run against
// the sequence's gt_cloud.pcd: SA, DA, AA and HA, a ground-truth point kept when the map has a
// point within 0.05 m.
//
// Usage:
//   dynamic_eval SEQ [--resolution R] [--max-range M] [--radius 0.05] [--free-length V]
//                    [--min-free-frames N] [--min-free-ratio F] [--free-margin M] [--free-margin-growth G]
//                    [--dilation V] [--spread STEPS] [--spread-fraction F] [--exact] [--save DIR]
//                    [--no-baseline]
//   dynamic_eval --score GT.pcd MAP.pcd [--radius 0.05]     (score any method's output)
//   dynamic_eval --make-real DATASET -o SEQ [--repeat 8] [--people 2] [--seed 1] [--pixel-step 2]
//                    [--gt-stride 8] [--intrinsics fx,fy,cx,cy]
//     a real static recording (any reader: a 3DMatch folder, ...) as a dynamic-map sequence,
//     each frame shown --repeat times while simulated people walk through it, drawn in by depth
//     (where a person is nearer than the real depth), labelled in gt_cloud.pcd.
// The last line of output is one JSON object.

#include <octomap/OcTree.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/integrate/static_points.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/sim/box_room.h"
#include "chronomap/sim/dynamic_map.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

struct Options {
  std::string mode = "eval";  // eval, score, make-real
  std::vector<std::string> inputs;
  std::string output, save, intrinsics;
  double radius_m = 0.05;
  StaticPointSettings points;
  size_t repeat = 8, people = 2, pixel_step = 2, gt_stride = 8;
  bool baseline = true;  // --no-baseline: chronomap only (for choosing constants)
  uint64_t seed = 1;
};

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

/// The OctoMap baseline: every frame inserted with its origin, the points in occupied voxels kept.
PointCloud octomapBaseline(const Dataset& dataset, double resolution_m, double max_range_m, size_t& nodes) {
  octomap::OcTree tree(resolution_m);
  auto worldPoints = [&](size_t i, Frame& frame) {
    frame = dataset.load(i);
    octomap::Pointcloud cloud;
    for (const Eigen::Vector3f& p : frame.cloud.points) {
      if (!p.allFinite() || p.squaredNorm() == 0.0f) continue;
      const Eigen::Vector3d w = frame.T_world_sensor * p.cast<double>();
      cloud.push_back(static_cast<float>(w.x()), static_cast<float>(w.y()), static_cast<float>(w.z()));
    }
    return cloud;
  };
  Frame frame;
  for (size_t i = 0; i < dataset.size(); ++i) {
    const octomap::Pointcloud cloud = worldPoints(i, frame);
    const Eigen::Vector3d o = frame.T_world_sensor.translation();
    tree.insertPointCloud(cloud, octomap::point3d(static_cast<float>(o.x()), static_cast<float>(o.y()),
                                                  static_cast<float>(o.z())),
                          max_range_m);
  }
  nodes = tree.size();
  PointCloud kept;
  for (size_t i = 0; i < dataset.size(); ++i) {
    const octomap::Pointcloud cloud = worldPoints(i, frame);
    for (size_t k = 0; k < cloud.size(); ++k) {
      const octomap::OcTreeNode* node = tree.search(cloud[k]);
      if (node && tree.isNodeOccupied(node)) kept.points.emplace_back(cloud[k].x(), cloud[k].y(), cloud[k].z());
    }
  }
  kept.width = static_cast<uint32_t>(kept.points.size());
  return kept;
}

nlohmann::json scoresJson(const StaticMapScores& s, size_t map_points, double secs) {
  return {{"SA", s.staticAccuracy()},       {"DA", s.dynamicAccuracy()},     {"AA", s.associatedAccuracy()},
          {"HA", s.harmonicAccuracy()},      {"static", s.static_total},      {"dynamic", s.dynamic_total},
          {"static_kept", s.static_kept},    {"dynamic_removed", s.dynamic_removed}, {"map_points", map_points},
          {"seconds", secs}};
}

void printRow(const std::string& name, const StaticMapScores& s, size_t map_points, double secs) {
  std::printf("  %-10s %10zu %8.2f %8.2f %8.2f %8.2f %9.1f\n", name.c_str(), map_points, 100 * s.staticAccuracy(),
              100 * s.dynamicAccuracy(), 100 * s.associatedAccuracy(), 100 * s.harmonicAccuracy(), secs);
}

/// gt_cloud.pcd's points and labels (its intensity field).
std::pair<PointCloud, std::vector<float>> readTruth(const fs::path& path) {
  PcdExtras extras;
  PointCloud truth = readPcd(path, extras);
  if (extras.intensity.size() != truth.points.size()) {
    throw DataError(path.string() + ": the ground truth has no intensity field (0 static, 1 dynamic)");
  }
  return {std::move(truth), std::move(extras.intensity)};
}

int runEval(const Options& o) {
  const fs::path seq = o.inputs.at(0);
  const auto [truth, labels] = readTruth(seq / "gt_cloud.pcd");
  DatasetSettings ds;
  ds.format = "dynamic-map";
  const auto dataset = openRecording(seq, ds);
  std::printf("dynamic_eval %s: %zu frames, %zu ground-truth points, resolution %.3f m, radius %.3f m\n",
              seq.string().c_str(), dataset->size(), truth.points.size(), o.points.resolution_m, o.radius_m);
  auto start = std::chrono::steady_clock::now();
  const StaticPointResult ours = staticPoints(*dataset, o.points);
  const double ours_s = seconds(start);
  start = std::chrono::steady_clock::now();
  size_t octomap_nodes = 0;
  const PointCloud baseline =
      o.baseline ? octomapBaseline(*dataset, o.points.resolution_m, o.points.max_range_m, octomap_nodes) : PointCloud{};
  const double octomap_s = seconds(start);
  std::vector<uint8_t> kept;
  const StaticMapScores a = scoreStaticMap(truth, labels, ours.points, o.radius_m, &kept);
  const StaticMapScores b = scoreStaticMap(truth, labels, baseline, o.radius_m);
  std::printf("  %zu static, %zu dynamic ground-truth points\n", a.static_total, a.dynamic_total);
  std::printf("  %-10s %10s %8s %8s %8s %8s %9s\n", "method", "points", "SA %", "DA %", "AA %", "HA %", "seconds");
  printRow("chronomap", a, ours.points.points.size(), ours_s);
  if (o.baseline) printRow("octomap", b, baseline.points.size(), octomap_s);
  const double aa_ratio = b.associatedAccuracy() > 0 ? a.associatedAccuracy() / b.associatedAccuracy() : 0.0;
  if (o.baseline) {
    std::printf("  ratios chronomap / octomap: SA %.3fx, DA %.3fx, AA %.3fx, time %.2fx\n",
                a.staticAccuracy() / std::max(b.staticAccuracy(), 1e-12),
                a.dynamicAccuracy() / std::max(b.dynamicAccuracy(), 1e-12), aa_ratio, ours_s / std::max(octomap_s, 1e-9));
  }
  if (!o.save.empty()) {
    fs::create_directories(o.save);
    writePcd(fs::path(o.save) / "chronomap_output.pcd", ours.points, PcdEncoding::Binary);
    writePcd(fs::path(o.save) / "octomap_output.pcd", baseline, PcdEncoding::Binary);
    // The ground-truth points chronomap scored wrongly: dynamic ones kept, static ones removed.
    PointCloud wrong;
    PcdExtras labelled;
    for (size_t i = 0; i < truth.points.size(); ++i) {
      if ((labels[i] == 1.0f) == (kept[i] == 1)) {
        wrong.points.push_back(truth.points[i]);
        labelled.intensity.push_back(labels[i]);
      }
    }
    wrong.width = static_cast<uint32_t>(wrong.points.size());
    writePcd(fs::path(o.save) / "chronomap_wrong.pcd", wrong, PcdEncoding::Binary, &labelled);
  }
  nlohmann::json out = {{"sequence", seq.string()},
                        {"frames", dataset->size()},
                        {"resolution_m", o.points.resolution_m},
                        {"radius_m", o.radius_m},
                        {"chronomap", scoresJson(a, ours.points.points.size(), ours_s)},
                        {"octomap", scoresJson(b, baseline.points.size(), octomap_s)},
                        {"octomap_nodes", octomap_nodes},
                        {"aa_ratio", aa_ratio}};
  std::cout << out.dump() << "\n";
  return 0;
}

int runScore(const Options& o) {
  const auto [truth, labels] = readTruth(o.inputs.at(0));
  const PointCloud map = readCloud(o.inputs.at(1));
  const auto start = std::chrono::steady_clock::now();
  const StaticMapScores s = scoreStaticMap(truth, labels, map, o.radius_m);
  std::printf("  %-10s %10s %8s %8s %8s %8s %9s\n", "map", "points", "SA %", "DA %", "AA %", "HA %", "seconds");
  printRow(fs::path(o.inputs.at(1)).filename().string(), s, map.points.size(), seconds(start));
  std::cout << scoresJson(s, map.points.size(), seconds(start)).dump() << "\n";
  return 0;
}

/// The camera of a recording: --intrinsics, else camera-intrinsics.txt in the folder or above it.
PinholeCamera cameraOf(const Options& o, const fs::path& dataset, const Frame& first) {
  CameraIntrinsics k;
  if (!o.intrinsics.empty()) {
    k = parseIntrinsics(o.intrinsics);
  } else {
    fs::path file = dataset / "camera-intrinsics.txt";
    if (!fs::exists(file)) file = dataset.parent_path() / "camera-intrinsics.txt";
    if (!fs::exists(file)) throw UsageError(dataset.string() + ": no camera-intrinsics.txt; give --intrinsics fx,fy,cx,cy");
    k = readIntrinsicsFile(file);
  }
  PinholeCamera camera;
  camera.width = first.cloud.width;
  camera.height = first.cloud.height;
  camera.fx = k.fx;
  camera.fy = k.fy;
  camera.cx = k.cx;
  camera.cy = k.cy;
  return camera;
}

/// The median depth of a frame's valid points (sensor frame), metres.
double medianDepth(const Frame& frame) {
  std::vector<float> z;
  for (const Eigen::Vector3f& p : frame.cloud.points) {
    if (p.allFinite() && p.z() > 0.0f) z.push_back(p.z());
  }
  if (z.empty()) throw DataError(frame.source + ": no valid depth");
  std::nth_element(z.begin(), z.begin() + static_cast<long>(z.size() / 2), z.end());
  return z[z.size() / 2];
}

/// People walking across the first camera's view, at 45% to 75% of its median depth (room behind
/// them, as in a room people walk through), in a frame whose z is up if the first camera was
/// level (the first camera at 1.4 m, looking along +x).
std::vector<Walker> realWalkers(size_t people, uint64_t seed, double median_depth_m) {
  std::mt19937_64 rng(seed * 104729 + 3);
  std::uniform_real_distribution<double> depth(0.45 * median_depth_m, 0.75 * median_depth_m), speed(0.5, 1.2),
      unit(0.0, 1.0);
  std::vector<Walker> out;
  for (size_t i = 0; i < people; ++i) {
    Walker w;
    const double d = depth(rng);
    w.from_m = Eigen::Vector3d(d, -1.6, 0.0);
    w.to_m = Eigen::Vector3d(d + 0.6 * (unit(rng) - 0.5), 1.6, 0.0);
    w.speed_mps = speed(rng);
    w.start_m = unit(rng) * 6.4;
    out.push_back(w);
  }
  return out;
}

int runMakeReal(const Options& o) {
  if (o.output.empty()) throw UsageError("--make-real needs -o SEQ");
  const fs::path input = o.inputs.at(0);
  DatasetSettings ds;
  ds.colour = false;
  const auto dataset = openRecording(input, ds);
  const Frame first = dataset->load(0);
  const PinholeCamera camera = cameraOf(o, input, first);
  // World: the first camera level at 1.4 m looking along +x (lookHorizontal), so people stand up.
  const Eigen::Isometry3d T_up_world = lookHorizontal({0.0, 0.0, 1.4}, 0.0) * first.T_world_sensor.inverse();
  const std::vector<Walker> walkers = realWalkers(o.people, o.seed, medianDepth(first));
  DynamicMapWriter writer(o.output, o.gt_stride);
  size_t n = 0;
  for (size_t i = 0; i < dataset->size(); ++i) {
    const Frame recorded = dataset->load(i);
    for (size_t r = 0; r < o.repeat; ++r, ++n) {
      Frame frame = recorded;
      frame.T_world_sensor = T_up_world * recorded.T_world_sensor;
      std::vector<Box> boxes;
      for (const Walker& w : walkers) boxes.push_back(walkerBox(w, static_cast<double>(n) / 10.0));
      std::vector<uint8_t> dynamic;
      insertBoxesByDepth(frame, camera, boxes, dynamic, 0.0014, o.seed * 7 + n);
      const float nan = std::numeric_limits<float>::quiet_NaN();
      for (size_t p = 0; p < frame.cloud.points.size(); ++p) {
        const size_t u = p % camera.width, v = p / camera.width;
        if (u % o.pixel_step != 0 || v % o.pixel_step != 0) frame.cloud.points[p] = Eigen::Vector3f(nan, nan, nan);
      }
      writer.add(frame, dynamic);
    }
  }
  writer.finish();
  std::printf("wrote %zu frames (%zu recorded x %zu) to %s: %llu points, %llu on people; gt_cloud.pcd %zu points, %zu dynamic\n",
              writer.frames(), dataset->size(), o.repeat, o.output.c_str(),
              static_cast<unsigned long long>(writer.points()), static_cast<unsigned long long>(writer.dynamicPoints()),
              writer.gtPoints(), writer.gtDynamic());
  std::cout << nlohmann::json{{"output", o.output}, {"frames", writer.frames()}, {"points", writer.points()},
                              {"dynamic_points", writer.dynamicPoints()}, {"gt_points", writer.gtPoints()},
                              {"gt_dynamic", writer.gtDynamic()}}
                   .dump()
            << "\n";
  return 0;
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw UsageError(a + " needs a value");
      return argv[++i];
    };
    if (a == "--score") o.mode = "score";
    else if (a == "--make-real") o.mode = "make-real";
    else if (a == "-o") o.output = value();
    else if (a == "--save") o.save = value();
    else if (a == "--intrinsics") o.intrinsics = value();
    else if (a == "--radius") o.radius_m = std::stod(value());
    else if (a == "--resolution") o.points.resolution_m = std::stod(value());
    else if (a == "--max-range") o.points.max_range_m = std::stod(value());
    else if (a == "--free-length") o.points.free_length_voxels = std::stod(value());
    else if (a == "--min-free-frames") o.points.min_free_frames = static_cast<uint32_t>(std::stoul(value()));
    else if (a == "--min-free-ratio") o.points.min_free_ratio = std::stod(value());
    else if (a == "--free-margin") o.points.free_margin_m = std::stod(value());
    else if (a == "--free-margin-growth") o.points.free_margin_per_m2 = std::stod(value());
    else if (a == "--dilation") o.points.occupied_dilation_voxels = std::stoi(value());
    else if (a == "--spread") o.points.spread_steps = std::stoi(value());
    else if (a == "--spread-fraction") o.points.spread_fraction = std::stod(value());
    else if (a == "--exact") o.points.fast = false;
    else if (a == "--no-baseline") o.baseline = false;
    else if (a == "--repeat") o.repeat = std::stoul(value());
    else if (a == "--people") o.people = std::stoul(value());
    else if (a == "--seed") o.seed = std::stoull(value());
    else if (a == "--pixel-step") o.pixel_step = std::max<size_t>(1, std::stoul(value()));
    else if (a == "--gt-stride") o.gt_stride = std::stoul(value());
    else if (!a.empty() && a[0] == '-') throw UsageError("unknown flag " + a);
    else o.inputs.push_back(a);
  }
  const size_t needed = o.mode == "score" ? 2 : 1;
  if (o.inputs.size() != needed) {
    throw UsageError("usage: dynamic_eval SEQ | --score GT.pcd MAP.pcd | --make-real DATASET -o SEQ (see the file's comment)");
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const Options o = parse(argc, argv);
    if (o.mode == "score") return runScore(o);
    if (o.mode == "make-real") return runMakeReal(o);
    return runEval(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dynamic_eval: error: %s\n", e.what());
    return 1;
  }
}
