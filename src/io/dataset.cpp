#include "chronomap/io/dataset.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "chronomap/io/cloud_io.h"
#include "chronomap/io/file.h"
#include "chronomap/io/jpeg.h"
#include "chronomap/io/png.h"
#include "rosbag1.h"
#include "rosbag2.h"
#include "stamped.h"
#include "text_util.h"

namespace chronomap::io {

namespace fs = std::filesystem;

const char* toString(DatasetFormat format) {
  switch (format) {
    case DatasetFormat::Auto: return "auto";
    case DatasetFormat::Tum: return "tum";
    case DatasetFormat::ThreeDMatch: return "3dmatch";
    case DatasetFormat::Clouds: return "clouds";
    case DatasetFormat::ScanNet: return "scannet";
    case DatasetFormat::RosBag: return "rosbag";
    case DatasetFormat::Ros2Bag: return "ros2bag";
  }
  return "unknown";
}

DatasetFormat parseDatasetFormat(const std::string& name) {
  if (name == "auto") return DatasetFormat::Auto;
  if (name == "tum") return DatasetFormat::Tum;
  if (name == "3dmatch" || name == "7scenes") return DatasetFormat::ThreeDMatch;
  if (name == "clouds") return DatasetFormat::Clouds;
  if (name == "scannet") return DatasetFormat::ScanNet;
  if (name == "rosbag" || name == "bag") return DatasetFormat::RosBag;
  if (name == "ros2bag" || name == "mcap" || name == "db3") return DatasetFormat::Ros2Bag;
  throw UsageError("unknown dataset format '" + name +
                   "' (expected auto, tum, 3dmatch, scannet, clouds, rosbag or ros2bag)");
}

CameraIntrinsics parseIntrinsics(const std::string& text) {
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  const auto tok = splitWhitespace(s);
  if (tok.size() != 4) throw UsageError("intrinsics '" + text + "' must be four numbers: fx,fy,cx,cy");
  CameraIntrinsics k;
  try {
    k = {parseDouble(tok[0], "fx"), parseDouble(tok[1], "fy"), parseDouble(tok[2], "cx"), parseDouble(tok[3], "cy")};
  } catch (const FormatError& e) {
    throw UsageError(std::string("intrinsics: ") + e.what());
  }
  if (!(k.fx > 0 && k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy) || !std::isfinite(k.cx) ||
      !std::isfinite(k.cy)) {
    throw UsageError("intrinsics '" + text + "': focal lengths must be positive and all values finite");
  }
  return k;
}

CameraIntrinsics readIntrinsicsFile(const fs::path& path) {
  return parseIntrinsicsText(readTextFile(path), path.string());
}

CameraIntrinsics parseIntrinsicsText(const std::string& text, const std::string& name) {
  std::vector<double> v;
  for (const auto& [number, line] : contentLines(text)) {
    for (const auto& t : splitWhitespace(line)) v.push_back(parseDouble(t, name + ":" + std::to_string(number)));
  }
  CameraIntrinsics k;
  if (v.size() == 9) {
    k = {v[0], v[4], v[2], v[5]};
  } else if (v.size() == 16) {  // a 4x4 projection (ScanNet's intrinsic_*.txt)
    k = {v[0], v[5], v[2], v[6]};
  } else if (v.size() == 4) {
    k = {v[0], v[1], v[2], v[3]};
  } else {
    throw FormatError(name + ": expected a 3x3 matrix or 'fx fy cx cy', found " + std::to_string(v.size()) + " numbers");
  }
  if (!(k.fx > 0 && k.fy > 0) || !std::isfinite(k.cx) || !std::isfinite(k.cy)) {
    throw FormatError(name + ": focal lengths must be positive and all values finite");
  }
  return k;
}

ImageRgb colorInDepthView(const ImageRgb& color, const CameraIntrinsics& color_k, const CameraIntrinsics& depth_k,
                          uint32_t width, uint32_t height) {
  ImageRgb out{width, height, std::vector<Rgb>(size_t{width} * height, Rgb{0, 0, 0})};
  // A ray's colour pixel does not depend on its depth: u_c = fx_c * (u - cx) / fx + cx_c.
  std::vector<int64_t> columns(width), rows(height);
  for (uint32_t u = 0; u < width; ++u) {
    columns[u] = static_cast<int64_t>(std::floor(color_k.fx * (u - depth_k.cx) / depth_k.fx + color_k.cx + 0.5));
  }
  for (uint32_t v = 0; v < height; ++v) {
    rows[v] = static_cast<int64_t>(std::floor(color_k.fy * (v - depth_k.cy) / depth_k.fy + color_k.cy + 0.5));
  }
  for (uint32_t v = 0; v < height; ++v) {
    if (rows[v] < 0 || rows[v] >= color.height) continue;
    for (uint32_t u = 0; u < width; ++u) {
      if (columns[u] < 0 || columns[u] >= color.width) continue;
      const size_t from = static_cast<size_t>(rows[v]) * color.width + static_cast<size_t>(columns[u]);
      out.pixels[size_t{v} * width + u] = color.pixels[from];
    }
  }
  return out;
}

std::shared_ptr<const ImageU16> DepthImageCache::find(const std::filesystem::path& path) const {
  std::shared_ptr<const ImageU16> found;
  {
    const std::lock_guard lock(mutex_);
    const auto it = images_.find(path.string());
    if (it != images_.end()) found = it->second;
  }
  if (found) ++hits_;
  return found;
}

bool DepthImageCache::keep(const std::filesystem::path& path, std::shared_ptr<const ImageU16> image) {
  if (!image) return false;
  const size_t need = bytesOf(path, *image);
  const std::lock_guard lock(mutex_);
  if (need > budget_ - bytes_) return false;
  if (!images_.try_emplace(path.string(), std::move(image)).second) return false;
  bytes_ += need;
  return true;
}

size_t DepthImageCache::bytesOf(const std::filesystem::path& path, const ImageU16& image) {
  // The pixels, the key, the image and its node in the table (two pointers and a hash), and the
  // shared pointer's control block.
  constexpr size_t kOverhead = sizeof(ImageU16) + sizeof(std::string) + 3 * sizeof(void*) + 32;
  return image.pixels.size() * sizeof(uint16_t) + path.native().size() + kOverhead;
}

size_t DepthImageCache::bytes() const {
  const std::lock_guard lock(mutex_);
  return bytes_;
}

void DepthImageCache::clear() {
  const std::lock_guard lock(mutex_);
  images_ = {};
  bytes_ = 0;
}

size_t DepthImageCache::images() const {
  const std::lock_guard lock(mutex_);
  return images_.size();
}

PointCloud depthToCloud(const ImageU16& depth, const ImageRgb* rgb, const CameraIntrinsics& k, double depth_scale,
                        const std::string& source) {
  if (!(depth_scale > 0.0) || !std::isfinite(depth_scale)) {
    throw DataError(source + ": depth scale must be a positive number of units per metre");
  }
  if (rgb && (rgb->width != depth.width || rgb->height != depth.height)) {
    std::ostringstream msg;
    msg << source << ": colour image is " << rgb->width << "x" << rgb->height << " but the depth image is "
        << depth.width << "x" << depth.height;
    throw DataError(msg.str());
  }
  PointCloud cloud;
  cloud.width = depth.width;
  cloud.height = depth.height;
  const size_t n = size_t{depth.width} * depth.height;
  cloud.points.resize(n);
  if (rgb) cloud.colors = rgb->pixels;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const double inv_scale = 1.0 / depth_scale;
  // Each column's offset from the principal point, the same double the per-pixel expression
  // (u - cx) * z / fx computes first: the same points, bit for bit.
  std::vector<double> columns(depth.width);
  for (uint32_t u = 0; u < depth.width; ++u) columns[u] = u - k.cx;
  for (uint32_t v = 0; v < depth.height; ++v) {
    const double row = v - k.cy;
    const uint16_t* line = depth.pixels.data() + size_t{v} * depth.width;
    Eigen::Vector3f* out = cloud.points.data() + size_t{v} * depth.width;
    for (uint32_t u = 0; u < depth.width; ++u) {
      const uint16_t d = line[u];
      if (d == 0) {
        out[u] = Eigen::Vector3f(nan, nan, nan);
        continue;
      }
      const double z = d * inv_scale;
      out[u] = Eigen::Vector3f(toFloat(columns[u] * z / k.fx), toFloat(row * z / k.fy), toFloat(z));
    }
  }
  return cloud;
}

namespace {

/// One RGB-D frame on disk.
struct ImageFrame {
  fs::path depth;
  std::optional<fs::path> color;
  Eigen::Isometry3d pose;
  double timestamp_s = 0.0;
};

/// Median depths outside this range (metres) mean the depth scale is wrong, typically by a
/// factor of 1000 (millimetres read as metres or the reverse).
constexpr double kPlausibleMedianDepthMin_m = 0.02;
constexpr double kPlausibleMedianDepthMax_m = 50.0;

class ImageDataset : public Dataset {
 public:
  ImageDataset(DatasetFormat format, std::vector<ImageFrame> frames, CameraIntrinsics k, double scale, size_t dropped,
               std::optional<CameraIntrinsics> color_k = std::nullopt, bool colour = true,
               std::shared_ptr<DepthImageCache> depth_cache = nullptr)
      : format_(format),
        frames_(std::move(frames)),
        k_(k),
        scale_(scale),
        dropped_(dropped),
        color_k_(color_k),
        colour_(colour),
        depth_cache_(std::move(depth_cache)) {}
  size_t size() const override { return frames_.size(); }
  DatasetFormat format() const override { return format_; }
  std::optional<double> recordedAt() const override {
    if (format_ != DatasetFormat::Tum || frames_.empty()) return std::nullopt;
    return frames_.front().timestamp_s;
  }
  size_t framesDropped() const override { return dropped_; }
  Eigen::Isometry3d poseOf(size_t i) const override { return frames_.at(i).pose; }

