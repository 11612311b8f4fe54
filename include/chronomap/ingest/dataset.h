#pragma once
/// @file
/// Datasets: folders and files of RGB-D frames with poses, in common layouts.

#include <atomic>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "chronomap/core/camera.h"
#include "chronomap/core/frame.h"
#include "chronomap/core/image.h"

namespace chronomap {

/// The canonical name of the reader that `name` (a reader's name or alias, or "auto") stands
/// for, as registered (ingest/registry.h): "7scenes" gives "3dmatch", "auto" stays "auto".
/// @throw UsageError for a name no registered reader has, listing the names there are.
std::string parseDatasetFormat(const std::string& name);

/// Parses "fx,fy,cx,cy". @throw UsageError.
CameraIntrinsics parseIntrinsics(const std::string& text);
/// Reads a 3x3 K matrix, or one line "fx fy cx cy". @throw FormatError naming the file.
CameraIntrinsics readIntrinsicsFile(const std::filesystem::path& path);

/// The text formats inside datasets, parsed from memory; `source` names the file in messages.
/// Each throws FormatError (or DataError for impossible poses) naming source and line.
CameraIntrinsics parseIntrinsicsText(const std::string& text, const std::string& source);
/// A 4x4 row-major matrix (3DMatch pose files).
Eigen::Matrix4d parseMatrix4(const std::string& text, const std::string& source);

/// A line "timestamp name" of a TUM rgb.txt or depth.txt.
struct StampedName {
  double t;
  std::string name;
};
/// TUM rgb.txt / depth.txt, sorted by time.
std::vector<StampedName> parseStampedList(const std::string& text, const std::string& source);

/// A line "timestamp tx ty tz qx qy qz qw" of a TUM trajectory.
struct StampedPose {
  double t;
  Eigen::Isometry3d pose;
};
/// TUM groundtruth.txt / trajectory.txt, sorted by time.
std::vector<StampedPose> parseTumTrajectory(const std::string& text, const std::string& source);

/// A line "cloud tx ty tz qx qy qz qw" of a cloud list, the path as written.
struct CloudListEntry {
  std::filesystem::path cloud;
  Eigen::Isometry3d pose;
  std::string source;  ///< "file:line"
};
std::vector<CloudListEntry> parseCloudList(const std::string& text, const std::string& source);

/// Which topics and frames of a ROS bag make the frames. Empty topics are detected from the bag
/// when only one topic fits; an ambiguous bag is refused with the candidates named.
struct BagSettings {
  std::string depth_topic;  ///< sensor_msgs/Image, 16UC1 (millimetres) or 32FC1 (metres)
  std::string colour_topic;  ///< sensor_msgs/Image, rgb8, bgr8, mono8, rgba8 or bgra8; "none": no colour
  std::string info_topic;   ///< sensor_msgs/CameraInfo of the depth camera (default: beside the depth topic)
  std::string cloud_topic;  ///< sensor_msgs/PointCloud2, read instead of depth images
  /// nav_msgs/Odometry or geometry_msgs/PoseStamped: the sensor's pose in the map frame (an
  /// odometry's child frame is carried to the sensor's frame through /tf when they differ).
  std::string pose_topic;
  /// Poses from /tf and /tf_static: the sensor frame (each message's header) in this frame.
  std::string fixed_frame;
  /// Largest time between a frame and the pose samples it is interpolated from (seconds).
  double pose_tolerance_s = 0.1;
};

/// Decoded depth images kept between passes over the same recordings (registration reads every
/// frame up to eight times), within a budget of bytes; shared by the datasets opened with it
/// (DatasetSettings::depth_cache) and safe from several threads. An image is kept when it still
/// fits and is never dropped: a pass over more frames than fit then still finds the first ones
/// kept (a cache that dropped the oldest would find none in passes that read every frame in turn).
/// Keyed by the image file's path: share one cache only among datasets with the same depth scale.
class DepthImageCache {
 public:
  explicit DepthImageCache(size_t budget_bytes) : budget_(budget_bytes) {}
  /// The image kept for `path`, or null.
  std::shared_ptr<const ImageU16> find(const std::filesystem::path& path) const;
  /// Keeps `image` for `path` when its bytes fit in what is left of the budget (and none is kept
  /// for it yet). @return whether it is kept now.
  bool keep(const std::filesystem::path& path, std::shared_ptr<const ImageU16> image);
  /// The bytes an image takes in the cache: its pixels, its path and the bookkeeping.
  static size_t bytesOf(const std::filesystem::path& path, const ImageU16& image);
  size_t budget_bytes() const { return budget_; }
  size_t bytes() const;   ///< of the kept images, never above budget_bytes()
  size_t images() const;  ///< kept
  size_t hits() const { return hits_; }  ///< find() calls that found an image
  /// Drops every image kept (the budget stays; the hits are still counted).
  void clear();

