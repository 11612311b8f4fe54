#include "chronomap/sim/dynamic_map.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <sstream>
#include <unordered_map>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/cloud_io.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

/// A pose's VIEWPOINT values, tx ty tz qw qx qy qz, to 9 significant digits.
std::vector<std::string> viewpointOf(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  const double v[7] = {T.translation().x(), T.translation().y(), T.translation().z(), q.w(), q.x(), q.y(), q.z()};
  std::vector<std::string> out;
  for (double x : v) {
    std::ostringstream s;
    s.precision(9);
    s << x;
    out.push_back(s.str());
  }
  return out;
}

/// Distance from `p` to the segment a-b, in the xy plane.
double distanceToSegmentXy(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

}  // namespace

Box walkerBox(const Walker& w, double time_s) {
  const double length = (w.to_m - w.from_m).norm();
  Eigen::Vector3d at = w.from_m;
  if (length > 0.0) {
    // Back and forth: the distance walked folded into [0, length].
    const double walked = std::fmod(w.start_m + w.speed_mps * time_s, 2.0 * length);
    const double along = walked <= length ? walked : 2.0 * length - walked;
    at = w.from_m + (w.to_m - w.from_m) * (along / length);
  }
  const Eigen::Vector3d half(0.5 * w.size_m.x(), 0.5 * w.size_m.y(), 0.0);
  return Box{at - half, at + half + Eigen::Vector3d(0.0, 0.0, w.size_m.z()), Rgb{255, 0, 255}};
}

DynamicMapWriter::DynamicMapWriter(const fs::path& folder, size_t gt_stride)
    : staged_(std::make_unique<StagedFolder>(folder)),
      folder_(staged_->path()),
      gt_stride_(std::max<size_t>(1, gt_stride)) {
  fs::create_directories(folder_ / "pcd");
}

DynamicMapWriter::~DynamicMapWriter() = default;

void DynamicMapWriter::add(const Frame& frame, const std::vector<uint8_t>& dynamic) {
  if (!dynamic.empty() && dynamic.size() != frame.cloud.points.size()) {
    throw UsageError("dynamic-map writer: " + std::to_string(dynamic.size()) + " labels for " +
                     std::to_string(frame.cloud.points.size()) + " points");
  }
  PointCloud world;
  for (size_t i = 0; i < frame.cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = frame.cloud.points[i];
    if (!p.allFinite()) continue;
    const Eigen::Vector3f w = (frame.T_world_sensor * p.cast<double>()).cast<float>();
    world.points.push_back(w);
    const bool moving = !dynamic.empty() && dynamic[i] != 0;
    dynamic_points_ += moving ? 1 : 0;
    if (points_++ % gt_stride_ == 0) {
      gt_.points.push_back(w);
      gt_labels_.push_back(moving ? 1.0f : 0.0f);
    }
  }
  world.width = static_cast<uint32_t>(world.points.size());
  PcdExtras extras;
  extras.viewpoint = viewpointOf(frame.T_world_sensor);
  char name[32];
  std::snprintf(name, sizeof name, "%06zu.pcd", frames_++);
  writePcd(folder_ / "pcd" / name, world, PcdEncoding::Binary, &extras);
}

void DynamicMapWriter::finish() {
  gt_.width = static_cast<uint32_t>(gt_.points.size());
  PcdExtras extras;
  extras.intensity = gt_labels_;
  writePcd(folder_ / "gt_cloud.pcd", gt_, PcdEncoding::Binary, &extras);
  staged_->commit();
}

size_t DynamicMapWriter::gtDynamic() const {
  size_t n = 0;
  for (float v : gt_labels_) n += v != 0.0f ? 1 : 0;
  return n;
}

std::vector<Walker> roomWalkers(const BoxRoom& room, size_t people, uint64_t seed) {
  constexpr double kWallMargin_m = 0.4;     // the box stays inside the room
  constexpr double kCameraClearance_m = 1.0;  // walks keep away from the camera's circle
  std::mt19937_64 rng(seed * 7919 + 17);
  const Eigen::Vector3d lo = room.bounds.min_m + Eigen::Vector3d::Constant(kWallMargin_m);
  const Eigen::Vector3d hi = room.bounds.max_m - Eigen::Vector3d::Constant(kWallMargin_m);
  std::uniform_real_distribution<double> ux(lo.x(), hi.x()), uy(lo.y(), hi.y()), speed(0.6, 1.4), unit(0.0, 1.0);
  std::vector<Walker> out;
  while (out.size() < people) {
    const Eigen::Vector2d a(ux(rng), uy(rng)), b(ux(rng), uy(rng));
    if ((b - a).norm() < 1.5 || distanceToSegmentXy(Eigen::Vector2d::Zero(), a, b) < kCameraClearance_m) continue;
    Walker w;
    w.from_m = Eigen::Vector3d(a.x(), a.y(), room.bounds.min_m.z());
    w.to_m = Eigen::Vector3d(b.x(), b.y(), room.bounds.min_m.z());
    w.speed_mps = speed(rng);
    w.start_m = unit(rng) * 2.0 * (b - a).norm();
    out.push_back(w);
  }
  return out;
}

