#pragma once
// What the image readers (TUM, 3DMatch, ScanNet) and the cloud reader share: the frames they
// list, the datasets that load them, and the checks of their files. Internal to chronomap_ingest.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"

namespace chronomap::readers {

namespace fs = std::filesystem;

/// One RGB-D frame on disk.
struct ImageFrame {
  fs::path depth;
  std::optional<fs::path> colour;
  Eigen::Isometry3d pose;
  double timestamp_s = 0.0;
};

/// Median depths outside this range (metres) mean the depth scale is wrong, typically by a
/// factor of 1000 (millimetres read as metres or the reverse).
constexpr double kPlausibleMedianDepthMin_m = 0.02;
constexpr double kPlausibleMedianDepthMax_m = 50.0;

class ImageDataset : public Dataset {
 public:
  ImageDataset(std::string format, std::vector<ImageFrame> frames, CameraIntrinsics k, double scale, size_t dropped,
               std::optional<CameraIntrinsics> colour_k = std::nullopt, bool colour = true,
               std::shared_ptr<DepthImageCache> depth_cache = nullptr, bool timestamps_are_times = false)
      : format_(std::move(format)),
        frames_(std::move(frames)),
        k_(k),
        scale_(scale),
        dropped_(dropped),
        colour_k_(colour_k),
        colour_(colour),
        depth_cache_(std::move(depth_cache)),
        timestamps_are_times_(timestamps_are_times) {}
  size_t size() const override { return frames_.size(); }
  std::string format() const override { return format_; }
  std::optional<double> recordedAt() const override {
    if (!timestamps_are_times_ || frames_.empty()) return std::nullopt;
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
    if (f.colour && colour_) rgb = readColourImage(*f.colour);
    // A colour camera with intrinsics of its own (ScanNet): looked up along each depth ray.
    if (rgb && colour_k_) rgb = colourInDepthView(*rgb, *colour_k_, k_, depth.width, depth.height);
    Frame frame;
    frame.source = f.depth.string();
    frame.cloud = depthToCloud(depth, rgb ? &*rgb : nullptr, k_, scale_, frame.source);
    frame.T_world_sensor = f.pose;
    frame.timestamp_s = f.timestamp_s;
    return frame;
  }

 private:
  std::string format_;
  std::vector<ImageFrame> frames_;
  CameraIntrinsics k_;
  double scale_;
  size_t dropped_;
  std::optional<CameraIntrinsics> colour_k_;
  bool colour_;
  std::shared_ptr<DepthImageCache> depth_cache_;
  bool timestamps_are_times_;  // the frames\' timestamps are seconds since the epoch (TUM)
};

class CloudDataset : public Dataset {
 public:
  struct Item {
    fs::path path;
    Eigen::Isometry3d pose;
  };
  explicit CloudDataset(std::vector<Item> items) : items_(std::move(items)) {}
  size_t size() const override { return items_.size(); }
  std::string format() const override { return "clouds"; }
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

/// The depth scale of the settings, or the format's `fallback`. @throw UsageError when not positive.
double checkedScale(const DatasetSettings& o, double fallback);
/// @throw DataError naming `p` when it is not a regular file.
void requireFile(const fs::path& p, const std::string& what);
/// A 4x4 matrix from a text file. @throw FormatError naming the file.
Eigen::Matrix4d readMatrix4(const fs::path& path);

}  // namespace chronomap::readers
