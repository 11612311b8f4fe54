// ROS 1 bags: written by Debian's python3-rosbag (tests/ingest/ros/make_ros1_bags.py) from a simulated
// TUM session, read back through librosbag, and compared with the TUM reader's frames and map.

#include "chronomap/ingest/ros/rosbag.h"

#include <gtest/gtest.h>

#include <functional>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>

#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/transform_tree.h"
#include "chronomap/pipeline/session.h"
#include "ingest/ros/ros_messages.h"
#include "bag_fixture.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

/// Debian's interpreter, which has python3-rosbag (the first python3 on PATH may not).
constexpr const char* kDebianPython = "/usr/bin/python3";

/// The shared recordings (bag_fixture.h); the ROS 1 bags need Debian's python3-rosbag.
class RosBagTest : public BagFixture<RosBagTest> {
 public:
  static constexpr const char* kWriters = "python3-rosbag";
  static constexpr const char* kErrorFile = "ros1.error";
};

TEST_F(RosBagTest, ListsTopicsTypesCountsAndEncodings) {
  const std::vector<BagTopic> topics = listBag(bag("tf.bag"));
  ASSERT_EQ(topics.size(), 5u);
  EXPECT_EQ(topics[0].name, "/camera/depth/camera_info");
  EXPECT_EQ(topics[0].type, "sensor_msgs/CameraInfo");
  EXPECT_EQ(topics[1].name, "/camera/depth/image_raw");
  EXPECT_EQ(topics[1].encoding, "16UC1");
  EXPECT_EQ(topics[1].messages, 32u);
  EXPECT_EQ(topics[2].encoding, "rgb8");
  EXPECT_EQ(topics[3].name, "/tf");
  EXPECT_EQ(topics[3].messages, 64u);  // two samples around every frame
  EXPECT_EQ(topics[4].name, "/tf_static");
}

// The same depth numbers, colour and pose numbers give the same map, byte for byte, whatever
// the chunk compression, and from an Odometry as from a PoseStamped topic.
TEST_F(RosBagTest, PoseTopicBagsGiveTheTumFoldersMapByteForByte) {
  const auto expected = mapBytes(tum(), {});
  for (const char* name : {"pose_none.bag", "pose_bz2.bag", "pose_lz4.bag", "odometry.bag"}) {
    SCOPED_TRACE(name);
    const auto dataset = openDataset(bag(name), bagSettings());
    EXPECT_EQ(dataset->format(), "rosbag");
    EXPECT_EQ(dataset->size(), 32u);
    EXPECT_EQ(dataset->framesDropped(), 0u);
    EXPECT_TRUE(mapBytes(bag(name), bagSettings()) == expected);
  }
}

// sensor_msgs/CompressedImage, as image_transport records it: compressedDepth with PNG colour is
// lossless (the folder's map, byte for byte); JPEG colour keeps every point and moves colours by
// JPEG's loss only; beside the raw colour topic, its compressed transport is not a second
// candidate (the raw one is read).
TEST_F(RosBagTest, CompressedImageTopicsAreReadAsImageTransportWritesThem) {
  const auto expected = mapBytes(tum(), {});
  const std::vector<BagTopic> topics = listBag(bag("compressed_png.bag"));
  ASSERT_EQ(topics.size(), 4u);
  EXPECT_EQ(topics[1].name, "/camera/depth/image_raw/compressedDepth");
  EXPECT_EQ(topics[1].type, "sensor_msgs/CompressedImage");
  EXPECT_EQ(topics[1].encoding, "16UC1; compressedDepth png");
  EXPECT_EQ(topics[2].name, "/camera/rgb/image_raw/compressed");
  EXPECT_EQ(topics[2].encoding, "rgb8; png compressed bgr8");
  EXPECT_TRUE(mapBytes(bag("compressed_png.bag"), bagSettings()) == expected);
  EXPECT_TRUE(mapBytes(bag("raw_and_jpeg.bag"), bagSettings()) == expected);

  const auto from_tum = openDataset(tum());
  const auto from_jpeg = openDataset(bag("compressed_jpeg.bag"), bagSettings());
  ASSERT_EQ(from_jpeg->size(), from_tum->size());
  double error = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < from_tum->size(); i += 10) {
    const Frame a = from_tum->load(i), b = from_jpeg->load(i);
    ASSERT_EQ(a.cloud.size(), b.cloud.size());
    EXPECT_EQ(std::memcmp(a.cloud.points.data(), b.cloud.points.data(), a.cloud.size() * sizeof(a.cloud.points[0])), 0);
    ASSERT_EQ(a.cloud.colours.size(), b.cloud.colours.size());
    for (size_t p = 0; p < a.cloud.colours.size(); ++p, ++n) {
      error += std::abs(a.cloud.colours[p].r - b.cloud.colours[p].r) + std::abs(a.cloud.colours[p].g - b.cloud.colours[p].g) +
               std::abs(a.cloud.colours[p].b - b.cloud.colours[p].b);
    }
  }
  ASSERT_GT(n, 0u);
  EXPECT_LT(error / (3.0 * static_cast<double>(n)), 8.0);  // mean error per channel, 8-bit units, JPEG at quality 90
  EXPECT_GT(error, 0.0);                                    // it was the JPEG that was read
}

