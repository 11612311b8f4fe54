// TUM RGB-D folders: depth.txt and rgb.txt list timestamped images, trajectory.txt or
// groundtruth.txt timestamped poses; frames are associated by nearest timestamp.

#include <algorithm>
#include <cmath>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/core/pose.h"
#include "image_dataset.h"
#include "readers.h"
#include "stamped.h"
#include "text_util.h"

namespace chronomap {

std::vector<StampedName> parseStampedList(const std::string& text, const std::string& name) {
  std::vector<StampedName> out;
  for (const auto& [number, line] : contentLines(text)) {
    const auto tok = splitWhitespace(line);
    const std::string ctx = name + ":" + std::to_string(number);
    if (tok.size() != 2) throw FormatError(ctx + ": expected 'timestamp filename'");
    const double t = parseDouble(tok[0], ctx);
    if (!std::isfinite(t)) throw FormatError(ctx + ": timestamp is not finite");
    out.push_back({t, tok[1]});
  }
  std::stable_sort(out.begin(), out.end(), [](const StampedName& a, const StampedName& b) { return a.t < b.t; });
  return out;
}

std::vector<StampedPose> parseTumTrajectory(const std::string& text, const std::string& name) {
  std::vector<StampedPose> out;
  for (const auto& [number, line] : contentLines(text)) {
    const auto tok = splitWhitespace(line);
    const std::string ctx = name + ":" + std::to_string(number);
    if (tok.size() != 8) throw FormatError(ctx + ": expected 'timestamp tx ty tz qx qy qz qw'");
    double v[8];
    for (int i = 0; i < 8; ++i) v[i] = parseDouble(tok[static_cast<size_t>(i)], ctx);
    if (!std::isfinite(v[0])) throw FormatError(ctx + ": timestamp is not finite");
    out.push_back({v[0], poseFromTranslationQuaternion({v[1], v[2], v[3]}, v[4], v[5], v[6], v[7], ctx)});
  }
  std::stable_sort(out.begin(), out.end(), [](const StampedPose& a, const StampedPose& b) { return a.t < b.t; });
  return out;
}

namespace readers {

namespace {

std::unique_ptr<Dataset> openTum(const fs::path& root, const DatasetSettings& o) {
  std::error_code ec;
  const fs::path depth_list = root / "depth.txt";
  requireFile(depth_list, "TUM depth list (depth.txt)");
  fs::path traj;
  if (o.trajectory) {
    traj = *o.trajectory;
    requireFile(traj, "trajectory file");
  } else if (fs::exists(root / "trajectory.txt", ec)) {
    traj = root / "trajectory.txt";
  } else if (fs::exists(root / "groundtruth.txt", ec)) {
    traj = root / "groundtruth.txt";
  } else {
    throw DataError(root.string() + ": no trajectory.txt or groundtruth.txt (give one with --trajectory)");
  }
  CameraIntrinsics k;
  if (o.intrinsics) {
    k = *o.intrinsics;
  } else {
    for (const char* name : {"camera-intrinsics.txt", "intrinsics.txt"}) {
      if (fs::exists(root / name, ec)) {
        k = readIntrinsicsFile(root / name);
        break;
      }
    }
  }
  const auto depths = parseStampedList(readTextFile(depth_list), depth_list.string());
  std::vector<StampedName> colours;
  const bool have_rgb = fs::exists(root / "rgb.txt", ec);
  if (have_rgb) colours = parseStampedList(readTextFile(root / "rgb.txt"), (root / "rgb.txt").string());
  const auto poses = parseTumTrajectory(readTextFile(traj), traj.string());
  if (poses.empty()) throw DataError(traj.string() + ": no poses");
  std::vector<ImageFrame> frames;
  size_t dropped = 0;
  for (const StampedName& d : depths) {
    const StampedPose* pose = nearestInTime(poses, d.t, o.max_time_difference_s);
    const StampedName* colour = have_rgb ? nearestInTime(colours, d.t, o.max_time_difference_s) : nullptr;
    if (!pose || (have_rgb && !colour)) {
      ++dropped;
      continue;
    }
    ImageFrame f;
    f.depth = root / d.name;
    if (colour) f.colour = root / colour->name;
    f.pose = pose->pose;
    f.timestamp_s = d.t;
    frames.push_back(f);
  }
  if (frames.empty()) {
    throw DataError(root.string() + ": none of the " + std::to_string(depths.size()) +
                    " depth frames has a pose (and colour) within " + std::to_string(o.max_time_difference_s) + " s");
  }
  return std::make_unique<ImageDataset>("tum", std::move(frames), k, checkedScale(o, 5000.0), dropped,
                                        std::nullopt, o.colour, o.depth_cache, true);
}

bool isTum(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec) && fs::exists(path / "depth.txt", ec);
}

std::unique_ptr<Dataset> openTumChecked(const fs::path& root, const DatasetSettings& o) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw UsageError(root.string() + ": a TUM dataset is a folder");
  return openTum(root, o);
}

}  // namespace

DatasetReader tum() {
  return {"tum", {}, "TUM RGB-D folder: depth.txt (rgb.txt optional), trajectory.txt or groundtruth.txt", isTum,
          openTumChecked};
}

}  // namespace readers

}  // namespace chronomap
