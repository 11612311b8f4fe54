// ROS 1 bags through Debian's librosbag and the generated message headers of sensor_msgs,
// geometry_msgs, nav_msgs and tf2_msgs. The only file of chronomap that includes ROS headers.

#include "rosbag1.h"
#include "stamped.h"

#include <console_bridge/console.h>
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>

#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "chronomap/io/rosbag.h"
#include "chronomap/io/transform_tree.h"
#include "ros_messages.h"

namespace chronomap::io {

namespace fs = std::filesystem;

namespace {

/// The allocator the messages are instantiated with. The generated headers ask their allocator
/// for `rebind`, which std::allocator lost in C++20; this one still has it.
template <class T>
struct RosAllocator {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = RosAllocator<U>;
  };
  RosAllocator() = default;
  template <class U>
  RosAllocator(const RosAllocator<U>& /*other*/) noexcept {}
  T* allocate(std::size_t n) { return std::allocator<T>{}.allocate(n); }
  void deallocate(T* p, std::size_t n) noexcept { std::allocator<T>{}.deallocate(p, n); }
  template <class U>
  bool operator==(const RosAllocator<U>& /*other*/) const {
    return true;
  }
};
using Image = sensor_msgs::Image_<RosAllocator<void>>;
using CameraInfo = sensor_msgs::CameraInfo_<RosAllocator<void>>;
using PointCloud2 = sensor_msgs::PointCloud2_<RosAllocator<void>>;
using TFMessage = tf2_msgs::TFMessage_<RosAllocator<void>>;
using Odometry = nav_msgs::Odometry_<RosAllocator<void>>;
using PoseStamped = geometry_msgs::PoseStamped_<RosAllocator<void>>;
using Point = geometry_msgs::Point_<RosAllocator<void>>;
using Quaternion = geometry_msgs::Quaternion_<RosAllocator<void>>;

/// A message's string as a std::string.
std::string text(std::string_view s) { return std::string(s); }

constexpr const char* kImage = "sensor_msgs/Image";
constexpr const char* kCameraInfo = "sensor_msgs/CameraInfo";
constexpr const char* kPointCloud2 = "sensor_msgs/PointCloud2";
constexpr const char* kOdometry = "nav_msgs/Odometry";
constexpr const char* kPoseStamped = "geometry_msgs/PoseStamped";
/// Millimetres, as REP 118 stores 16UC1 depth.
constexpr double kDefaultDepthScale = 1000.0;

/// A tf frame name without the leading slash some old recorders wrote.
std::string frameName(std::string_view id) { return std::string(!id.empty() && id[0] == '/' ? id.substr(1) : id); }

double seconds(const ros::Time& t) { return t.toSec(); }

/// Opens a bag, librosbag's console messages silenced (the library never prints).
void openBag(rosbag::Bag& bag, const fs::path& path) {
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file");
  checkBagStructure(path);
  try {
    bag.open(path.string(), rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw FormatError(path.string() + ": not a readable ROS 1 bag (" + e.what() + ")");
  }
}

struct TopicInfo {
  std::string type;
  uint64_t messages = 0;
  std::string encoding;
  std::string frame_id;
};

/// Every topic with its type, count and, for images, the first message's encoding.
std::map<std::string, TopicInfo> topicsOf(const rosbag::Bag& bag) {
  std::map<std::string, TopicInfo> out;
  rosbag::View all(bag);
  for (const rosbag::ConnectionInfo* c : all.getConnections()) out[c->topic].type = c->datatype;
  for (auto& [name, info] : out) {
    rosbag::View view(bag, rosbag::TopicQuery(name));
    info.messages = view.size();
    if (info.type == kImage && info.messages > 0) {
      if (auto im = view.begin()->instantiate<Image>()) {
        info.encoding = text(im->encoding);
        info.frame_id = text(im->header.frame_id);
      }
    }
  }
  return out;
}

std::string joinNames(const std::vector<std::string>& names) {
  std::ostringstream out;
  for (size_t i = 0; i < names.size(); ++i) out << (i ? ", " : "") << names[i];
  return out.str();
}

/// The topics of `type` (and, when given, whose images pass `encoding_ok`).
std::vector<std::string> topicsOfType(const std::map<std::string, TopicInfo>& topics, const std::string& type,
                                      bool (*encoding_ok)(std::string_view) = nullptr) {
  std::vector<std::string> out;
  for (const auto& [name, info] : topics) {
    if (info.type == type && info.messages > 0 && (!encoding_ok || encoding_ok(info.encoding))) out.push_back(name);
  }
  return out;
}

/// A topic named by the user: it must exist with one of `types`.
void requireTopic(const std::map<std::string, TopicInfo>& topics, const std::string& name,
                  const std::vector<std::string>& types, const std::string& flag, const fs::path& path) {
  auto it = topics.find(name);
  if (it == topics.end()) {
    std::vector<std::string> fitting;
    for (const auto& type : types) {
      for (const auto& n : topicsOfType(topics, type)) fitting.push_back(n);
    }
    throw UsageError(path.string() + ": " + flag + ": no topic '" + name + "' in the bag (" +
                     (fitting.empty() ? std::string("none of type ") + joinNames(types)
                                      : std::string("candidates: ") + joinNames(fitting)) +
                     ")");
  }
  if (std::find(types.begin(), types.end(), it->second.type) == types.end()) {
    throw UsageError(path.string() + ": " + flag + ": topic '" + name + "' is a " + it->second.type + ", not a " +
                     joinNames(types));
  }
}

/// The one topic among `candidates`, or none when there is none. @throw UsageError when several fit.
std::optional<std::string> theOnly(const std::vector<std::string>& candidates, const std::string& what,
                                   const std::string& flag, const fs::path& path) {
  if (candidates.empty()) return std::nullopt;
  if (candidates.size() > 1) {
    throw UsageError(path.string() + ": " + std::to_string(candidates.size()) + " " + what + " topics (" +
                     joinNames(candidates) + "); choose one with " + flag);
  }
  return candidates.front();
}

/// The topics a bag's frames come from, as given or detected.
struct Topics {
  std::string depth;  ///< depth images, or
  std::string cloud;  ///< point clouds
  std::string color;
  std::string info;
  std::string color_info;
  std::string pose;  ///< empty: /tf and /tf_static
};

/// The CameraInfo beside an image topic (/cam/depth/image_raw -> /cam/depth/camera_info).
std::string infoBeside(const std::map<std::string, TopicInfo>& topics, const std::string& image_topic) {
  const auto slash = image_topic.rfind('/');
  if (slash == std::string::npos) return {};
  const std::string candidate = image_topic.substr(0, slash + 1) + "camera_info";
  auto it = topics.find(candidate);
  return it != topics.end() && it->second.type == kCameraInfo ? candidate : std::string();
}

Topics chooseTopics(const std::map<std::string, TopicInfo>& topics, const BagSettings& s, const fs::path& path) {
  Topics t;
  if (!s.cloud_topic.empty()) {
    requireTopic(topics, s.cloud_topic, {kPointCloud2}, "--cloud-topic", path);
    t.cloud = s.cloud_topic;
  } else if (!s.depth_topic.empty()) {
    requireTopic(topics, s.depth_topic, {kImage}, "--depth-topic", path);
    t.depth = s.depth_topic;
  } else if (auto depth =
                 theOnly(topicsOfType(topics, kImage, rosmsg::isDepthEncoding), "depth image", "--depth-topic", path)) {
    t.depth = *depth;  // depth images first: a cloud topic beside them is usually made from them
  } else if (auto cloud = theOnly(topicsOfType(topics, kPointCloud2), "point cloud", "--cloud-topic", path)) {
    t.cloud = *cloud;
  } else {
    throw DataError(path.string() + ": no depth image (16UC1, 32FC1) or PointCloud2 topic");
  }
  if (!t.depth.empty()) {
    if (s.color_topic == "none") {
      // no colour, as asked
    } else if (!s.color_topic.empty()) {
      requireTopic(topics, s.color_topic, {kImage}, "--color-topic", path);
      t.color = s.color_topic;
    } else if (auto color = theOnly(topicsOfType(topics, kImage, rosmsg::isColorEncoding), "colour image",
                                    "--color-topic (or --color-topic none)", path)) {
      t.color = *color;
    }
    if (!s.info_topic.empty()) {
      requireTopic(topics, s.info_topic, {kCameraInfo}, "--info-topic", path);
      t.info = s.info_topic;
    } else {
      t.info = infoBeside(topics, t.depth);
      if (t.info.empty())
        t.info = theOnly(topicsOfType(topics, kCameraInfo), "camera info", "--info-topic", path).value_or("");
    }
    if (!t.color.empty()) t.color_info = infoBeside(topics, t.color);
  }
  if (!s.pose_topic.empty()) {
    requireTopic(topics, s.pose_topic, {kOdometry, kPoseStamped}, "--pose-topic", path);
    t.pose = s.pose_topic;
  } else if (s.fixed_frame.empty()) {
    std::vector<std::string> poses = topicsOfType(topics, kOdometry);
    for (const auto& n : topicsOfType(topics, kPoseStamped)) poses.push_back(n);
    // /tf_static alone cannot move the sensor: a pose topic beside it is the trajectory.
    const bool has_tf = topics.count("/tf") > 0;
    if (poses.size() == 1 && !has_tf) {
      t.pose = poses.front();
    } else if (poses.empty() && !has_tf) {
      throw DataError(path.string() +
                      ": no poses: no /tf, no nav_msgs/Odometry and no geometry_msgs/PoseStamped topic");
    } else {
      throw UsageError(path.string() + ": where do the poses come from? Give --fixed-frame FRAME (poses from /tf)" +
                       (poses.empty() ? std::string() : " or --pose-topic (" + joinNames(poses) + ")"));
    }
  }
  return t;
}

Eigen::Isometry3d poseOf(const Point& p, const Quaternion& q, const std::string& context) {
  return poseFromTranslationQuaternion({p.x, p.y, p.z}, q.x, q.y, q.z, q.w, context);
}

/// The transforms of one /tf or /tf_static message.
void addTransforms(TransformTree& tree, const rosbag::MessageInstance& m, bool is_static, const fs::path& path) {
  const auto tf = m.instantiate<TFMessage>();
  if (!tf)
    throw DataError(path.string() + ": " + m.getTopic() + " is a " + m.getDataType() + ", not tf2_msgs/TFMessage");
  for (const auto& ts : tf->transforms) {
    const auto& tr = ts.transform.translation;
    const auto& q = ts.transform.rotation;
    std::string context = path.string();
    context.append(": ")
        .append(m.getTopic())
        .append(" ")
        .append(ts.header.frame_id)
        .append(" -> ")
        .append(ts.child_frame_id);
    tree.add(frameName(ts.header.frame_id), frameName(ts.child_frame_id), seconds(ts.header.stamp),
             poseFromTranslationQuaternion({tr.x, tr.y, tr.z}, q.x, q.y, q.z, q.w, context), is_static);
  }
}

/// The poses of a pose topic: the trajectory and the frame it gives the pose of.
struct PoseTrack {
  std::vector<TimedPose> poses;
  std::string child_frame;  ///< nav_msgs/Odometry's child frame; empty: the sensor's
};

/// The pose of one Odometry or PoseStamped message.
void addPose(PoseTrack& track, const rosbag::MessageInstance& m, const fs::path& path) {
  const std::string context = path.string() + ": " + m.getTopic();
  if (auto odom = m.instantiate<Odometry>()) {
    track.child_frame = frameName(odom->child_frame_id);
    track.poses.push_back(
        {seconds(odom->header.stamp), poseOf(odom->pose.pose.position, odom->pose.pose.orientation, context)});
  } else if (auto ps = m.instantiate<PoseStamped>()) {
    track.poses.push_back({seconds(ps->header.stamp), poseOf(ps->pose.position, ps->pose.orientation, context)});
  }
}

std::optional<CameraIntrinsics> readInfo(const rosbag::Bag& bag, const std::string& topic, const fs::path& path) {
  if (topic.empty()) return std::nullopt;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic))) {
    const auto info = m.instantiate<CameraInfo>();
    if (!info) continue;
    const CameraIntrinsics k{info->K[0], info->K[4], info->K[2], info->K[5]};
    if (!(k.fx > 0 && k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy) || !std::isfinite(k.cx) ||
        !std::isfinite(k.cy)) {
      throw DataError(path.string() + ": " + topic + ": the camera matrix K has no positive, finite focal lengths");
    }
    return k;
  }
  return std::nullopt;
}