 private:
  size_t budget_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, std::shared_ptr<const ImageU16>> images_;
  size_t bytes_ = 0;
  mutable std::atomic<size_t> hits_{0};
};

/// Settings of openDataset; unset values take the format's defaults.
struct DatasetSettings {
  /// A registered reader's name or alias ("tum", "3dmatch", ...), or "auto": detect from the path.
  std::string format = "auto";
  /// Depth image units per metre (TUM: 5000, 3DMatch: 1000).
  std::optional<double> depth_scale;
  /// Overrides the intrinsics file of the dataset (TUM default: 525, 525, 319.5, 239.5).
  std::optional<CameraIntrinsics> intrinsics;
  /// Pose of a single cloud (default: identity).
  std::optional<Eigen::Isometry3d> pose;
  /// TUM: pose file to use instead of trajectory.txt or groundtruth.txt.
  std::optional<std::filesystem::path> trajectory;
  /// TUM: largest time difference accepted when associating depth, colour and pose; ROS bags:
  /// between depth and colour.
  double max_time_difference_s = 0.02;
  /// ROS bags: topics and frames.
  BagSettings bag;
  /// False: image datasets (TUM, 3DMatch, ScanNet) leave the colour images unread and give
  /// frames without colours (the same points), for passes that need only the geometry.
  bool colour = true;
  /// Image datasets (TUM, 3DMatch, ScanNet): decoded depth images are looked up here before a
  /// file is read, and kept here when they fit (the same frames as without it).
  std::shared_ptr<DepthImageCache> depth_cache;
  /// Turns the recording's world frame: every pose T_world_sensor becomes R * T_world_sensor (its
  /// points with it), so that a recording whose up is another axis is read with z up
  /// (align/up_axis.h's uprightRotation). None: the frame as recorded. A proper rotation.
  std::optional<Eigen::Matrix3d> world_rotation;
};

/// Frames of one recording. load() reads and decodes one frame; safe from several threads.
class Dataset : public FrameSource {
 public:
  /// The name of the reader that read it ("tum", "3dmatch", "rosbag", ...).
  virtual std::string format() const = 0;
  /// Frames listed but left out (no colour or pose within the time tolerance).
  virtual size_t framesDropped() const { return 0; }
  /// Why frames were left out, for people ("12 without a pose within 0.1 s"); empty when none were.
  virtual std::string droppedReasons() const { return {}; }
  /// When the recording started (seconds since the epoch), if its files say so: the first
  /// frame's timestamp of a TUM folder. Nothing for formats without times.
  virtual std::optional<double> recordedAt() const { return std::nullopt; }
};

/// Opens a dataset folder or file. Reads every index and pose file now (and checks them), and
/// images only when frames are loaded.
/// @throw UsageError when the path does not exist or the format cannot be detected;
///        DataError / FormatError naming the file at fault for malformed input or no frames.
std::unique_ptr<Dataset> openDataset(const std::filesystem::path& path, const DatasetSettings& options = {});

/// The colour image as the depth camera sees it: for every depth pixel (width x height, depth
/// intrinsics), the colour pixel on the same ray through the colour intrinsics (the cameras
/// share their centre and axes, as in ScanNet's export), nearest neighbour; black where the
/// ray leaves the colour image.
ImageRgb colourInDepthView(const ImageRgb& colour, const CameraIntrinsics& colour_k, const CameraIntrinsics& depth_k,
                          uint32_t width, uint32_t height);

/// Back-projects a depth image into an organized cloud in the camera frame (x right, y down,
/// z forward). Zero depth becomes NaN. `rgb` may be null; otherwise it must match in size.
/// @throw DataError naming `source` for mismatched sizes or a bad scale.
PointCloud depthToCloud(const ImageU16& depth, const ImageRgb* rgb, const CameraIntrinsics& k, double depth_scale,
                        const std::string& source);

}  // namespace chronomap
