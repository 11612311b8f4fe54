// ROS 1 bags through Debian's librosbag and the generated message headers of sensor_msgs,
// geometry_msgs, nav_msgs and tf2_msgs. The only file of chronomap that includes ROS headers.

#include "rosbag1.h"

#include <console_bridge/console.h>
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <limits>
#include <stdexcept>
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
#include "chronomap/ingest/ros/rosbag.h"
#include "chronomap/ingest/ros/transform_tree.h"
#include "bag_dataset.h"
#include "ros_messages.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

/// The most bytes one allocation may take while a message is instantiated (instantiate() sets it
/// from the message's size): a corrupt array length must not ask for gigabytes.
thread_local size_t tl_allocation_limit = std::numeric_limits<size_t>::max();

/// Thrown by RosAllocator past tl_allocation_limit; the readers' handlers turn it into a
/// FormatError naming the file.
struct OversizedMessage : std::runtime_error {
  OversizedMessage() : std::runtime_error("a message claims more elements than its bytes can hold (corrupt)") {}
};

/// The allocator the messages are instantiated with. The generated headers ask their allocator
/// for `rebind`, which std::allocator lost in C++20; this one still has it, and refuses what no
/// message of its size can hold (tl_allocation_limit).
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
  T* allocate(std::size_t n) {
    if (n > tl_allocation_limit / sizeof(T)) throw OversizedMessage();
    return std::allocator<T>{}.allocate(n);
  }
  void deallocate(T* p, std::size_t n) noexcept { std::allocator<T>{}.deallocate(p, n); }
  template <class U>
  bool operator==(const RosAllocator<U>& /*other*/) const {
    return true;
  }
};
using Image = sensor_msgs::Image_<RosAllocator<void>>;
using CompressedImage = sensor_msgs::CompressedImage_<RosAllocator<void>>;
using CameraInfo = sensor_msgs::CameraInfo_<RosAllocator<void>>;
using PointCloud2 = sensor_msgs::PointCloud2_<RosAllocator<void>>;
using TFMessage = tf2_msgs::TFMessage_<RosAllocator<void>>;
using Odometry = nav_msgs::Odometry_<RosAllocator<void>>;
using PoseStamped = geometry_msgs::PoseStamped_<RosAllocator<void>>;
using Point = geometry_msgs::Point_<RosAllocator<void>>;
using Quaternion = geometry_msgs::Quaternion_<RosAllocator<void>>;

/// `m` as a T (null when it is another type). No allocation may exceed 16 times the message's
/// bytes (plus 4 KiB): an element takes at most 8 times its serialised size in memory (an empty
/// string: 4 bytes in the bag, 32 in memory).
template <class T>
boost::shared_ptr<T> instantiate(const rosbag::MessageInstance& m) {
  struct Limit {
    size_t before = tl_allocation_limit;
    ~Limit() { tl_allocation_limit = before; }
  } limit;
  tl_allocation_limit = 16 * size_t{m.size()} + 4096;
  return m.instantiate<T>();
}

/// A message's string as a std::string.
std::string text(std::string_view s) { return std::string(s); }

double seconds(const ros::Time& t) { return t.toSec(); }