/// A message of the bag with its header's time and frame.
struct Stamped {
  double t = 0.0;
  size_t message = 0;  ///< index into the reader's messages
  std::string frame_id;
};

/// One frame: a depth image (or cloud), its colour and its pose.
struct BagFrame {
  size_t depth = 0;
  std::optional<size_t> color;
  Eigen::Isometry3d pose;
  double t = 0.0;
};

class RosBagDataset : public Dataset {
 public:
  RosBagDataset(const fs::path& path, const DatasetSettings& settings) : path_(path) {
    openBag(bag_, path);
    try {
      read(settings);
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {  // librosbag's and the deserialiser's exceptions
      throw FormatError(path.string() + ": " + e.what());
    }
  }

  size_t size() const override { return frames_.size(); }
  DatasetFormat format() const override { return DatasetFormat::RosBag; }
  size_t framesDropped() const override { return without_pose_ + without_color_; }
  std::string droppedReasons() const override {
    std::ostringstream out;
    if (without_pose_) out << without_pose_ << " without a pose within " << pose_tolerance_s_ << " s";
    if (without_pose_ && without_color_) out << ", ";
    if (without_color_) out << without_color_ << " without colour within " << color_tolerance_s_ << " s";
    return out.str();
  }
  std::optional<double> recordedAt() const override {
    return frames_.empty() ? std::nullopt : std::optional<double>(frames_.front().t);
  }
  Eigen::Isometry3d poseOf(size_t i) const override { return frames_.at(i).pose; }

  Frame load(size_t i) const override {
    const BagFrame& f = frames_.at(i);
    Frame frame;
    std::ostringstream source;
    source.precision(17);
    source << path_.string() << ": " << (cloud_ ? cloud_topic_ : depth_topic_) << " at " << f.t;
    frame.source = source.str();
    frame.T_world_sensor = f.pose;
    frame.timestamp_s = f.t;
    try {
      if (cloud_) {
        const auto msg = instantiate<PointCloud2>(f.depth);
        rosmsg::CloudView view{msg->height,
                               msg->width,
                               {},
                               msg->is_bigendian != 0,
                               msg->point_step,
                               msg->row_step,
                               std::span<const uint8_t>(msg->data.data(), msg->data.size())};
        for (const auto& field : msg->fields) {
          view.fields.push_back({std::string_view(field.name), field.offset, field.datatype, field.count});
        }
        frame.cloud = rosmsg::pointCloud(view, frame.source);
        return frame;
      }
      const auto depth = instantiate<Image>(f.depth);
      std::optional<ImageRgb> rgb;
      if (f.color) {
        const auto color = instantiate<Image>(*f.color);
        rgb = rosmsg::colorImage(viewOf(*color), frame.source);
        if (rgb->width != depth->width || rgb->height != depth->height) {
          if (!color_k_) {
            std::ostringstream msg;
            msg << frame.source << ": the colour image is " << rgb->width << "x" << rgb->height << ", the depth image "
                << depth->width << "x" << depth->height << ", and " << color_topic_
                << " has no camera_info beside it to look colour up with";
            throw DataError(msg.str());
          }
          rgb = colorInDepthView(*rgb, *color_k_, k_, depth->width, depth->height);
        }
      }
      frame.cloud = rosmsg::depthCloud(viewOf(*depth), rgb ? &*rgb : nullptr, k_, depth_scale_, frame.source);
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      throw FormatError(frame.source + ": " + e.what());
    }
    return frame;
  }

 private:
  static rosmsg::ImageView viewOf(const Image& im) {
    return {im.height,
            im.width,
            std::string_view(im.encoding),
            im.is_bigendian != 0,
            im.step,
            std::span<const uint8_t>(im.data.data(), im.data.size())};
  }

  /// Reads message `i` (librosbag reads one message at a time; decoding runs outside the lock).
  template <class T>
  boost::shared_ptr<T> instantiate(size_t i) const {
    boost::shared_ptr<T> msg;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      msg = messages_.at(i).instantiate<T>();
    }
    if (!msg)
      throw DataError(path_.string() + ": message " + std::to_string(i) + " is not a " +
                      ros::message_traits::datatype<T>());
    return msg;
  }