TEST_F(RosBagTest, FramesMatchTheTumReadersFrames) {
  const auto from_tum = openDataset(tum());
  const auto from_bag = openDataset(bag("pose_lz4.bag"), bagSettings());
  ASSERT_EQ(from_bag->size(), from_tum->size());
  for (size_t i = 0; i < from_tum->size(); i += 7) {
    const Frame a = from_tum->load(i), b = from_bag->load(i);
    EXPECT_TRUE(a.T_world_sensor.matrix() == b.T_world_sensor.matrix());
    EXPECT_NEAR(a.timestamp_s, b.timestamp_s, 1e-6);
    ASSERT_EQ(a.cloud.size(), b.cloud.size());
    EXPECT_EQ(std::memcmp(a.cloud.points.data(), b.cloud.points.data(), a.cloud.size() * sizeof(a.cloud.points[0])), 0);
    EXPECT_TRUE(a.cloud.colours == b.cloud.colours);
    EXPECT_NE(b.source.find("pose_lz4.bag: /camera/depth/image_raw at "), std::string::npos) << b.source;
  }
  EXPECT_NEAR(*from_bag->recordedAt(), *from_tum->recordedAt(), 1e-6);
}

// /tf: map -> odom (static), odom -> base_link sampled 10 ms either side of each frame, and
// base_link -> camera (static). Composing and interpolating moves the poses by rounding only
// (the generator composes in Python, the trajectory's quaternions have 9 digits): within 1e-8 m
// and 1e-8 rad of the TUM poses; the maps then hold the same voxels.
TEST_F(RosBagTest, TfPosesAreInterpolatedWithinATolerance) {
  const auto from_tum = openDataset(tum());
  DatasetSettings s = bagSettings();
  s.bag.fixed_frame = "map";
  const auto from_bag = openDataset(bag("tf.bag"), s);
  ASSERT_EQ(from_bag->size(), from_tum->size());
  for (size_t i = 0; i < from_tum->size(); ++i) {
    const Eigen::Isometry3d a = from_tum->poseOf(i), b = from_bag->poseOf(i);
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-8) << i;
    EXPECT_LT(Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle(), 1e-8) << i;
  }
  SessionSettings settings;
  const auto tum_map = integrateDataset(tum(), settings).map;
  settings.dataset = s;
  const auto bag_map = integrateDataset(bag("tf.bag"), settings).map;
  EXPECT_EQ(bag_map.counts().occupied_voxels, tum_map.counts().occupied_voxels);
  EXPECT_EQ(bag_map.counts().free_voxels, tum_map.counts().free_voxels);
}