  /// @throw DataError when the frame's median depth at this scale is not plausible.
  void checkDepthScale(const ImageU16& depth, const std::string& source) const {
    // About 4,000 samples are enough for a median.
    const size_t step = std::max<size_t>(1, depth.pixels.size() / 4096);
    std::vector<uint16_t> valid;
    valid.reserve(depth.pixels.size() / step + 1);
    for (size_t i = 0; i < depth.pixels.size(); i += step) {
      if (depth.pixels[i] != 0) valid.push_back(depth.pixels[i]);
    }
    if (valid.empty()) return;
    std::nth_element(valid.begin(), valid.begin() + static_cast<long>(valid.size() / 2), valid.end());
    const double median_m = valid[valid.size() / 2] / scale_;
    if (median_m < kPlausibleMedianDepthMin_m || median_m > kPlausibleMedianDepthMax_m) {
      std::ostringstream msg;
      msg << source << ": median depth is " << median_m << " m at a depth scale of " << scale_
          << " units per metre; the scale looks wrong (set it with --depth-scale)";
      throw DataError(msg.str());
    }
  }

  Frame load(size_t i) const override {
    const ImageFrame& f = frames_.at(i);
    std::shared_ptr<const ImageU16> kept = depth_cache_ ? depth_cache_->find(f.depth) : nullptr;
    if (!kept) {
      auto read = std::make_shared<ImageU16>(readPngU16(f.depth));
      checkDepthScale(*read, f.depth.string());
      kept = std::move(read);
      if (depth_cache_) depth_cache_->keep(f.depth, kept);
    }
    const ImageU16& depth = *kept;
    std::optional<ImageRgb> rgb;
    if (f.color && colour_) rgb = readColorImage(*f.color);
    // A colour camera with intrinsics of its own (ScanNet): looked up along each depth ray.
    if (rgb && color_k_) rgb = colorInDepthView(*rgb, *color_k_, k_, depth.width, depth.height);
    Frame frame;
    frame.source = f.depth.string();
    frame.cloud = depthToCloud(depth, rgb ? &*rgb : nullptr, k_, scale_, frame.source);
    frame.T_world_sensor = f.pose;
    frame.timestamp_s = f.timestamp_s;
    return frame;
  }