/// A copy of a bag in the temporary folder whose index times 0 read as 1 ns, the first time
/// librosbag indexes (it drops entries at 0 when it opens a bag). Removed on destruction: an
/// open bag keeps reading its file.
class ZeroTimesMoved {
 public:
  ZeroTimesMoved(const fs::path& path, const BagStructure& s) {
    static std::atomic<unsigned> counter{0};
    path_ = fs::temp_directory_path() /
            ("chronomap-bag-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + ".bag");
    std::error_code ec;
    fs::copy_file(path, path_, fs::copy_options::overwrite_existing, ec);
    std::fstream f(path_, std::ios::in | std::ios::out | std::ios::binary);
    const uint32_t one_ns[2] = {0, 1};
    for (const uint64_t at : s.zero_times) {
      if (ec || !f) break;
      f.seekp(static_cast<std::streamoff>(at));
      f.write(reinterpret_cast<const char*>(one_ns), sizeof one_ns);
    }
    if (ec || !f.flush()) {
      fs::remove(path_, ec);
      throw IoError(path.string() + ": cannot copy it to " + path_.parent_path().string() +
                    " to read its messages recorded at time 0 (" + std::to_string(s.zero_time_messages) +
                    "; librosbag skips them in place): is the temporary folder full? Set TMPDIR");
    }
  }
  ~ZeroTimesMoved() {
    std::error_code ignored;
    fs::remove(path_, ignored);
  }
  ZeroTimesMoved(const ZeroTimesMoved&) = delete;
  ZeroTimesMoved& operator=(const ZeroTimesMoved&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// Opens a bag, librosbag's console messages silenced (the library never prints). Messages
/// recorded at time 0 are read too (ZeroTimesMoved).
void openBag(rosbag::Bag& bag, const fs::path& path) {
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file");
  const BagStructure structure = checkBagStructure(path);
  std::optional<ZeroTimesMoved> copy;
  if (!structure.zero_times.empty()) copy.emplace(path, structure);
  try {
    bag.open((copy ? copy->path() : path).string(), rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw FormatError(path.string() + ": not a readable ROS 1 bag (" + e.what() + ")");
  }
}

/// Every topic with its type, count and, for images, the first message's encoding.
bag::TopicMap topicsOf(const rosbag::Bag& bag) {
  bag::TopicMap out;
  rosbag::View all(bag);
  for (const rosbag::ConnectionInfo* c : all.getConnections()) out[c->topic].type = c->datatype;
  for (auto& [name, info] : out) {
    rosbag::View view(bag, rosbag::TopicQuery(name));
    info.messages = view.size();
    if (info.type == bag::kImage && info.messages > 0) {
      if (auto im = instantiate<Image>(*view.begin())) {
        info.encoding = text(im->encoding);
        info.frame_id = text(im->header.frame_id);
      }
    } else if (info.type == bag::kCompressedImage && info.messages > 0) {
      if (auto im = instantiate<CompressedImage>(*view.begin())) {
        info.encoding = text(im->format);
        info.frame_id = text(im->header.frame_id);
      }
    }
  }
  return out;
}

Eigen::Isometry3d poseOf(const Point& p, const Quaternion& q, const std::string& context) {
  return poseFromTranslationQuaternion({p.x, p.y, p.z}, q.x, q.y, q.z, q.w, context);
}

/// The transforms of one /tf or /tf_static message.
void addTransforms(TransformTree& tree, const rosbag::MessageInstance& m, bool is_static, const fs::path& path) {
  const auto tf = instantiate<TFMessage>(m);
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
    tree.add(bag::frameName(ts.header.frame_id), bag::frameName(ts.child_frame_id), seconds(ts.header.stamp),
             poseFromTranslationQuaternion({tr.x, tr.y, tr.z}, q.x, q.y, q.z, q.w, context), is_static, context);
  }
}

/// The pose of one Odometry or PoseStamped message.
void addPose(bag::PoseTrack& track, const rosbag::MessageInstance& m, const fs::path& path) {
  const std::string context = path.string() + ": " + m.getTopic();
  if (auto odom = instantiate<Odometry>(m)) {
    track.child_frame = bag::frameName(odom->child_frame_id);
    track.poses.push_back(
        {seconds(odom->header.stamp), poseOf(odom->pose.pose.position, odom->pose.pose.orientation, context)});
  } else if (auto ps = instantiate<PoseStamped>(m)) {
    track.poses.push_back({seconds(ps->header.stamp), poseOf(ps->pose.position, ps->pose.orientation, context)});
  }
}

/// The first CameraInfo of `topic`: its intrinsics, and the image size it states into
/// `width`, `height` when asked.
std::optional<CameraIntrinsics> readInfo(const rosbag::Bag& bag, const std::string& topic, const fs::path& path,
                                         uint32_t* width = nullptr, uint32_t* height = nullptr) {
  if (topic.empty()) return std::nullopt;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic))) {
    const auto info = instantiate<CameraInfo>(m);
    if (!info) continue;
    double k[9];
    std::copy(info->K.begin(), info->K.end(), k);
    if (width) *width = info->width;
    if (height) *height = info->height;
    return bag::intrinsicsOf(k, path.string() + ": " + topic);
  }
  return std::nullopt;
}