namespace {

/// One camera of the ring: `count` cameras share the horizontal circle, each a little wider
/// than its share (one camera: the Kinect's 57 degrees).
PinholeCamera ringCamera(size_t count, double scale) {
  PinholeCamera camera;
  camera.width = static_cast<uint32_t>(std::lround(640 * scale));
  camera.height = static_cast<uint32_t>(std::lround(480 * scale));
  const double hfov_rad = count <= 1 ? 57.0 * std::numbers::pi / 180.0
                                     : 2.0 * std::numbers::pi / static_cast<double>(count) + 4.0 * std::numbers::pi / 180.0;
  camera.fx = camera.fy = 0.5 * camera.width / std::tan(0.5 * hfov_rad);
  camera.cx = 0.5 * camera.width - 0.5;
  camera.cy = 0.5 * camera.height - 0.5;
  return camera;
}

/// Frame i of the simulated sequence: every camera of the ring rendered with the people drawn in
/// by depth, joined into one frame in the first camera's frame; `dynamic` labels its points.
Frame renderRingFrame(const DynamicMapSimSettings& s, const BoxRoom& room, const PinholeCamera& camera,
                      const std::vector<Walker>& walkers, size_t i, std::vector<uint8_t>& dynamic) {
  const double turn = 2.0 * (2.0 * std::numbers::pi) * static_cast<double>(i) / static_cast<double>(s.frames);
  const Eigen::Vector3d position(0.3 * std::cos(turn), 0.3 * std::sin(turn), 1.2);
  const double time_s = static_cast<double>(i) / s.frame_rate_hz;
  std::vector<Box> people;
  people.reserve(walkers.size());
  for (const Walker& w : walkers) people.push_back(walkerBox(w, time_s));
  Frame joined;
  dynamic.clear();
  for (size_t c = 0; c < s.cameras; ++c) {
    const double yaw = turn + 2.0 * std::numbers::pi * static_cast<double>(c) / static_cast<double>(s.cameras);
    const uint64_t seed = (s.seed * 1000003 + i) * 64 + c;
    Frame f = renderFrame(room, camera, lookHorizontal(position, yaw), s.noise_per_m2, seed);
    std::vector<uint8_t> inserted;
    insertBoxesByDepth(f, camera, people, inserted, s.noise_per_m2, seed ^ 0x9e3779b97f4a7c15ULL);
    if (c == 0) joined.T_world_sensor = f.T_world_sensor;
    const Eigen::Isometry3f T_first_this = (joined.T_world_sensor.inverse() * f.T_world_sensor).cast<float>();
    for (const Eigen::Vector3f& p : f.cloud.points) joined.cloud.points.push_back(T_first_this * p);
    dynamic.insert(dynamic.end(), inserted.begin(), inserted.end());
  }
  joined.cloud.width = static_cast<uint32_t>(joined.cloud.points.size());
  return joined;
}

}  // namespace