// An odometry of the robot's base_link, the camera fixed to it through /tf_static: the pose of
// the base carried to the camera's frame.
TEST_F(RosBagTest, OdometryOfTheBaseIsCarriedToTheSensorThroughTf) {
  const auto from_tum = openDataset(tum());
  const auto from_bag = openDataset(bag("odometry_base.bag"), bagSettings());
  ASSERT_EQ(from_bag->size(), from_tum->size());
  for (size_t i = 0; i < from_tum->size(); ++i) {
    const Eigen::Isometry3d a = from_tum->poseOf(i), b = from_bag->poseOf(i);
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-8) << i;
    EXPECT_LT(Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle(), 1e-8) << i;
  }
}

// Simulated time: the first frame, its pose and the latched /tf_static are all at bag time 0.
// Every message counts, as in the same recording at wall-clock times.
TEST_F(RosBagTest, MessagesAtTimeZeroAreRead) {
  const std::vector<BagTopic> topics = listBag(bag("sim_time.bag"));
  std::map<std::string, uint64_t> counts;
  for (const BagTopic& t : topics) counts[t.name] = t.messages;
  EXPECT_EQ(counts["/camera/depth/image_raw"], 32u);
  EXPECT_EQ(counts["/odom"], 32u);
  EXPECT_EQ(counts["/tf_static"], 1u);
  const auto from_tum = openDataset(tum());
  const auto from_bag = openDataset(bag("sim_time.bag"), bagSettings());
  ASSERT_EQ(from_bag->size(), from_tum->size());
  EXPECT_EQ(from_bag->framesDropped(), 0u);
  for (size_t i = 0; i < from_tum->size(); ++i) {
    const Eigen::Isometry3d a = from_tum->poseOf(i), b = from_bag->poseOf(i);
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-8) << i;
  }
  EXPECT_EQ(from_bag->load(0).timestamp_s, 0.0);
}

TEST_F(RosBagTest, FramesWithoutAPoseAreDroppedAndCounted) {
  DatasetSettings s = bagSettings();
  s.bag.fixed_frame = "map";
  const auto dataset = openDataset(bag("tf_gaps.bag"), s);
  EXPECT_EQ(dataset->size(), 29u);
  EXPECT_EQ(dataset->framesDropped(), 3u);
  EXPECT_EQ(dataset->droppedReasons(), "3 without a pose within 0.1 s");
  // A tolerance below the 10 ms between a frame and its /tf samples leaves no frame.
  s.bag.pose_tolerance_s = 0.005;
  try {
    openDataset(bag("tf_gaps.bag"), s);
    FAIL() << "expected a DataError";
  } catch (const DataError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("tf_gaps.bag: none of the 32 frames"), std::string::npos) << what;
    EXPECT_NE(what.find("the images are in 'camera_depth_optical_frame'"), std::string::npos) << what;
    EXPECT_NE(what.find("32 without a pose within 0.005 s"), std::string::npos) << what;
  }
}

// 32FC1 metres and bgr8 colour: the same points up to the float rounding of the metres.
TEST_F(RosBagTest, FloatDepthAndBgrColourGiveTheSamePoints) {
  const auto from_tum = openDataset(tum());
  const auto from_bag = openDataset(bag("float_bgr.bag"));
  for (size_t i = 0; i < from_tum->size(); i += 5) {
    const Frame a = from_tum->load(i), b = from_bag->load(i);
    ASSERT_EQ(a.cloud.size(), b.cloud.size());
    EXPECT_TRUE(a.cloud.colours == b.cloud.colours);
    for (size_t p = 0; p < a.cloud.size(); ++p) {
      const bool valid = std::isfinite(a.cloud.points[p].z());
      ASSERT_EQ(valid, std::isfinite(b.cloud.points[p].z())) << p;
      if (valid) {
        ASSERT_LT((a.cloud.points[p] - b.cloud.points[p]).norm(), 1e-6f) << p;
      }
    }
  }
}

TEST_F(RosBagTest, NanDepthPixelsAreInvalidPoints) {
  const auto dataset = openDataset(bag("float_nan.bag"));
  const Frame f = dataset->load(0);
  const size_t half = size_t{f.cloud.width} * (f.cloud.height / 2);
  for (size_t p = 0; p < half; ++p) ASSERT_TRUE(std::isnan(f.cloud.points[p].z())) << p;
  SessionSettings s;
  const auto full = integrateDataset(tum(), s);
  const auto halved = integrateDataset(bag("float_nan.bag"), s);
  EXPECT_EQ(halved.stats.points + halved.stats.pointsSkipped(), full.stats.points + full.stats.pointsSkipped());
  EXPECT_GT(halved.stats.points_invalid, full.stats.points_invalid + full.stats.points / 3);
}

