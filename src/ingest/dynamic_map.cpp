// The public dynamic-map benchmark's sequences (docs/benchmarks.md, "Dynamic points"): a folder
// with pcd/*.pcd frames whose points are already in the world frame, each file's VIEWPOINT
// (tx ty tz qw qx qy qz) the sensor's pose; gt_cloud.pcd beside it holds the labelled truth.

#include <algorithm>

#include "chronomap/core/error.h"
#include "image_dataset.h"
#include "readers.h"

namespace chronomap::readers {

namespace {

/// A frame's file and the sensor pose its VIEWPOINT gives.
struct PosedCloud {
  fs::path path;
  Eigen::Isometry3d T_world_sensor;
};

/// The frames in time order: by number when every name is a whole number (1.pcd before 10.pcd),
/// else by name (000123.pcd: the same order).
std::vector<fs::path> framesOf(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && e.path().extension() == ".pcd") files.push_back(e.path());
  }
  auto number = [](const fs::path& p) -> std::optional<unsigned long long> {
    const std::string stem = p.stem().string();
    if (stem.empty() || stem.size() > 18 || stem.find_first_not_of("0123456789") != std::string::npos) return {};
    return std::stoull(stem);
  };
  const bool numeric = std::all_of(files.begin(), files.end(), [&](const fs::path& p) { return number(p).has_value(); });
  std::sort(files.begin(), files.end(), [&](const fs::path& a, const fs::path& b) {
    if (numeric && *number(a) != *number(b)) return *number(a) < *number(b);
    return a.filename() < b.filename();
  });
  return files;
}

/// Frames whose points are in the world frame: handed out in the sensor frame (the integrator's
/// convention), T_world_sensor from the file's VIEWPOINT.
class DynamicMapDataset : public Dataset {
 public:
  explicit DynamicMapDataset(std::vector<PosedCloud> frames) : frames_(std::move(frames)) {}
  size_t size() const override { return frames_.size(); }
  std::string format() const override { return "dynamic-map"; }
  Eigen::Isometry3d poseOf(size_t i) const override { return frames_.at(i).T_world_sensor; }
  Frame load(size_t i) const override {
    const PosedCloud& f = frames_.at(i);
    PcdExtras extras;
    Frame frame;
    frame.cloud = readPcd(f.path, extras);
    frame.source = f.path.string();
    frame.T_world_sensor = pcdViewpointPose(extras.viewpoint, frame.source);
    if (!frame.T_world_sensor.isApprox(f.T_world_sensor)) {
      throw DataError(frame.source + ": its VIEWPOINT changed since the sequence was opened");
    }
    const Eigen::Isometry3f T_sensor_world = f.T_world_sensor.inverse().cast<float>();
    for (Eigen::Vector3f& p : frame.cloud.points) p = T_sensor_world * p;
    frame.timestamp_s = static_cast<double>(i);
    return frame;
  }

 private:
  std::vector<PosedCloud> frames_;
};

bool isDynamicMap(const fs::path& root) {
  std::error_code ec;
  if (!fs::is_directory(root / "pcd", ec)) return false;
  for (const auto& e : fs::directory_iterator(root / "pcd", ec)) {
    if (e.path().extension() == ".pcd") return true;
  }
  return false;
}

std::unique_ptr<Dataset> openDynamicMap(const fs::path& root, const DatasetSettings&) {
  if (!isDynamicMap(root)) {
    throw UsageError(root.string() + ": a dynamic-map sequence is a folder with pcd/*.pcd frames (points in the "
                     "world frame, the sensor pose in each file's VIEWPOINT)");
  }
  std::vector<PosedCloud> frames;
  for (const fs::path& file : framesOf(root / "pcd")) {
    frames.push_back({file, pcdViewpointPose(readPcdViewpoint(file), file.string())});
  }
  return std::make_unique<DynamicMapDataset>(std::move(frames));
}

}  // namespace

DatasetReader dynamicMap() {
  return {"dynamic-map",
          {"dynamicmap"},
          "dynamic-map benchmark folder: pcd/*.pcd frames in the world frame, the sensor pose in each file's "
          "VIEWPOINT (tx ty tz qw qx qy qz)",
          isDynamicMap,
          openDynamicMap,
          false};
}

}  // namespace chronomap::readers
