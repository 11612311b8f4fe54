#pragma once
// CDR decoding (internal) of the ROS 2 messages chronomap reads from a ROS 2 bag: XCDR1 plain
// CDR, little- or big-endian as the 4-byte encapsulation header says (ROS 2 writes CDR_LE),
// each primitive aligned to its size counted from the end of that header. Images and clouds
// become the views of ros_messages.h, pointing into the message's bytes (which must outlive
// them); the other messages become the few numbers chronomap uses. Every error is a
// FormatError naming `source`.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ros_messages.h"

namespace chronomap::cdr {

/// std_msgs/msg/Header.
struct Header {
  double stamp = 0.0;  ///< seconds: sec + 1e-9 nanosec, as ROS 1's Time::toSec
  std::string_view frame_id;
};

struct Image {
  Header header;
  rosmsg::ImageView view;
};

/// sensor_msgs/msg/CompressedImage.
struct CompressedImage {
  Header header;
  rosmsg::CompressedView view;
};

struct Cloud {
  Header header;
  rosmsg::CloudView view;
};

/// sensor_msgs/msg/CameraInfo: the header and the camera matrix.
struct CameraInfo {
  Header header;
  uint32_t height = 0, width = 0;  ///< the images it describes (0: not said)
  double k[9] = {};
};

/// A pose or transform: geometry_msgs/msg/TransformStamped, the pose of a nav_msgs/msg/Odometry
/// (child_frame_id set) or of a geometry_msgs/msg/PoseStamped (child empty).
struct Transform {
  Header header;
  std::string_view child;
  double xyz[3] = {};
  double q[4] = {0, 0, 0, 1};  ///< x, y, z, w
};

/// The header every stamped message starts with.
Header header(std::span<const uint8_t> msg, const std::string& source);
Image image(std::span<const uint8_t> msg, const std::string& source);
CompressedImage compressedImage(std::span<const uint8_t> msg, const std::string& source);
Cloud cloud(std::span<const uint8_t> msg, const std::string& source);
CameraInfo cameraInfo(std::span<const uint8_t> msg, const std::string& source);
/// tf2_msgs/msg/TFMessage.
std::vector<Transform> tfMessage(std::span<const uint8_t> msg, const std::string& source);
Transform odometry(std::span<const uint8_t> msg, const std::string& source);
Transform poseStamped(std::span<const uint8_t> msg, const std::string& source);

}  // namespace chronomap::cdr