TEST_F(RosBagTest, PointCloud2TopicsGiveTheSamePointsAndColours) {
  const auto from_tum = openDataset(tum());
  const auto from_bag = openDataset(bag("points.bag"));
  ASSERT_EQ(from_bag->size(), from_tum->size());
  const Frame a = from_tum->load(4), b = from_bag->load(4);
  ASSERT_EQ(b.cloud.width, a.cloud.width);
  ASSERT_EQ(b.cloud.height, a.cloud.height);
  EXPECT_TRUE(a.cloud.colours == b.cloud.colours);
  for (size_t p = 0; p < a.cloud.size(); ++p) {
    if (std::isfinite(a.cloud.points[p].z())) {
      ASSERT_LT((a.cloud.points[p] - b.cloud.points[p]).norm(), 1e-6f) << p;
    }
  }
}

/// The message of the exception `body` throws as `E`, or a failure.
template <class E, class F>
std::string messageOf(F body) {
  try {
    body();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "no exception of the expected type";
  return {};
}

// A CameraInfo for 640 x 480 beside depth images of 160 x 120 (its intrinsics scaled with it):
// refused with both sizes, where it built a map of a few voxels; --intrinsics for the images
// reads the bag.
TEST_F(RosBagTest, ACameraInfoOfAnotherImageSizeIsRefused) {
  const auto dataset = openDataset(bag("info_640.bag"), bagSettings());
  const std::string what = messageOf<DataError>([&] { dataset->load(0); });
  EXPECT_NE(what.find("the depth image is 160 x 120 but the CameraInfo on /camera/depth/camera_info describes "
                      "640 x 480 images"),
            std::string::npos)
      << what;
  DatasetSettings s = bagSettings();
  const auto from_tum = openDataset(tum());
  s.intrinsics = readIntrinsicsFile(tum() / "camera-intrinsics.txt");
  const auto with_k = openDataset(bag("info_640.bag"), s);
  EXPECT_EQ(with_k->load(0).cloud.size(), from_tum->load(0).cloud.size());
}


TEST_F(RosBagTest, AmbiguousDepthTopicsAreRefusedWithTheCandidates) {
  const std::string what = messageOf<UsageError>([&] { openDataset(bag("two_depths.bag"), bagSettings()); });
  EXPECT_NE(what.find("two_depths.bag: 2 depth image topics (/camera/depth/image_raw, /camera2/depth/image_raw); "
                      "choose one with --depth-topic"),
            std::string::npos)
      << what;
  DatasetSettings s = bagSettings();
  s.bag.depth_topic = "/camera2/depth/image_raw";
  s.bag.info_topic = "/camera/depth/camera_info";
  EXPECT_EQ(openDataset(bag("two_depths.bag"), s)->size(), 32u);
}

TEST_F(RosBagTest, MissingTopicsAndPosesAreNamed) {
  DatasetSettings s = bagSettings();
  s.bag.depth_topic = "/nope";
  std::string what = messageOf<UsageError>([&] { openDataset(bag("pose_none.bag"), s); });
  EXPECT_NE(what.find("pose_none.bag: --depth-topic: no topic '/nope' in the bag (candidates: /camera/depth/image_raw, "
                      "/camera/rgb/image_raw)"),
            std::string::npos)
      << what;
  s = bagSettings();
  s.bag.pose_topic = "/camera/depth/camera_info";
  what = messageOf<UsageError>([&] { openDataset(bag("pose_none.bag"), s); });
  EXPECT_NE(what.find("'/camera/depth/camera_info' is a sensor_msgs/CameraInfo"), std::string::npos) << what;
  what = messageOf<DataError>([&] { openDataset(bag("no_pose.bag"), bagSettings()); });
  EXPECT_NE(what.find("no_pose.bag: no poses"), std::string::npos) << what;
  s = bagSettings();
  s.bag.fixed_frame = "map";  // but the bag has no /tf
  what = messageOf<DataError>([&] { openDataset(bag("no_pose.bag"), s); });
  EXPECT_NE(what.find("32 without a pose"), std::string::npos) << what;
  // A tf bag without --fixed-frame asks for it.
  what = messageOf<UsageError>([&] { openDataset(bag("tf.bag"), bagSettings()); });
  EXPECT_NE(what.find("--fixed-frame"), std::string::npos) << what;
}

TEST_F(RosBagTest, AColourTopicAsDepthIsAnUnknownEncoding) {
  DatasetSettings s = bagSettings();
  s.bag.depth_topic = "/camera/rgb/image_raw";
  s.bag.info_topic = "/camera/depth/camera_info";
  s.bag.colour_topic = "none";
  const auto dataset = openDataset(bag("pose_none.bag"), s);
  const std::string what = messageOf<DataError>([&] { dataset->load(0); });
  EXPECT_NE(what.find("pose_none.bag: /camera/rgb/image_raw at "), std::string::npos) << what;
  EXPECT_NE(what.find("depth encoding 'rgb8' is not read"), std::string::npos) << what;
}

TEST_F(RosBagTest, TruncatedAndForeignFilesAreFormatErrorsNamingTheFile) {
  for (const char* name : {"pose_none.bag", "pose_lz4.bag", "pose_bz2.bag"}) {
    const auto bytes = test::bytesOf(bag(name));
    for (const size_t keep : {size_t{0}, size_t{13}, size_t{4096}, bytes.size() / 2, bytes.size() - 100}) {
      const fs::path cut = *dir_ / "cut.bag";
      test::writeBytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<long>(keep)));
      SCOPED_TRACE(std::string(name) + " cut to " + std::to_string(keep));
      const std::string what = messageOf<FormatError>([&] { openDataset(cut, bagSettings()); });
      EXPECT_EQ(what.rfind(cut.string() + ": ", 0), 0u) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  const fs::path text = *dir_ / "text.bag";
  test::writeBytes(text, std::string("#ROSBAG V1.2\nnot really\n"));
  EXPECT_THROW(listBag(text), FormatError);
  EXPECT_THROW(listBag(*dir_ / "missing.bag"), UsageError);
}

// librosbag trusts record lengths inside chunks and the index; checkBagStructure refuses a bag
// whose framing is broken before librosbag reads it.
TEST_F(RosBagTest, CorruptChunksAreFormatErrorsNotCrashes) {
  auto bytes = test::bytesOf(bag("tiny/none.bag"));
  const std::string text(bytes.begin(), bytes.end());
  const size_t size = text.find("size=", text.find("compression=none"));
  ASSERT_NE(size, std::string::npos);
  bytes[size + 5] ^= 0x01;  // the chunk's size field, one byte off
  const fs::path bad = *dir_ / "bad_size.bag";
  test::writeBytes(bad, bytes);
  std::string what = messageOf<FormatError>([&] { openDataset(bad, bagSettings()); });
  EXPECT_NE(what.find("bad_size.bag: not a readable ROS 1 bag: at byte "), std::string::npos) << what;
  EXPECT_NE(what.find("size field does not match"), std::string::npos) << what;
  // Bit flips anywhere (the fuzz target's kind of input, with a fixed seed): each reads, or is
  // refused with a chronomap error; none may crash.
  uint64_t state = 12345;
  const auto next = [&] { return state = state * 6364136223846793005ull + 1442695040888963407ull; };
  for (const char* name : {"tiny/none.bag", "tiny/lz4.bag", "tiny/bz2.bag", "tiny/tf.bag", "tiny/float.bag"}) {
    const auto seed = test::bytesOf(bag(name));
    for (int round = 0; round < 100; ++round) {
      auto mutated = seed;
      for (int flip = 0; flip < 4; ++flip)
        mutated[(next() >> 33) % mutated.size()] ^= static_cast<uint8_t>(1u << ((next() >> 33) % 8));
      // Every other round, four 0xff bytes somewhere: a length or offset far past its buffer.
      const size_t at = (next() >> 33) % mutated.size();
      for (size_t k = at; k < at + 4 && k < mutated.size() && round % 2 == 0; ++k) mutated[k] = 0xff;
      const fs::path path = *dir_ / "mutated.bag";
      test::writeBytes(path, mutated);
      try {
        DatasetSettings s;
        s.bag.fixed_frame = std::string(name) == "tiny/tf.bag" ? "map" : "";
        const auto dataset = openDataset(path, s);
        for (size_t i = 0; i < dataset->size(); ++i) dataset->load(i);
      } catch (const Error&) {
      }
    }
  }
}

// Found by fuzz_bag (2026-12-05): a connection record's data is a header of its own (topic, type,
// md5sum, message_definition) that librosbag's ros::Header::parse reads without checking a
// field's length against the data: a length past it read beyond the buffer (heap overflow under
// AddressSanitizer). checkBagStructure checks those fields too, inside chunks and at the top level.
TEST_F(RosBagTest, AConnectionHeaderFieldPastItsDataIsAFormatError) {
  const auto seed = test::bytesOf(bag("tiny/none.bag"));
  const std::string text(seed.begin(), seed.end());
  const size_t first = text.find("md5sum="), last = text.rfind("md5sum=");
  ASSERT_NE(first, std::string::npos);
  ASSERT_LT(first, last) << "a connection in the chunk and one after the index";
  for (const size_t at : {first, last}) {
    auto bytes = seed;
    const uint32_t huge = 9767;  // the length fuzz_bag found: past the connection's 2,199 bytes
    std::memcpy(bytes.data() + at - 4, &huge, 4);
    const fs::path bad = *dir_ / "bad_connection.bag";
    test::writeBytes(bad, bytes);
    SCOPED_TRACE("md5sum field at byte " + std::to_string(at));
    const std::string what = messageOf<FormatError>([&] { openDataset(bad, bagSettings()); });
    EXPECT_NE(what.find("bad_connection.bag: not a readable ROS 1 bag: at byte "), std::string::npos) << what;
    EXPECT_NE(what.find("a connection's header's field runs past it"), std::string::npos) << what;
    EXPECT_THROW(listBag(bad), FormatError);
  }
}

TEST_F(RosBagTest, TheCommandLineListsAndIntegratesABag) {
  const auto listed = test::runCommand(test::cli() + " integrate " + bag("tf.bag").string() + " --list");
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_NE(listed.out.find("/camera/depth/image_raw  sensor_msgs/Image  32 message(s)  16UC1"), std::string::npos)
      << listed.out;
  const fs::path out = *dir_ / "gaps.cmap";
  const auto run = test::runCommand(test::cli() + " integrate " + bag("tf_gaps.bag").string() +
                                    " --fixed-frame map --depth-scale 5000 -o " + out.string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("integrated 29 frame(s)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("3 frame(s) dropped (3 without a pose within 0.1 s)"), std::string::npos) << run.out;
  // build takes bags as it takes folders, the topic flags applying to each.
  const fs::path map = *dir_ / "two.cmap";
  const auto built =
      test::runCommand(test::cli() + " build " + map.string() + " " + bag("tf_gaps.bag").string() + " " +
                       bag("tf.bag").string() + " --fixed-frame map --depth-scale 5000 --times 1000000000,1000086400");
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_TRUE(fs::exists(map));
  const auto missing = test::runCommand(test::cli() + " integrate " + bag("tf.bag").string() + " -o " + out.string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("--fixed-frame"), std::string::npos) << missing.err;
}

// The 3DMatch frames of ../shared/data as a bag (depth in millimetres, the bag's default units;
// poses as quaternions computed like Eigen does from the matrices): the same frames and map.
TEST_F(RosBagTest, RealThreeDMatchFramesFromABagGiveTheFoldersMap) {
  CHRONOMAP_REQUIRE_DATA(root, "3dmatch/3dmatch");
  const fs::path real = *dir_ / "3dmatch.bag";
  const auto made = test::runCommand(std::string(kDebianPython) + " " + CHRONOMAP_SOURCE_DIR +
                                     "/tests/ingest/ros/make_ros1_bags.py --3dmatch " + (root / "seq-01").string() + " " +
                                     (root / "camera-intrinsics.txt").string() + " " + real.string());
  ASSERT_EQ(made.exit_code, 0) << made.err;
  const auto from_folder = openDataset(root);
  const auto from_bag = openDataset(real);
  ASSERT_EQ(from_bag->size(), from_folder->size());
  for (size_t i = 0; i < from_folder->size(); ++i) {
    const Eigen::Isometry3d a = from_folder->poseOf(i), b = from_bag->poseOf(i);
    EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), 1e-12) << i;
  }
  const Frame a = from_folder->load(1), b = from_bag->load(1);
  EXPECT_EQ(std::memcmp(a.cloud.points.data(), b.cloud.points.data(), a.cloud.size() * sizeof(a.cloud.points[0])), 0);
  EXPECT_TRUE(a.cloud.colours == b.cloud.colours);
  SessionSettings s;
  const auto folder_map = integrateDataset(root, s).map;
  const auto bag_map = integrateDataset(real, s).map;
  EXPECT_EQ(bag_map.counts().occupied_voxels, folder_map.counts().occupied_voxels);
  EXPECT_EQ(bag_map.counts().free_voxels, folder_map.counts().free_voxels);
  RecordProperty("byte_identical", encodeSessionMap(bag_map, {}) == encodeSessionMap(folder_map, {}) ? "yes" : "no");
}

// ---------------------------------------------------------------- messages and poses, analytic

TEST(RosMessages, ReadsBigEndianDepthAndPaddedRows) {
  // 2 x 2 16UC1, big-endian, rows padded to 6 bytes: 1000, 2000 / 0, 4000 millimetres.
  const std::vector<uint8_t> data{0x03, 0xE8, 0x07, 0xD0, 0xAA, 0xAA, 0x00, 0x00, 0x0F, 0xA0, 0xAA, 0xAA};
  const rosmsg::ImageView im{2, 2, "16UC1", true, 6, data};
  const PointCloud c = rosmsg::depthCloud(im, nullptr, {1, 1, 0, 0}, 1000.0, "t");
  EXPECT_FLOAT_EQ(c.points[0].z(), 1.0f);
  EXPECT_FLOAT_EQ(c.points[1].z(), 2.0f);
  EXPECT_TRUE(std::isnan(c.points[2].z()));
  EXPECT_FLOAT_EQ(c.points[3].z(), 4.0f);
  EXPECT_FLOAT_EQ(c.points[3].x(), 4.0f);  // (u - cx) * z / fx
}

TEST(RosMessages, ShortBuffersAndUnknownEncodingsAreDataErrors) {
  const std::vector<uint8_t> data(7);
  EXPECT_THROW(rosmsg::depthCloud({2, 2, "16UC1", false, 4, data}, nullptr, {1, 1, 0, 0}, 1000.0, "t"), DataError);
  EXPECT_THROW(rosmsg::depthCloud({1, 2, "16UC1", false, 2, data}, nullptr, {1, 1, 0, 0}, 1000.0, "t"), DataError);
  EXPECT_THROW(rosmsg::colourImage({1, 1, "yuv422", false, 2, data}, "t"), DataError);
  rosmsg::CloudView cloud{1, 2, {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}}, false, 12, 24, data};
  EXPECT_THROW(rosmsg::pointCloud(cloud, "t"), DataError);  // 24 bytes claimed, 7 held
  cloud.fields.pop_back();
  EXPECT_THROW(rosmsg::pointCloud(cloud, "t"), DataError);  // no z
}