 private:
  DatasetFormat format_;
  std::vector<ImageFrame> frames_;
  CameraIntrinsics k_;
  double scale_;
  size_t dropped_;
  std::optional<CameraIntrinsics> color_k_;
  bool colour_;
  std::shared_ptr<DepthImageCache> depth_cache_;
};

class CloudDataset : public Dataset {
 public:
  struct Item {
    fs::path path;
    Eigen::Isometry3d pose;
  };
  explicit CloudDataset(std::vector<Item> items) : items_(std::move(items)) {}
  size_t size() const override { return items_.size(); }
  DatasetFormat format() const override { return DatasetFormat::Clouds; }
  Eigen::Isometry3d poseOf(size_t i) const override { return items_.at(i).pose; }
  Frame load(size_t i) const override {
    Frame frame;
    frame.cloud = readCloud(items_.at(i).path);
    frame.T_world_sensor = items_.at(i).pose;
    frame.source = items_.at(i).path.string();
    return frame;
  }

 private:
  std::vector<Item> items_;
};

double checkedScale(const DatasetSettings& o, double fallback) {
  const double s = o.depth_scale.value_or(fallback);
  if (!(s > 0.0) || !std::isfinite(s)) throw UsageError("depth scale must be a positive number of units per metre");
  return s;
}

void requireFile(const fs::path& p, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) throw DataError(p.string() + ": " + what + " is missing");
}

// ---------------------------------------------------------------- 3DMatch / 7-Scenes

/// The frame number of "frame-NNNNNN.depth.png", or -1 for any other name.
long frameNumber(const std::string& name) {
  const std::string prefix = "frame-", suffix = ".depth.png";
  if (name.size() <= prefix.size() + suffix.size() || name.compare(0, prefix.size(), prefix) != 0 ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0) {
    return -1;
  }
  const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return -1;
  return std::stol(digits);
}

std::vector<fs::path> sortedFrames(const fs::path& dir) {
  std::vector<std::pair<long, fs::path>> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    const long n = frameNumber(e.path().filename().string());
    if (n >= 0) found.emplace_back(n, e.path());
  }
  std::sort(found.begin(), found.end());
  std::vector<fs::path> out;
  out.reserve(found.size());
  for (auto& [n, p] : found) out.push_back(p);
  return out;
}