class RosBagDataset : public bag::BagDataset {
 public:
  RosBagDataset(const fs::path& path, const DatasetSettings& settings)
      : BagDataset(path, "rosbag") {
    openBag(bag_, path);
    try {
      read(settings);
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {  // librosbag's and the deserialiser's exceptions
      throw FormatError(path.string() + ": " + e.what());
    }
  }

 protected:
  bag::ImageMessage image(uint64_t message, bool compressed) const override {
    if (compressed) {
      const auto im = instantiate<CompressedImage>(message);
      return {{},
              rosmsg::CompressedView{std::string_view(im->format),
                                     std::span<const uint8_t>(im->data.data(), im->data.size())},
              std::shared_ptr<const void>(im)};
    }
    const auto im = instantiate<Image>(message);
    return {{im->height, im->width, std::string_view(im->encoding), im->is_bigendian != 0, im->step,
             std::span<const uint8_t>(im->data.data(), im->data.size())},
            std::nullopt,
            std::shared_ptr<const void>(im)};
  }

  bag::CloudMessage cloud(uint64_t message) const override {
    const auto msg = instantiate<PointCloud2>(message);
    bag::CloudMessage out{{msg->height,
                           msg->width,
                           {},
                           msg->is_bigendian != 0,
                           msg->point_step,
                           msg->row_step,
                           std::span<const uint8_t>(msg->data.data(), msg->data.size())},
                          std::shared_ptr<const void>(msg)};
    for (const auto& field : msg->fields) {
      out.view.fields.push_back({std::string_view(field.name), field.offset, field.datatype, field.count});
    }
    return out;
  }

 private:
  /// Reads message `i` (librosbag reads one message at a time; decoding runs outside the lock).
  template <class T>
  std::shared_ptr<T> instantiate(uint64_t i) const {
    boost::shared_ptr<T> msg;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      msg = chronomap::instantiate<T>(messages_.at(i));
    }
    if (!msg)
      throw DataError(path_.string() + ": message " + std::to_string(i) + " is not a " +
                      ros::message_traits::datatype<T>());
    return std::shared_ptr<T>(msg.get(), [msg](T*) mutable { msg.reset(); });
  }

  /// Remembers a message with its header's stamp and frame.
  template <class T>
  void addStamped(std::vector<bag::Stamped>& out, const rosbag::MessageInstance& m) {
    const auto msg = chronomap::instantiate<T>(m);
    if (!msg) return;
    out.push_back({seconds(msg->header.stamp), messages_.size(), bag::frameName(msg->header.frame_id)});
    messages_.push_back(m);
  }

  void read(const DatasetSettings& s) {
    const auto topics = topicsOf(bag_);
    const bag::Topics t = bag::chooseTopics(topics, s.bag, path_);
    bag::Gathered g;
    const bool cloud = !t.cloud.empty();
    if (!cloud) {
      if (!s.intrinsics) {
        g.k = readInfo(bag_, t.info, path_, &g.info_width, &g.info_height);
        g.info_topic = t.info;
      }
      g.colour_k = readInfo(bag_, t.colour_info, path_);
    }
    // One pass over the topics in time order, so that each chunk is decompressed once.
    const std::string frames_topic = cloud ? t.cloud : t.depth;
    std::vector<std::string> wanted{frames_topic};
    for (const std::string& topic : {t.colour, t.pose, std::string("/tf"), std::string("/tf_static")}) {
      if (!topic.empty() && topics.count(topic)) wanted.push_back(topic);
    }
    if (!t.pose.empty()) g.track.emplace();
    for (const rosbag::MessageInstance& m : rosbag::View(bag_, rosbag::TopicQuery(wanted))) {
      const std::string& topic = m.getTopic();
      if (topic == frames_topic) {
        if (cloud) {
          addStamped<PointCloud2>(g.depths, m);
        } else {
          t.depth_compressed ? addStamped<CompressedImage>(g.depths, m) : addStamped<Image>(g.depths, m);
        }
      } else if (topic == t.colour) {
        t.colour_compressed ? addStamped<CompressedImage>(g.colours, m) : addStamped<Image>(g.colours, m);
      } else if (topic == t.pose) {
        addPose(*g.track, m, path_);
      } else if (topic == "/tf" || topic == "/tf_static") {
        addTransforms(g.tree, m, topic == "/tf_static", path_);
      }
    }
    assemble(t, s, std::move(g));
  }

  rosbag::Bag bag_;
  mutable std::mutex mutex_;  ///< librosbag's reads share one file and one chunk buffer
  std::vector<rosbag::MessageInstance> messages_;
};

}  // namespace

std::unique_ptr<Dataset> openRosBag(const fs::path& path, const DatasetSettings& settings) {
  return std::make_unique<RosBagDataset>(path, settings);
}

std::vector<BagTopic> listRosBag1(const fs::path& path) {
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

}  // namespace chronomap