Eigen::Isometry3d pose(double x, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, 0, 0);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

TEST(PoseAt, InterpolatesBetweenSamplesWithinTheTolerance) {
  const std::vector<TimedPose> samples{{1.0, pose(0.0, 0.0)}, {1.1, pose(1.0, 0.2)}, {3.0, pose(5.0, 0.0)}};
  const auto mid = poseAt(samples, 1.075, 0.1);
  ASSERT_TRUE(mid);
  EXPECT_NEAR(mid->translation().x(), 0.75, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(mid->linear()).angle(), 0.15, 1e-12);
  EXPECT_TRUE(poseAt(samples, 1.1, 0.0)->matrix() == samples[1].pose.matrix());   // exact time: the sample's numbers
  EXPECT_FALSE(poseAt(samples, 2.0, 0.1));                                        // in a 1.9 s gap
  EXPECT_TRUE(poseAt(samples, 3.05, 0.1)->matrix() == samples[2].pose.matrix());  // just after the last
  EXPECT_FALSE(poseAt(samples, 3.2, 0.1));
  EXPECT_FALSE(poseAt(samples, 0.8, 0.1));
  EXPECT_FALSE(poseAt({}, 1.0, 0.1));
}

// A loop or a frame with two parents is a broken tree, said as such (it was "no pose" before).
TEST(TransformTree, LoopsAndSecondParentsAreRefusedNamingTheFrames) {
  const auto message = [](const std::function<void()>& body) -> std::string {
    try {
      body();
    } catch (const DataError& e) {
      return e.what();
    }
    return "(accepted)";
  };
  EXPECT_EQ(message([] {
              TransformTree tree;
              tree.add("map", "odom", 0.0, pose(1.0, 0.0), true, "bag: /tf_static");
              tree.add("base", "odom", 1.0, pose(1.0, 0.0), false, "bag: /tf base -> odom");
            }),
            "bag: /tf base -> odom: frame 'odom' has two parents, 'map' and 'base' (a transform tree gives each "
            "frame one parent; record one of them under another name)");
  EXPECT_NE(message([] {
              TransformTree tree;
              tree.add("odom", "odom", 0.0, pose(1.0, 0.0), true);
            }).find("frame 'odom' is given itself as its parent"),
            std::string::npos);
  const std::string loop = message([] {
    TransformTree tree;
    tree.add("map", "odom", 0.0, pose(1.0, 0.0), true);
    tree.add("odom", "base", 0.0, pose(1.0, 0.0), true);
    tree.add("base", "map", 0.0, pose(1.0, 0.0), true);
    tree.add("base", "camera", 0.0, pose(1.0, 0.0), true);
    tree.finish("bag: /tf");
  });
  EXPECT_EQ(loop.rfind("bag: /tf: the transforms form a loop (", 0), 0u) << loop;
  for (const char* frame : {"map", "odom", "base"}) EXPECT_NE(loop.find(frame), std::string::npos) << loop;
  EXPECT_EQ(loop.find("camera"), std::string::npos) << loop;
}

