// The part of the bag readers that does not depend on how a bag stores its messages.

#include "bag_dataset.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "chronomap/core/error.h"
#include "stamped.h"

namespace chronomap::bag {

namespace fs = std::filesystem;

std::string frameName(std::string_view id) { return std::string(!id.empty() && id[0] == '/' ? id.substr(1) : id); }

std::string joinNames(const std::vector<std::string>& names) {
  std::ostringstream out;
  for (size_t i = 0; i < names.size(); ++i) out << (i ? ", " : "") << names[i];
  return out.str();
}

namespace {

/// The topics of `type` (and, when given, whose images pass `encoding_ok`).
std::vector<std::string> topicsOfType(const TopicMap& topics, const std::string& type,
                                      bool (*encoding_ok)(std::string_view) = nullptr) {
  std::vector<std::string> out;
  for (const auto& [name, info] : topics) {
    if (info.type == type && info.messages > 0 && (!encoding_ok || encoding_ok(info.encoding))) out.push_back(name);
  }
  return out;
}

/// A topic named by the user: it must exist with one of `types`.
void requireTopic(const TopicMap& topics, const std::string& name, const std::vector<std::string>& types,
                  const std::string& flag, const fs::path& path) {
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

/// An image_transport topic's base: /cam/rgb/image_raw/compressed -> /cam/rgb/image_raw (the
/// same for compressedDepth); other names unchanged.
std::string transportBase(const std::string& topic) {
  for (const std::string suffix : {"/compressed", "/compressedDepth"}) {
    if (topic.size() > suffix.size() && topic.compare(topic.size() - suffix.size(), suffix.size(), suffix) == 0)
      return topic.substr(0, topic.size() - suffix.size());
  }
  return topic;
}

/// The CameraInfo beside an image topic (/cam/depth/image_raw -> /cam/depth/camera_info; the
/// same for its /compressed or /compressedDepth transport).
std::string infoBeside(const TopicMap& topics, const std::string& image_topic) {
  const std::string base = transportBase(image_topic);
  const auto slash = base.rfind('/');
  if (slash == std::string::npos) return {};
  const std::string candidate = base.substr(0, slash + 1) + "camera_info";
  auto it = topics.find(candidate);
  return it != topics.end() && it->second.type == kCameraInfo ? candidate : std::string();
}

/// Image topics (raw images passing `raw_ok`, compressed ones passing `compressed_ok`); a
/// compressed transport is left out when its raw topic is there too (the same images, stored
/// twice: the raw ones are read, lossless and without decoding).
std::vector<std::string> imageTopics(const TopicMap& topics, bool (*raw_ok)(std::string_view),
                                     bool (*compressed_ok)(std::string_view)) {
  std::vector<std::string> out = topicsOfType(topics, kImage, raw_ok);
  for (const std::string& name : topicsOfType(topics, kCompressedImage, compressed_ok)) {
    const std::string base = transportBase(name);
    const auto raw = topics.find(base);
    if (base != name && raw != topics.end() && raw->second.type == kImage && raw->second.messages > 0) continue;
    out.push_back(name);
  }
  return out;
}

bool isCompressed(const TopicMap& topics, const std::string& name) {
  const auto it = topics.find(name);
  return it != topics.end() && it->second.type == kCompressedImage;
}

}  // namespace

Topics chooseTopics(const TopicMap& topics, const BagSettings& s, const fs::path& path) {
  Topics t;
  if (!s.cloud_topic.empty()) {
    requireTopic(topics, s.cloud_topic, {kPointCloud2}, "--cloud-topic", path);
    t.cloud = s.cloud_topic;
  } else if (!s.depth_topic.empty()) {
    requireTopic(topics, s.depth_topic, {kImage, kCompressedImage}, "--depth-topic", path);
    t.depth = s.depth_topic;
  } else if (auto depth = theOnly(imageTopics(topics, rosmsg::isDepthEncoding, rosmsg::isCompressedDepthFormat),
                                  "depth image", "--depth-topic", path)) {
    t.depth = *depth;  // depth images first: a cloud topic beside them is usually made from them
  } else if (auto cloud = theOnly(topicsOfType(topics, kPointCloud2), "point cloud", "--cloud-topic", path)) {
    t.cloud = *cloud;
  } else {
    throw DataError(path.string() + ": no depth image (16UC1, 32FC1, compressedDepth) or PointCloud2 topic");
  }
  if (!t.depth.empty()) {
    if (s.colour_topic == "none") {
      // no colour, as asked
    } else if (!s.colour_topic.empty()) {
      requireTopic(topics, s.colour_topic, {kImage, kCompressedImage}, "--color-topic", path);
      t.colour = s.colour_topic;
    } else if (auto colour = theOnly(imageTopics(topics, rosmsg::isColourEncoding, rosmsg::isCompressedColourFormat),
                                    "colour image", "--color-topic (or --color-topic none)", path)) {
      t.colour = *colour;
    }
    t.depth_compressed = isCompressed(topics, t.depth);
    t.colour_compressed = isCompressed(topics, t.colour);
    if (!s.info_topic.empty()) {
      requireTopic(topics, s.info_topic, {kCameraInfo}, "--info-topic", path);
      t.info = s.info_topic;
    } else {
      t.info = infoBeside(topics, t.depth);
      if (t.info.empty())
        t.info = theOnly(topicsOfType(topics, kCameraInfo), "camera info", "--info-topic", path).value_or("");
    }
    if (!t.colour.empty()) t.colour_info = infoBeside(topics, t.colour);
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

CameraIntrinsics intrinsicsOf(const double (&k)[9], const std::string& context) {
  const CameraIntrinsics out{k[0], k[4], k[2], k[5]};
  if (!intrinsicsValid(out)) {
    throw DataError(context + ": the camera matrix K has no positive, finite focal lengths");
  }
  return out;
}

std::string BagDataset::droppedReasons() const {
  std::ostringstream out;
  if (without_pose_) out << without_pose_ << " without a pose within " << pose_tolerance_s_ << " s";
  if (without_pose_ && without_colour_) out << ", ";
  if (without_colour_) out << without_colour_ << " without colour within " << colour_tolerance_s_ << " s";
  if (!lost_.empty()) out << (without_pose_ || without_colour_ ? "; " : "") << lost_;
  return out.str();
}

std::optional<double> BagDataset::recordedAt() const {
  return frames_.empty() ? std::nullopt : std::optional<double>(frames_.front().t);
}

void BagDataset::assemble(const Topics& t, const DatasetSettings& s, Gathered g) {
  pose_tolerance_s_ = s.bag.pose_tolerance_s;
  colour_tolerance_s_ = s.max_time_difference_s;
  depth_scale_ = s.depth_scale.value_or(kDefaultDepthScale);
  cloud_ = !t.cloud.empty();
  depth_compressed_ = t.depth_compressed;
  colour_compressed_ = t.colour_compressed;
  depth_topic_ = t.depth;
  cloud_topic_ = t.cloud;
  colour_topic_ = t.colour;
  if (!cloud_) {
    const auto k = s.intrinsics ? s.intrinsics : g.k;
    if (!k) {
      throw DataError(path_.string() + ": no sensor_msgs/CameraInfo for " + t.depth +
                      " (give --info-topic or --intrinsics)");
    }
    k_ = *k;
    colour_k_ = g.colour_k;
    if (!s.intrinsics) {
      info_width_ = g.info_width;
      info_height_ = g.info_height;
      info_topic_ = g.info_topic;
    }
  }
  const auto by_time = [](const Stamped& a, const Stamped& b) { return a.t < b.t; };
  std::stable_sort(g.depths.begin(), g.depths.end(), by_time);
  std::stable_sort(g.colours.begin(), g.colours.end(), by_time);
  g.tree.finish(path_.string() + ": /tf and /tf_static");
  if (g.track) {
    std::stable_sort(g.track->poses.begin(), g.track->poses.end(),
                     [](const TimedPose& a, const TimedPose& b) { return a.t < b.t; });
    if (g.track->poses.empty()) throw DataError(path_.string() + ": pose topic " + t.pose + " has no messages");
  }
  for (const Stamped& d : g.depths) {
    const std::optional<Eigen::Isometry3d> pose = poseAt(d, g.tree, g.track, s.bag);
    if (!pose) {
      ++without_pose_;
      continue;
    }
    Pair f{d.message, std::nullopt, *pose, d.t};
    if (!t.colour.empty()) {
      const Stamped* c = nearestInTime(g.colours, d.t, s.max_time_difference_s);
      if (!c) {
        ++without_colour_;
        continue;
      }
      f.colour = c->message;
    }
    frames_.push_back(f);
  }
  if (frames_.empty()) {
    std::ostringstream msg;
    msg << path_.string() << ": none of the " << g.depths.size() << " frames of " << (cloud_ ? t.cloud : t.depth)
        << " can be used (" << droppedReasons() << ")";
    const std::set<std::string> frames = g.tree.frames();
    if (!g.track && !frames.empty() && !g.depths.empty()) {
      msg << "; /tf holds the frames " << joinNames({frames.begin(), frames.end()}) << ", the images are in '"
          << g.depths.front().frame_id << "'";
    }
    throw DataError(msg.str());
  }
}

std::optional<Eigen::Isometry3d> BagDataset::poseAt(const Stamped& d, const TransformTree& tree,
                                                    const std::optional<PoseTrack>& track,
                                                    const BagSettings& s) const {
  const double tol = s.pose_tolerance_s;
  if (!track) return tree.lookup(frameName(s.fixed_frame), d.frame_id, d.t, tol);
  const auto T_map_body = chronomap::poseAt(track->poses, d.t, tol);
  if (!T_map_body || track->child_frame.empty() || track->child_frame == d.frame_id) return T_map_body;
  // An odometry of the robot's body: carried to the sensor through /tf.
  const auto T_body_sensor = tree.lookup(track->child_frame, d.frame_id, d.t, tol);
  if (!T_body_sensor) return std::nullopt;
  return *T_map_body * *T_body_sensor;
}

void BagDataset::checkInfoSize(uint32_t width, uint32_t height, const std::string& source) const {
  if (info_width_ == 0 || info_height_ == 0 || (info_width_ == width && info_height_ == height)) return;
  std::ostringstream msg;
  msg << source << ": the depth image is " << width << " x " << height << " but the CameraInfo on " << info_topic_
      << " describes " << info_width_ << " x " << info_height_
      << " images: its intrinsics belong to another image size (give --intrinsics for " << width << " x " << height
      << ", or --info-topic)";
  throw DataError(msg.str());
}

Frame BagDataset::load(size_t i) const {
  const Pair& f = frames_.at(i);
  Frame frame;
  std::ostringstream source;
  source.precision(17);
  source << path_.string() << ": " << (cloud_ ? cloud_topic_ : depth_topic_) << " at " << f.t;
  frame.source = source.str();
  frame.T_world_sensor = f.pose;
  frame.timestamp_s = f.t;
  try {
    if (cloud_) {
      const CloudMessage msg = cloud(f.depth);
      frame.cloud = rosmsg::pointCloud(msg.view, frame.source);
      return frame;
    }
    const ImageMessage depth = image(f.depth, depth_compressed_);
    rosmsg::OwnedImage decoded;
    if (depth.compressed) decoded = rosmsg::compressedDepthImage(*depth.compressed, frame.source);
    const rosmsg::ImageView& depth_view = depth.compressed ? decoded.view : depth.view;
    checkInfoSize(depth_view.width, depth_view.height, frame.source);
    std::optional<ImageRgb> rgb;
    if (f.colour) {
      const ImageMessage colour = image(*f.colour, colour_compressed_);
      rgb = colour.compressed ? rosmsg::compressedColourImage(*colour.compressed, frame.source)
                             : rosmsg::colourImage(colour.view, frame.source);
      if (rgb->width != depth_view.width || rgb->height != depth_view.height) {
        if (!colour_k_) {
          std::ostringstream msg;
          msg << frame.source << ": the colour image is " << rgb->width << "x" << rgb->height << ", the depth image "
              << depth_view.width << "x" << depth_view.height << ", and " << colour_topic_
              << " has no camera_info beside it to look colour up with";
          throw DataError(msg.str());
        }
        rgb = colourInDepthView(*rgb, *colour_k_, k_, depth_view.width, depth_view.height);
      }
    }
    frame.cloud = rosmsg::depthCloud(depth_view, rgb ? &*rgb : nullptr, k_, depth_scale_, frame.source);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw FormatError(frame.source + ": " + e.what());
  }
  return frame;
}

}  // namespace chronomap::bag