std::vector<fs::path> threeDMatchSequences(const fs::path& root) {
  std::vector<fs::path> seqs;
  if (!sortedFrames(root).empty()) seqs.push_back(root);
  std::vector<fs::path> subdirs;
  for (const auto& e : fs::directory_iterator(root)) {
    if (e.is_directory() && e.path().filename().string().rfind("seq-", 0) == 0) subdirs.push_back(e.path());
  }
  std::sort(subdirs.begin(), subdirs.end());
  for (auto& s : subdirs) {
    if (!sortedFrames(s).empty()) seqs.push_back(s);
  }
  return seqs;
}

Eigen::Matrix4d readMatrix4(const fs::path& path) { return parseMatrix4(readTextFile(path), path.string()); }

}  // namespace

Eigen::Matrix4d parseMatrix4(const std::string& text, const std::string& name) {
  std::vector<double> v;
  for (const auto& [number, line] : contentLines(text)) {
    for (const auto& t : splitWhitespace(line)) v.push_back(parseDouble(t, name + ":" + std::to_string(number)));
  }
  if (v.size() != 16) throw FormatError(name + ": expected a 4x4 matrix, found " + std::to_string(v.size()) + " numbers");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<size_t>(r) * 4 + static_cast<size_t>(c)];
  }
  return m;
}

namespace {

std::unique_ptr<Dataset> openThreeDMatch(const fs::path& root, const DatasetSettings& o) {
  fs::path intrinsics = root / "camera-intrinsics.txt";
  std::error_code ec;
  if (!fs::exists(intrinsics, ec)) intrinsics = root.parent_path() / "camera-intrinsics.txt";
  const CameraIntrinsics k = o.intrinsics ? *o.intrinsics : (requireFile(intrinsics, "camera intrinsics file"),
                                                               readIntrinsicsFile(intrinsics));
  std::vector<ImageFrame> frames;
  for (const auto& seq : threeDMatchSequences(root)) {
    for (const auto& depth : sortedFrames(seq)) {
      const std::string stem = depth.filename().string().substr(0, depth.filename().string().size() - 10);
      const fs::path pose = seq / (stem + ".pose.txt");
      // Colour as PNG or, as 7-Scenes, ScanNet and many copies store it, JPEG.
      fs::path color = seq / (stem + ".color.png");
      if (!fs::exists(color, ec)) color = seq / (stem + ".color.jpg");
      requireFile(pose, "pose file");
      ImageFrame f;
      f.depth = depth;
      if (fs::exists(color, ec)) f.color = color;
      f.pose = poseFromMatrix(readMatrix4(pose), pose.string());
      f.timestamp_s = static_cast<double>(frames.size());
      frames.push_back(f);
    }
  }
  if (frames.empty()) throw DataError(root.string() + ": no frame-*.depth.png files found");
  return std::make_unique<ImageDataset>(DatasetFormat::ThreeDMatch, std::move(frames), k, checkedScale(o, 1000.0), 0,
                                        std::nullopt, o.colour, o.depth_cache);
}

// ---------------------------------------------------------------- ScanNet

/// Files "N.ext" of `dir` (N a whole number), in the order of N.
std::vector<std::pair<long, fs::path>> numberedFiles(const fs::path& dir, const std::string& ext) {
  std::vector<std::pair<long, fs::path>> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() != ext) continue;
    const std::string digits = name.substr(0, name.size() - ext.size());
    if (digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    found.emplace_back(std::stol(digits), e.path());
  }
  std::sort(found.begin(), found.end());
  return found;
}