  /// Remembers a message with its header's stamp and frame.
  template <class T>
  void addStamped(std::vector<Stamped>& out, const rosbag::MessageInstance& m) {
    const auto msg = m.instantiate<T>();
    if (!msg) return;
    out.push_back({seconds(msg->header.stamp), messages_.size(), frameName(msg->header.frame_id)});
    messages_.push_back(m);
  }

  void read(const DatasetSettings& s) {
    const auto topics = topicsOf(bag_);
    const Topics t = chooseTopics(topics, s.bag, path_);
    pose_tolerance_s_ = s.bag.pose_tolerance_s;
    color_tolerance_s_ = s.max_time_difference_s;
    depth_scale_ = s.depth_scale.value_or(kDefaultDepthScale);
    cloud_ = !t.cloud.empty();
    depth_topic_ = t.depth;
    cloud_topic_ = t.cloud;
    color_topic_ = t.color;
    if (!cloud_) {
      const auto k = s.intrinsics ? s.intrinsics : readInfo(bag_, t.info, path_);
      if (!k) {
        throw DataError(path_.string() + ": no sensor_msgs/CameraInfo for " + t.depth +
                        " (give --info-topic or --intrinsics)");
      }
      k_ = *k;
      color_k_ = readInfo(bag_, t.color_info, path_);
    }
    // One pass over the topics in time order, so that each chunk is decompressed once.
    const std::string frames_topic = cloud_ ? t.cloud : t.depth;
    std::vector<std::string> wanted{frames_topic};
    for (const std::string& topic : {t.color, t.pose, std::string("/tf"), std::string("/tf_static")}) {
      if (!topic.empty() && topics.count(topic)) wanted.push_back(topic);
    }
    std::vector<Stamped> depths, colors;
    TransformTree tree;
    std::optional<PoseTrack> track;
    if (!t.pose.empty()) track.emplace();
    for (const rosbag::MessageInstance& m : rosbag::View(bag_, rosbag::TopicQuery(wanted))) {
      const std::string& topic = m.getTopic();
      if (topic == frames_topic) {
        cloud_ ? addStamped<PointCloud2>(depths, m) : addStamped<Image>(depths, m);
      } else if (topic == t.color) {
        addStamped<Image>(colors, m);
      } else if (topic == t.pose) {
        addPose(*track, m, path_);
      } else if (topic == "/tf" || topic == "/tf_static") {
        addTransforms(tree, m, topic == "/tf_static", path_);
      }
    }
    const auto by_time = [](const Stamped& a, const Stamped& b) { return a.t < b.t; };
    std::stable_sort(depths.begin(), depths.end(), by_time);
    std::stable_sort(colors.begin(), colors.end(), by_time);
    tree.finish();
    if (track) {
      std::stable_sort(track->poses.begin(), track->poses.end(),
                       [](const TimedPose& a, const TimedPose& b) { return a.t < b.t; });
      if (track->poses.empty()) throw DataError(path_.string() + ": pose topic " + t.pose + " has no messages");
    }
    for (const Stamped& d : depths) {
      const std::optional<Eigen::Isometry3d> pose = poseAt(d, tree, track, s);
      if (!pose) {
        ++without_pose_;
        continue;
      }
      BagFrame f{d.message, std::nullopt, *pose, d.t};
      if (!t.color.empty()) {
        const Stamped* c = nearestInTime(colors, d.t, s.max_time_difference_s);
        if (!c) {
          ++without_color_;
          continue;
        }
        f.color = c->message;
      }
      frames_.push_back(f);
    }
    if (frames_.empty()) {
      std::ostringstream msg;
      msg << path_.string() << ": none of the " << depths.size() << " frames of " << (cloud_ ? t.cloud : t.depth)
          << " can be used (" << droppedReasons() << ")";
      const std::set<std::string> frames = tree.frames();
      if (!track && !frames.empty() && !depths.empty()) {
        msg << "; /tf holds the frames " << joinNames({frames.begin(), frames.end()}) << ", the images are in '"
            << depths.front().frame_id << "'";
      }
      throw DataError(msg.str());
    }
  }