DynamicMapSimSummary simulateDynamicMap(const DynamicMapSimSettings& s, const fs::path& folder,
                                        const std::function<void(size_t, size_t)>& progress) {
  if (s.frames == 0 || s.frames > 100000) throw UsageError("--frames: must lie in [1, 100000]");
  if (!(s.resolution_scale >= 0.05 && s.resolution_scale <= 1.0)) {
    throw UsageError("--resolution-scale: must lie in [0.05, 1]");
  }
  if (!(s.frame_rate_hz > 0.0)) throw UsageError("dynamic-map simulation: the frame rate must be positive");
  if (s.cameras == 0 || s.cameras > 36) throw UsageError("dynamic-map simulation: 1 to 36 cameras");
  const auto start = std::chrono::steady_clock::now();
  const BoxRoom room = defaultRoom();
  const PinholeCamera camera = ringCamera(s.cameras, s.resolution_scale);
  const std::vector<Walker> walkers = roomWalkers(room, s.people, s.seed);
  DynamicMapWriter writer(folder, s.gt_stride);
  std::vector<uint8_t> dynamic;
  for (size_t i = 0; i < s.frames; ++i) {
    writer.add(renderRingFrame(s, room, camera, walkers, i, dynamic), dynamic);
    if (progress) progress(i + 1, s.frames);
  }
  writer.finish();
  DynamicMapSimSummary out;
  out.frames = writer.frames();
  out.points = writer.points();
  out.dynamic_points = writer.dynamicPoints();
  out.gt_points = writer.gtPoints();
  out.gt_dynamic = writer.gtDynamic();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

namespace {

void checkScoring(const PointCloud& truth, const std::vector<float>& labels, double radius_m) {
  if (labels.size() != truth.points.size()) {
    throw UsageError("scoring a static map: " + std::to_string(labels.size()) + " labels for " +
                     std::to_string(truth.points.size()) + " ground-truth points");
  }
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) throw UsageError("scoring a static map: the radius must be positive");
}

/// One ground-truth point counted, `kept` by the map or not.
void countPoint(StaticMapScores& s, float label, bool kept) {
  if (label == 0.0f) {
    ++s.static_total;
    s.static_kept += kept ? 1 : 0;
  } else if (label == 1.0f) {
    ++s.dynamic_total;
    s.dynamic_removed += kept ? 0 : 1;
  } else {
    ++s.unlabelled;
  }
}

/// Within the radius as the benchmark decides: sqrt of the single-precision squared distance,
/// not greater than the radius.
bool within(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float radius) {
  return !(std::sqrt((a - b).squaredNorm()) > radius);
}

struct CellHash {
  size_t operator()(const Eigen::Vector3i& c) const {
    return static_cast<size_t>(c.x()) * 73856093u ^ static_cast<size_t>(c.y()) * 19349663u ^
           static_cast<size_t>(c.z()) * 83492791u;
  }
};
struct CellEqual {
  bool operator()(const Eigen::Vector3i& a, const Eigen::Vector3i& b) const { return a == b; }
};

}  // namespace

double StaticMapScores::staticAccuracy() const {
  return static_total == 0 ? 1.0 : static_cast<double>(static_kept) / static_cast<double>(static_total);
}
double StaticMapScores::dynamicAccuracy() const {
  return dynamic_total == 0 ? 1.0 : static_cast<double>(dynamic_removed) / static_cast<double>(dynamic_total);
}
double StaticMapScores::associatedAccuracy() const { return std::sqrt(staticAccuracy() * dynamicAccuracy()); }
double StaticMapScores::harmonicAccuracy() const {
  const double sa = staticAccuracy(), da = dynamicAccuracy();
  return sa + da > 0.0 ? 2.0 * sa * da / (sa + da) : 0.0;
}

StaticMapScores scoreStaticMap(const PointCloud& truth, const std::vector<float>& labels, const PointCloud& map,
                               double radius_m, std::vector<uint8_t>* kept_out) {
  checkScoring(truth, labels, radius_m);
  const float radius = static_cast<float>(radius_m);
  const double inv_cell = 1.0 / radius_m;
  auto cellOf = [&](const Eigen::Vector3f& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() * inv_cell)), static_cast<int>(std::floor(p.y() * inv_cell)),
                           static_cast<int>(std::floor(p.z() * inv_cell)));
  };
  std::unordered_map<Eigen::Vector3i, std::vector<uint32_t>, CellHash, CellEqual> cells;
  for (size_t i = 0; i < map.points.size(); ++i) {
    if (map.points[i].allFinite()) cells[cellOf(map.points[i])].push_back(static_cast<uint32_t>(i));
  }
  StaticMapScores s;
  if (kept_out) kept_out->assign(truth.points.size(), 0);
  for (size_t i = 0; i < truth.points.size(); ++i) {
    const Eigen::Vector3f& p = truth.points[i];
    bool kept = false;
    if (p.allFinite()) {
      const Eigen::Vector3i c = cellOf(p);
      for (int dz = -1; dz <= 1 && !kept; ++dz) {
        for (int dy = -1; dy <= 1 && !kept; ++dy) {
          for (int dx = -1; dx <= 1 && !kept; ++dx) {
            const auto it = cells.find(c + Eigen::Vector3i(dx, dy, dz));
            if (it == cells.end()) continue;
            for (uint32_t j : it->second) {
              if (within(p, map.points[j], radius)) {
                kept = true;
                break;
              }
            }
          }
        }
      }
    }
    countPoint(s, labels[i], kept);
    if (kept_out) (*kept_out)[i] = kept ? 1 : 0;
  }
  return s;
}

StaticMapScores scoreStaticMapBruteForce(const PointCloud& truth, const std::vector<float>& labels,
                                         const PointCloud& map, double radius_m) {
  checkScoring(truth, labels, radius_m);
  StaticMapScores s;
  for (size_t i = 0; i < truth.points.size(); ++i) {
    bool kept = false;
    for (const Eigen::Vector3f& q : map.points) {
      kept = kept || (truth.points[i].allFinite() && within(truth.points[i], q, static_cast<float>(radius_m)));
    }
    countPoint(s, labels[i], kept);
  }
  return s;
}

}  // namespace chronomap