bool isScanNet(const fs::path& root) {
  std::error_code ec;
  return fs::is_directory(root / "depth", ec) && fs::is_directory(root / "pose", ec) &&
         fs::is_directory(root / "intrinsic", ec);
}

std::unique_ptr<Dataset> openScanNet(const fs::path& root, const DatasetSettings& o) {
  const fs::path depth_k_file = root / "intrinsic" / "intrinsic_depth.txt";
  const fs::path color_k_file = root / "intrinsic" / "intrinsic_color.txt";
  const CameraIntrinsics k = o.intrinsics ? *o.intrinsics : (requireFile(depth_k_file, "depth intrinsics file"),
                                                               readIntrinsicsFile(depth_k_file));
  std::error_code ec;
  const bool has_color = fs::is_directory(root / "color", ec);
  std::optional<CameraIntrinsics> color_k;
  if (has_color) {
    requireFile(color_k_file, "colour intrinsics file");
    color_k = readIntrinsicsFile(color_k_file);
  }
  std::vector<ImageFrame> frames;
  size_t dropped = 0;
  for (const auto& [n, depth] : numberedFiles(root / "depth", ".png")) {
    const fs::path pose = root / "pose" / (std::to_string(n) + ".txt");
    requireFile(pose, "pose file");
    const Eigen::Matrix4d m = readMatrix4(pose);
    // ScanNet marks frames its reconstruction lost with -inf poses: left out and counted.
    if (!m.allFinite()) {
      ++dropped;
      continue;
    }
    ImageFrame f;
    f.depth = depth;
    if (has_color) {
      fs::path color = root / "color" / (std::to_string(n) + ".jpg");
      if (!fs::exists(color, ec)) color = root / "color" / (std::to_string(n) + ".png");
      requireFile(color, "colour frame");
      f.color = color;
    }
    f.pose = poseFromMatrix(m, pose.string());
    f.timestamp_s = static_cast<double>(n);
    frames.push_back(f);
  }
  if (frames.empty()) {
    throw DataError(root.string() + ": no depth/N.png frame with a valid pose (" + std::to_string(dropped) +
                    " with invalid poses)");
  }
  return std::make_unique<ImageDataset>(DatasetFormat::ScanNet, std::move(frames), k, checkedScale(o, 1000.0), dropped,
                                        color_k, o.colour, o.depth_cache);
}

// ---------------------------------------------------------------- TUM RGB-D

}  // namespace

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
  std::vector<StampedName> colors;
  const bool have_rgb = fs::exists(root / "rgb.txt", ec);
  if (have_rgb) colors = parseStampedList(readTextFile(root / "rgb.txt"), (root / "rgb.txt").string());
  const auto poses = parseTumTrajectory(readTextFile(traj), traj.string());
  if (poses.empty()) throw DataError(traj.string() + ": no poses");
  std::vector<ImageFrame> frames;
  size_t dropped = 0;
  for (const StampedName& d : depths) {
    const StampedPose* pose = nearestInTime(poses, d.t, o.max_time_difference_s);
    const StampedName* color = have_rgb ? nearestInTime(colors, d.t, o.max_time_difference_s) : nullptr;
    if (!pose || (have_rgb && !color)) {
      ++dropped;
      continue;
    }
    ImageFrame f;
    f.depth = root / d.name;
    if (color) f.color = root / color->name;
    f.pose = pose->pose;
    f.timestamp_s = d.t;
    frames.push_back(f);
  }
  if (frames.empty()) {
    throw DataError(root.string() + ": none of the " + std::to_string(depths.size()) +
                    " depth frames has a pose (and colour) within " + std::to_string(o.max_time_difference_s) + " s");
  }
  return std::make_unique<ImageDataset>(DatasetFormat::Tum, std::move(frames), k, checkedScale(o, 5000.0), dropped,
                                        std::nullopt, o.colour, o.depth_cache);
}

// ---------------------------------------------------------------- clouds