  /// The sensor's pose at a frame's time, or nothing when none is known within the tolerance.
  std::optional<Eigen::Isometry3d> poseAt(const Stamped& d, const TransformTree& tree,
                                          const std::optional<PoseTrack>& track, const DatasetSettings& s) const {
    const double tol = s.bag.pose_tolerance_s;
    if (!track) return tree.lookup(frameName(s.bag.fixed_frame), d.frame_id, d.t, tol);
    const auto T_map_body = io::poseAt(track->poses, d.t, tol);
    if (!T_map_body || track->child_frame.empty() || track->child_frame == d.frame_id) return T_map_body;
    // An odometry of the robot's body: carried to the sensor through /tf.
    const auto T_body_sensor = tree.lookup(track->child_frame, d.frame_id, d.t, tol);
    if (!T_body_sensor) return std::nullopt;
    return *T_map_body * *T_body_sensor;
  }

  fs::path path_;
  rosbag::Bag bag_;
  mutable std::mutex mutex_;  ///< librosbag's reads share one file and one chunk buffer
  std::vector<rosbag::MessageInstance> messages_;
  std::vector<BagFrame> frames_;
  bool cloud_ = false;
  std::string depth_topic_, cloud_topic_, color_topic_;
  CameraIntrinsics k_;
  std::optional<CameraIntrinsics> color_k_;
  double depth_scale_ = kDefaultDepthScale;
  double pose_tolerance_s_ = 0.0, color_tolerance_s_ = 0.0;
  size_t without_pose_ = 0, without_color_ = 0;
};

}  // namespace

std::unique_ptr<Dataset> openRosBag(const fs::path& path, const DatasetSettings& settings) {
  return std::make_unique<RosBagDataset>(path, settings);
}

std::vector<BagTopic> listBag(const fs::path& path) {
  rosbag::Bag bag;
  openBag(bag, path);
  std::vector<BagTopic> out;
  try {
    for (const auto& [name, info] : topicsOf(bag)) out.push_back({name, info.type, info.messages, info.encoding});
  } catch (const std::exception& e) {
    throw FormatError(path.string() + ": " + e.what());
  }
  return out;
}

bool rosBagSupported() { return true; }

}  // namespace chronomap::io