TEST(TransformTree, ChainsThroughTheCommonAncestor) {
  TransformTree tree;
  tree.add("map", "odom", 0.0, pose(1.0, 0.0), true);
  tree.add("odom", "base", 10.0, pose(0.0, 0.0), false);
  tree.add("odom", "base", 11.0, pose(2.0, 0.0), false);
  tree.add("base", "camera", 0.0, pose(0.5, M_PI / 2), true);
  tree.add("map", "landmark", 0.0, pose(-3.0, 0.0), true);
  tree.finish();
  const auto T = tree.lookup("map", "camera", 10.5, 0.6);
  ASSERT_TRUE(T);
  EXPECT_NEAR(T->translation().x(), 1.0 + 1.0 + 0.5, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(T->linear()).angle(), M_PI / 2, 1e-12);
  // Across branches: the camera seen from the landmark.
  const auto L = tree.lookup("landmark", "camera", 10.5, 0.6);
  ASSERT_TRUE(L);
  EXPECT_NEAR(L->translation().x(), 2.5 + 3.0, 1e-12);
  EXPECT_FALSE(tree.lookup("map", "camera", 10.5, 0.4));  // both samples 0.5 s away
  EXPECT_FALSE(tree.lookup("map", "elsewhere", 10.5, 0.6));
  EXPECT_EQ(tree.roots(), std::set<std::string>{"map"});
  EXPECT_EQ(tree.frames().size(), 5u);
}

}  // namespace
}  // namespace chronomap