std::unique_ptr<Dataset> openClouds(const fs::path& path, const DatasetSettings& o) {
  if (isCloudFile(path)) {
    return std::make_unique<CloudDataset>(
        std::vector<CloudDataset::Item>{{path, o.pose.value_or(Eigen::Isometry3d::Identity())}});
  }
  if (o.pose) throw UsageError("--pose applies to a single cloud file, not to a list");
  std::vector<CloudDataset::Item> items;
  const std::string name = path.string();
  for (auto& entry : parseCloudList(readTextFile(path), name)) {
    fs::path cloud = entry.cloud;
    if (cloud.is_relative()) cloud = path.parent_path() / cloud;
    requireFile(cloud, "cloud listed at " + entry.source);
    items.push_back({cloud, entry.pose});
  }
  if (items.empty()) throw DataError(name + ": the cloud list is empty");
  return std::make_unique<CloudDataset>(std::move(items));
}

}  // namespace

std::vector<CloudListEntry> parseCloudList(const std::string& text, const std::string& name) {
  std::vector<CloudListEntry> out;
  for (const auto& [number, line] : contentLines(text)) {
    const auto tok = splitWhitespace(line);
    const std::string ctx = name + ":" + std::to_string(number);
    if (tok.size() != 8) throw FormatError(ctx + ": expected 'cloud_file tx ty tz qx qy qz qw'");
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = parseDouble(tok[static_cast<size_t>(i) + 1], ctx);
    out.push_back({tok[0], poseFromTranslationQuaternion({v[0], v[1], v[2]}, v[3], v[4], v[5], v[6], ctx), ctx});
  }
  return out;
}

namespace {

DatasetFormat detect(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (fs::exists(path / "depth.txt", ec)) return DatasetFormat::Tum;
    if (fs::exists(path / "metadata.yaml", ec)) return DatasetFormat::Ros2Bag;
    if (!threeDMatchSequences(path).empty()) return DatasetFormat::ThreeDMatch;
    if (isScanNet(path)) return DatasetFormat::ScanNet;
    throw UsageError(path.string() +
                     ": cannot tell the dataset format (no depth.txt, no frame-*.depth.png, no depth/, pose/ and "
                     "intrinsic/ folders); use --format");
  }
  if (isCloudFile(path) || dataExtension(path) == ".txt") return DatasetFormat::Clouds;
  if (path.extension() == ".bag") return DatasetFormat::RosBag;
  if (isRos2Bag(path)) return DatasetFormat::Ros2Bag;
  throw UsageError(path.string() + ": cannot tell the dataset format from the extension; use --format");
}

}  // namespace

std::unique_ptr<Dataset> openDataset(const fs::path& path, const DatasetSettings& options) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file or folder");
  if (options.depth_scale && !(*options.depth_scale > 0.0 && std::isfinite(*options.depth_scale))) {
    throw UsageError("the depth scale must be a positive number of image units per metre, got " +
                     std::to_string(*options.depth_scale));
  }
  DatasetFormat format = options.format == DatasetFormat::Auto ? detect(path) : options.format;
  if (format != DatasetFormat::Clouds && options.pose) {
    throw UsageError("--pose applies to a single cloud file");
  }
  switch (format) {
    case DatasetFormat::Tum:
      if (!fs::is_directory(path, ec)) throw UsageError(path.string() + ": a TUM dataset is a folder");
      return openTum(path, options);
    case DatasetFormat::ThreeDMatch:
      if (!fs::is_directory(path, ec)) throw UsageError(path.string() + ": a 3DMatch dataset is a folder");
      return openThreeDMatch(path, options);
    case DatasetFormat::ScanNet:
      if (!isScanNet(path)) {
        throw UsageError(path.string() + ": a ScanNet export is a folder with depth/, pose/ and intrinsic/");
      }
      return openScanNet(path, options);
    case DatasetFormat::Clouds:
      if (fs::is_directory(path, ec)) {
        throw UsageError(path.string() + ": for clouds give one cloud file or a list file, not a folder");
      }
      return openClouds(path, options);
    case DatasetFormat::RosBag:
      if (fs::is_directory(path, ec)) throw UsageError(path.string() + ": a ROS 1 bag is a file (.bag)");
      return openRosBag(path, options);
    case DatasetFormat::Ros2Bag:
      return openRos2Bag(path, options);
    case DatasetFormat::Auto:
      break;
  }
  throw UsageError("unknown dataset format");
}

}  // namespace chronomap::io
