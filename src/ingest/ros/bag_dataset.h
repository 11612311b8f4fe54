#pragma once
// What the ROS 1 and ROS 2 bag readers share (internal): the topics a bag's frames come from
// (given or detected), the messages one pass over the bag gathers, and the dataset that pairs
// depth with colour and poses and decodes the frames through ros_messages.h. Each reader only
// stores and deserialises messages: librosbag for ROS 1, MCAP or SQLite with CDR for ROS 2.

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/transform_tree.h"
#include "ros_messages.h"

namespace chronomap::bag {

/// Message types, by their ROS 1 names (a ROS 2 reader maps "sensor_msgs/msg/Image" to these).
inline constexpr const char* kImage = "sensor_msgs/Image";
inline constexpr const char* kCompressedImage = "sensor_msgs/CompressedImage";
inline constexpr const char* kCameraInfo = "sensor_msgs/CameraInfo";
inline constexpr const char* kPointCloud2 = "sensor_msgs/PointCloud2";
inline constexpr const char* kTfMessage = "tf2_msgs/TFMessage";
inline constexpr const char* kOdometry = "nav_msgs/Odometry";
inline constexpr const char* kPoseStamped = "geometry_msgs/PoseStamped";
/// Millimetres, as REP 118 stores 16UC1 depth.
inline constexpr double kDefaultDepthScale = 1000.0;

/// One topic: its type (ROS 1 name), message count and, for images, the first message's
/// encoding (a CompressedImage's format) and frame.
struct TopicInfo {
  std::string type;
  uint64_t messages = 0;
  std::string encoding;
  std::string frame_id;
};
using TopicMap = std::map<std::string, TopicInfo>;

/// A tf frame name without the leading slash some old recorders wrote.
std::string frameName(std::string_view id);
/// "a, b, c".
std::string joinNames(const std::vector<std::string>& names);

/// The topics a bag's frames come from, as given or detected.
struct Topics {
  std::string depth;  ///< depth images, or
  std::string cloud;  ///< point clouds
  std::string colour;
  std::string info;
  std::string colour_info;
  std::string pose;  ///< empty: /tf and /tf_static
  /// The depth or colour topic holds sensor_msgs/CompressedImage (compressedDepth, JPEG or PNG).
  bool depth_compressed = false, colour_compressed = false;
};

/// The topics for `s`: named ones checked, the others detected when only one fits.
/// @throw UsageError for a missing, mistyped or ambiguous topic; DataError when none fits.
Topics chooseTopics(const TopicMap& topics, const BagSettings& s, const std::filesystem::path& path);

/// A message with its header's time and frame; `message` is the reader's own handle.
struct Stamped {
  double t = 0.0;
  uint64_t message = 0;
  std::string frame_id;
};

/// The poses of a pose topic: the trajectory and the frame it gives the pose of.
struct PoseTrack {
  std::vector<TimedPose> poses;
  std::string child_frame;  ///< nav_msgs/Odometry's child frame; empty: the sensor's
};

/// The camera matrix of a CameraInfo, checked. @throw DataError naming `context`.
CameraIntrinsics intrinsicsOf(const double (&k)[9], const std::string& context);

/// What one pass over a bag gathers for the chosen topics.
struct Gathered {
  std::vector<Stamped> depths, colours;  ///< the frames' messages (depth images or clouds) and colour images
  TransformTree tree;                   ///< /tf and /tf_static
  std::optional<PoseTrack> track;       ///< the pose topic's poses, when there is one
  std::optional<CameraIntrinsics> k, colour_k;  ///< the first CameraInfo of each info topic
  uint32_t info_width = 0, info_height = 0;     ///< the image size the depth CameraInfo states (0: none)
  std::string info_topic;                       ///< where it came from, for messages
};

/// A decoded message with what keeps its bytes alive: a sensor_msgs/Image (`view`) or a
/// sensor_msgs/CompressedImage (`compressed`).
struct ImageMessage {
  rosmsg::ImageView view;
  std::optional<rosmsg::CompressedView> compressed;
  std::shared_ptr<const void> owner;
};
struct CloudMessage {
  rosmsg::CloudView view;
  std::shared_ptr<const void> owner;
};

/// A bag as a dataset: frames paired with colour and poses by stamp; the reader decodes one
/// stored message at a time.
class BagDataset : public Dataset {
 public:
  size_t size() const override { return frames_.size(); }
  std::string format() const override { return format_; }
  size_t framesDropped() const override { return without_pose_ + without_colour_; }
  std::string droppedReasons() const override;
  std::optional<double> recordedAt() const override;
  Eigen::Isometry3d poseOf(size_t i) const override { return frames_.at(i).pose; }
  Frame load(size_t i) const override;

 protected:
  BagDataset(const std::filesystem::path& path, std::string format) : path_(path), format_(std::move(format)) {}
  /// Pairs what the reader's pass gathered into frames. @throw DataError when no frame is left
  /// or the depth camera has no intrinsics.
  void assemble(const Topics& t, const DatasetSettings& s, Gathered g);
  /// What the storage could not read (a file cut short), said with the dropped frames.
  void noteWhatWasLost(std::string note) { lost_ = std::move(note); }
  /// The message behind a handle of Stamped::message, decoded (a CompressedImage when
  /// `compressed`). @throw Error naming the bag.
  virtual ImageMessage image(uint64_t message, bool compressed) const = 0;
  virtual CloudMessage cloud(uint64_t message) const = 0;

  std::filesystem::path path_;

 private:
  struct Pair {
    uint64_t depth = 0;
    std::optional<uint64_t> colour;
    Eigen::Isometry3d pose;
    double t = 0.0;
  };
  /// @throw DataError when the depth CameraInfo states another image size than the image's.
  void checkInfoSize(uint32_t width, uint32_t height, const std::string& source) const;
  std::optional<Eigen::Isometry3d> poseAt(const Stamped& d, const TransformTree& tree,
                                          const std::optional<PoseTrack>& track, const BagSettings& s) const;

  std::string format_;
  std::vector<Pair> frames_;
  bool cloud_ = false;
  bool depth_compressed_ = false, colour_compressed_ = false;
  std::string depth_topic_, cloud_topic_, colour_topic_;
  CameraIntrinsics k_;
  std::optional<CameraIntrinsics> colour_k_;
  uint32_t info_width_ = 0, info_height_ = 0;  ///< the depth CameraInfo's image size, when k_ came from it
  std::string info_topic_;
  double depth_scale_ = kDefaultDepthScale;
  double pose_tolerance_s_ = 0.0, colour_tolerance_s_ = 0.0;
  size_t without_pose_ = 0, without_colour_ = 0;
  std::string lost_;
};

}  // namespace chronomap::bag
