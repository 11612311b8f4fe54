// ROS 2 bags: MCAP files written by npm's @mcap/core with @foxglove/rosmsg2-serialization's CDR
// (tests/ingest/ros/ros2_writer/make_ros2_bags.mjs) from a simulated TUM session, SQLite .db3 bags
// written here through SQLite with rosbag2's schema, read back and compared with the TUM
// reader's frames and map (and a ROS 1 bag's, where this build reads them).

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>

#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/rosbag.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"
#include "ingest/ros/cdr.h"
#include "ingest/ros/ros_messages.h"
#include "ingest/ros/mcap.h"
#include "bag_fixture.h"
#include "db3_writer.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

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

/// A rosbag2 SQLite bag with the messages of an MCAP bag (db3_writer.h), or a failure.
void writeDb3(const fs::path& mcap_path, const fs::path& db3, const std::map<std::string, std::string>& formats = {}) {
  try {
    test::writeDb3(mcap_path, db3, formats);
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
}

/// A rosbag2 bag folder: the storage file and metadata.yaml naming it.
void writeBagFolder(const fs::path& folder, const fs::path& storage, const std::string& identifier) {
  fs::create_directories(folder);
  fs::copy_file(storage, folder / storage.filename(), fs::copy_options::overwrite_existing);
  std::ofstream(folder / "metadata.yaml") << "rosbag2_bagfile_information:\n"
                                          << "  version: 8\n"
                                          << "  storage_identifier: " << identifier << "\n"
                                          << "  relative_file_paths:\n"
                                          << "    - " << storage.filename().string() << "\n"
                                          << "  message_count: 128\n";
}

/// The shared recordings (bag_fixture.h; the MCAP bags need node and npm) and, in the suite's
/// scratch folder, the SQLite bags and bag folders this file writes from them.
class Ros2BagTest : public BagFixture<Ros2BagTest> {
 public:
  static constexpr const char* kWriters = "node or npm";
  static constexpr const char* kErrorFile = "ros2.error";

 protected:
  static void SetUpTestSuite() {
    BagFixture::SetUpTestSuite();
    if (!generator_error_.empty()) return;
    writeDb3(bag("pose_lz4.mcap"), *dir_ / "pose.db3");
    writeDb3(bag("tf.mcap"), *dir_ / "tf.db3");
    writeBagFolder(*dir_ / "pose_db3_folder", *dir_ / "pose.db3", "sqlite3");
    writeBagFolder(*dir_ / "pose_mcap_folder", bag("pose_zstd.mcap"), "mcap");
  }
  /// A bag this suite wrote, or else one of the shared recordings.
  static fs::path bag(const std::string& name) {
    return fs::exists(*dir_ / name) ? *dir_ / name : BagFixture::bag(name);
  }
};

TEST_F(Ros2BagTest, ListsTopicsWithRos2TypesCountsAndEncodings) {
  for (const char* name : {"pose_lz4.mcap", "pose_unchunked_nosummary.mcap", "pose.db3", "pose_db3_folder"}) {
    SCOPED_TRACE(name);
    const std::vector<BagTopic> topics = listBag(bag(name));
    ASSERT_EQ(topics.size(), 4u);
    EXPECT_EQ(topics[0].name, "/camera/depth/camera_info");
    EXPECT_EQ(topics[0].type, "sensor_msgs/msg/CameraInfo");
    EXPECT_EQ(topics[1].name, "/camera/depth/image_raw");
    EXPECT_EQ(topics[1].type, "sensor_msgs/msg/Image");
    EXPECT_EQ(topics[1].encoding, "16UC1");
    EXPECT_EQ(topics[1].messages, 32u);
    EXPECT_EQ(topics[2].encoding, "rgb8");
    EXPECT_EQ(topics[3].name, "/camera_pose");
    EXPECT_EQ(topics[3].type, "geometry_msgs/msg/PoseStamped");
  }
  const std::vector<BagTopic> tf = listBag(bag("tf.mcap"));
  ASSERT_EQ(tf.size(), 5u);
  EXPECT_EQ(tf[3].name, "/tf");
  EXPECT_EQ(tf[3].messages, 64u);  // two samples around every frame
  EXPECT_EQ(tf[4].type, "tf2_msgs/msg/TFMessage");
}

// The same depth numbers, colour and pose numbers give the same map, byte for byte, whatever
// the storage (MCAP unchunked, chunks stored plain, lz4 or zstd, with or without the summary;
// SQLite; a bag folder) and from an Odometry as from a PoseStamped topic.
TEST_F(Ros2BagTest, PoseTopicBagsGiveTheTumFoldersMapByteForByte) {
  const auto expected = mapBytes(tum(), {});
  for (const char* name : {"pose_unchunked.mcap", "pose_unchunked_nosummary.mcap", "pose_none.mcap", "pose_lz4.mcap",
                           "pose_zstd.mcap", "pose_zstd_nosummary.mcap", "odometry.mcap", "pose.db3",
                           "pose_db3_folder", "pose_mcap_folder"}) {
    SCOPED_TRACE(name);
    const auto dataset = openDataset(bag(name), bagSettings());
    EXPECT_EQ(dataset->format(), "ros2bag");
    EXPECT_EQ(dataset->size(), 32u);
    EXPECT_EQ(dataset->framesDropped(), 0u);
    EXPECT_TRUE(mapBytes(bag(name), bagSettings()) == expected);
  }
}

// sensor_msgs/CompressedImage: compressedDepth (a 12-byte header and the TUM folder's 16-bit
// PNG) and PNG colour (the folder's file) are lossless, so the map is the folder's, byte for byte;
// the CameraInfo is found beside the transports' base topics.
TEST_F(Ros2BagTest, CompressedImageTopicsGiveTheTumFoldersMapByteForByte) {
  const std::vector<BagTopic> topics = listBag(bag("compressed.mcap"));
  ASSERT_EQ(topics.size(), 4u);
  EXPECT_EQ(topics[1].name, "/camera/depth/image_raw/compressedDepth");
  EXPECT_EQ(topics[1].type, "sensor_msgs/msg/CompressedImage");
  EXPECT_EQ(topics[1].encoding, "16UC1; compressedDepth png");
  EXPECT_EQ(topics[2].name, "/camera/rgb/image_raw/compressed");
  EXPECT_EQ(topics[2].encoding, "rgb8; png compressed bgr8");
  const auto dataset = openDataset(bag("compressed.mcap"), bagSettings());
  EXPECT_EQ(dataset->size(), 32u);
  EXPECT_EQ(dataset->framesDropped(), 0u);
  EXPECT_TRUE(mapBytes(bag("compressed.mcap"), bagSettings()) == mapBytes(tum(), {}));
}

TEST_F(Ros2BagTest, FramesMatchTheTumReadersAndAFrameDecodesTheSameFromEveryStorage) {
  const auto from_tum = openDataset(tum());
  const auto from_mcap = openDataset(bag("pose_zstd.mcap"), bagSettings());
  const auto from_db3 = openDataset(bag("pose.db3"), bagSettings());
  ASSERT_EQ(from_mcap->size(), from_tum->size());
  for (size_t i = 0; i < from_tum->size(); i += 7) {
    const Frame a = from_tum->load(i), b = from_mcap->load(i), c = from_db3->load(i);
    EXPECT_TRUE(a.T_world_sensor.matrix() == b.T_world_sensor.matrix());
    EXPECT_NEAR(a.timestamp_s, b.timestamp_s, 1e-6);
    ASSERT_EQ(a.cloud.size(), b.cloud.size());
    ASSERT_EQ(b.cloud.size(), c.cloud.size());
    // Compared as bytes: invalid depth pixels are NaN points in both.
    const size_t bytes = a.cloud.size() * sizeof(a.cloud.points[0]);
    EXPECT_EQ(std::memcmp(a.cloud.points.data(), b.cloud.points.data(), bytes), 0);
    EXPECT_EQ(std::memcmp(b.cloud.points.data(), c.cloud.points.data(), bytes), 0);
    EXPECT_TRUE(b.cloud.colours == c.cloud.colours);
    EXPECT_NE(b.source.find("pose_zstd.mcap: /camera/depth/image_raw at "), std::string::npos) << b.source;
    EXPECT_TRUE(a.cloud.colours == b.cloud.colours);
  }
}

// PointCloud2 (x, y, z FLOAT32 computed from the depth image in JavaScript, packed rgb): the
// TUM reader's points within 1e-6 m and its colours exactly.
TEST_F(Ros2BagTest, PointCloud2TopicsGiveTheSamePointsAndColours) {
  const auto from_tum = openDataset(tum());
  const auto from_bag = openDataset(bag("points.mcap"));
  ASSERT_EQ(from_bag->size(), from_tum->size());
  const Frame a = from_tum->load(4), b = from_bag->load(4);
  ASSERT_EQ(b.cloud.width, a.cloud.width);
  ASSERT_EQ(b.cloud.height, a.cloud.height);
  EXPECT_TRUE(a.cloud.colours == b.cloud.colours);
  size_t finite = 0;
  for (size_t p = 0; p < a.cloud.size(); ++p) {
    EXPECT_EQ(std::isfinite(a.cloud.points[p].z()), std::isfinite(b.cloud.points[p].z())) << p;
    if (std::isfinite(a.cloud.points[p].z())) {
      ++finite;
      ASSERT_LT((a.cloud.points[p] - b.cloud.points[p]).norm(), 1e-6f) << p;
    }
  }
  EXPECT_GT(finite, a.cloud.size() / 2);
}

// The ROS 1 bag of the same frames (Debian's python3-rosbag) gives the same map as well.
TEST_F(Ros2BagTest, TheRos1BagOfTheSameFramesGivesTheSameMap) {
  if (!rosBagSupported()) GTEST_SKIP() << "built without ROS 1 bags";
  ASSERT_TRUE(fs::exists(bag("pose_lz4.bag"))) << "the shared ROS 1 bags are missing: see " << recordings();
  EXPECT_TRUE(mapBytes(bag("pose_lz4.bag"), bagSettings()) == mapBytes(bag("pose_lz4.mcap"), bagSettings()));
}

// /tf: map -> odom static, odom -> base_link sampled 10 ms either side of each frame, base_link
// -> camera static; the composed, interpolated pose agrees with the TUM pose to 1e-8 (m, rad).
TEST_F(Ros2BagTest, TfPosesAreInterpolatedWithinATolerance) {
  const auto from_tum = openDataset(tum());
  DatasetSettings s = bagSettings();
  s.bag.fixed_frame = "map";
  for (const char* name : {"tf.mcap", "tf.db3"}) {
    SCOPED_TRACE(name);
    const auto from_bag = openDataset(bag(name), s);
    ASSERT_EQ(from_bag->size(), from_tum->size());
    for (size_t i = 0; i < from_tum->size(); ++i) {
      const Eigen::Isometry3d a = from_tum->poseOf(i), b = from_bag->poseOf(i);
      EXPECT_LT((a.translation() - b.translation()).norm(), 1e-8) << i;
      EXPECT_LT(Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle(), 1e-8) << i;
    }
  }
  // Outside the tolerance (the samples lie 10 ms from each frame), no frame has a pose.
  s.bag.pose_tolerance_s = 0.005;
  const std::string what = messageOf<DataError>([&] { openDataset(bag("tf.mcap"), s); });
  EXPECT_NE(what.find("none of the 32 frames"), std::string::npos) << what;
  EXPECT_NE(what.find("32 without a pose within 0.005 s"), std::string::npos) << what;
}

// The summary's chunk indexes lead the reading when present; without them the data section is
// scanned; both meet the same messages with the same bytes.
TEST_F(Ros2BagTest, TheSummaryIsUsedWhenPresentAndTheFileScannedOtherwise) {
  const auto contents = [](const fs::path& path, bool expect_indexed) {
    mcap::Reader reader(path);
    EXPECT_EQ(reader.indexed(), expect_indexed) << path;
    std::vector<std::pair<std::string, std::vector<uint8_t>>> out;
    std::vector<mcap::MessageRef> refs;
    reader.forEachMessage([&](const mcap::Message& m) {
      out.emplace_back(reader.channels().at(m.channel).topic, std::vector<uint8_t>(m.data.begin(), m.data.end()));
      refs.push_back(m.ref);
    });
    // Reading a message again by its reference gives its bytes.
    for (size_t i = 0; i < refs.size(); i += 11) {
      const auto again = reader.message(refs[i]);
      EXPECT_TRUE(std::vector<uint8_t>(again.data.begin(), again.data.end()) == out[i].second) << i;
    }
    return out;
  };
  const auto reference = contents(bag("pose_unchunked_nosummary.mcap"), false);
  EXPECT_EQ(reference.size(), 128u);
  EXPECT_TRUE(contents(bag("pose_unchunked.mcap"), false) == reference);  // a summary without chunk indexes
  EXPECT_TRUE(contents(bag("pose_none.mcap"), true) == reference);
  EXPECT_TRUE(contents(bag("pose_lz4.mcap"), true) == reference);
  EXPECT_TRUE(contents(bag("pose_zstd.mcap"), true) == reference);
  EXPECT_TRUE(contents(bag("pose_zstd_nosummary.mcap"), false) == reference);
}

/// The offset of the first chunk record (opcode 0x06) of an MCAP file, found by walking the
/// data section's records.
size_t firstChunk(const std::vector<uint8_t>& bytes) {
  size_t pos = 8;
  while (pos + 9 <= bytes.size()) {
    uint64_t len = 0;
    std::memcpy(&len, &bytes[pos + 1], 8);
    if (bytes[pos] == 0x06) return pos;
    pos += 9 + len;
  }
  ADD_FAILURE() << "no chunk";
  return 0;
}

// A bag cut short (a recorder killed, a copy interrupted) is read up to the cut, as `mcap
// recover` would, and says what was lost; before, it was refused whole ("no MCAP magic at the
// end"). Chunked and unchunked, with and without a summary.
TEST_F(Ros2BagTest, ATruncatedMcapIsReadUpToTheCutAndSaysWhatWasLost) {
  for (const char* name : {"pose_none.mcap", "pose_lz4.mcap", "pose_zstd_nosummary.mcap", "pose_unchunked.mcap"}) {
    const auto bytes = test::bytesOf(bag(name));
    const auto whole = openDataset(bag(name), bagSettings());
    for (const size_t keep : {bytes.size() / 2, bytes.size() - 100}) {
      SCOPED_TRACE(std::string(name) + " cut to " + std::to_string(keep));
      const fs::path cut = *dir_ / "cut.mcap";
      test::writeBytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<long>(keep)));
      const auto dataset = openDataset(cut, bagSettings());
      EXPECT_GT(dataset->size(), 0u);
      EXPECT_NE(dataset->droppedReasons().find("cut.mcap cut short (no MCAP magic at its end)"), std::string::npos)
          << dataset->droppedReasons();
      std::string note;
      listBag(cut, &note);
      EXPECT_NE(note.find("cut short"), std::string::npos) << note;
      if (keep == bytes.size() / 2) {
        EXPECT_LT(dataset->size(), whole->size());
        EXPECT_NE(dataset->droppedReasons().find("bytes (an incomplete record) are lost"), std::string::npos);
      }
      // What was read is what the whole file holds, frame for frame.
      for (size_t i = 0; i < dataset->size(); i += 5) {
        EXPECT_EQ(dataset->load(i).cloud.points.size(), whole->load(i).cloud.points.size()) << i;
        EXPECT_TRUE(dataset->poseOf(i).isApprox(whole->poseOf(i))) << i;
      }
    }
  }
}

TEST_F(Ros2BagTest, TruncatedAndCorruptFilesAreOneLineFormatErrorsNamingTheFile) {
  const auto expectError = [&](const fs::path& path, const std::string& problem) {
    SCOPED_TRACE(path.filename().string() + ": " + problem);
    const std::string what = messageOf<FormatError>([&] { openDataset(path, bagSettings()); });
    EXPECT_EQ(what.rfind(path.string() + ": ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_NE(what.find(problem), std::string::npos) << what;
  };
  for (const char* name : {"pose_none.mcap", "pose_lz4.mcap", "pose_zstd_nosummary.mcap", "pose_unchunked.mcap"}) {
    const auto bytes = test::bytesOf(bag(name));
    for (const size_t keep : {size_t{0}, size_t{13}}) {
      const fs::path cut = *dir_ / "cut.mcap";
      test::writeBytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<long>(keep)));
      SCOPED_TRACE(std::string(name) + " cut to " + std::to_string(keep));
      const std::string what = messageOf<FormatError>([&] { openDataset(cut, bagSettings()); });
      EXPECT_EQ(what.rfind(cut.string() + ": ", 0), 0u) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  // Nothing intact but the header and a piece of the first chunk: no frames, said as such.
  {
    const auto bytes = test::bytesOf(bag("pose_none.mcap"));
    test::writeBytes(*dir_ / "cut.mcap", std::vector<uint8_t>(bytes.begin(), bytes.begin() + 4096));
    const std::string what = messageOf<Error>([&] { openDataset(*dir_ / "cut.mcap", bagSettings()); });
    EXPECT_EQ(what.rfind((*dir_ / "cut.mcap").string() + ": ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  // One byte of an uncompressed chunk's data changed: its CRC no longer matches.
  {
    auto bytes = test::bytesOf(bag("pose_none.mcap"));
    bytes[firstChunk(bytes) + 2000] ^= 0x10;
    test::writeBytes(*dir_ / "bad_crc.mcap", bytes);
    expectError(*dir_ / "bad_crc.mcap", "the chunk's CRC does not match its data");
  }
  // A chunk whose stated uncompressed size is one byte off, and one whose records' length runs
  // past the record.
  {
    const auto good = test::bytesOf(bag("pose_none.mcap"));
    const size_t chunk = firstChunk(good);
    auto bytes = good;
    bytes[chunk + 9 + 16] ^= 0x01;  // uncompressed_size
    test::writeBytes(*dir_ / "bad_size.mcap", bytes);
    expectError(*dir_ / "bad_size.mcap", "states");
    bytes = good;
    uint32_t compression_len = 0;
    std::memcpy(&compression_len, &bytes[chunk + 9 + 28], 4);
    bytes[chunk + 9 + 32 + compression_len + 7] = 0x7f;  // records length: far past the file
    test::writeBytes(*dir_ / "bad_length.mcap", bytes);
    expectError(*dir_ / "bad_length.mcap", "a field needs");
  }
  // An lz4 chunk with a claim no lz4 frame can reach (refused before allocating), and an
  // unknown compression.
  {
    auto bytes = test::bytesOf(bag("pose_lz4.mcap"));
    const size_t chunk = firstChunk(bytes);
    bytes[chunk + 9 + 16 + 5] = 0x7f;  // uncompressed_size around 500 TB
    test::writeBytes(*dir_ / "bomb.mcap", bytes);
    expectError(*dir_ / "bomb.mcap", "more than lz4 can pack");
    bytes = test::bytesOf(bag("pose_lz4.mcap"));
    bytes[chunk + 9 + 32 + 2] = '5';  // "lz4" -> "lz5"
    test::writeBytes(*dir_ / "lz5.mcap", bytes);
    expectError(*dir_ / "lz5.mcap", "unknown chunk compression 'lz5'");
  }
  // A messages table in another serialisation than CDR.
  writeDb3(bag("pose_lz4.mcap"), *dir_ / "json.db3", {{"/camera_pose", "json"}});
  expectError(*dir_ / "json.db3", "/camera_pose is encoded as 'json'; chronomap decodes ROS 2 messages in CDR only");
  // A .db3 cut short (SQLite's own checks name the damage), and an SQLite file that is no bag.
  {
    const auto bytes = test::bytesOf(bag("pose.db3"));
    for (const size_t keep : {size_t{100}, size_t{4096}, bytes.size() / 2}) {
      SCOPED_TRACE("pose.db3 cut to " + std::to_string(keep));
      const fs::path cut = *dir_ / "cut.db3";
      test::writeBytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<long>(keep)));
      const std::string what = messageOf<FormatError>([&] { openDataset(cut, bagSettings()); });
      EXPECT_EQ(what.rfind(cut.string() + ": ", 0), 0u) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
    const fs::path other = *dir_ / "other.db3";
    fs::copy_file(bag("pose.db3"), other);
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(other.c_str(), &db), SQLITE_OK);
    EXPECT_EQ(sqlite3_exec(db, "DROP TABLE topics", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
    expectError(other, "not a rosbag2 SQLite bag (no table 'topics')");
  }
  // Bytes computed when read instead of stored: a 16 KiB file whose every message is a
  // generated zeroblob of 900 MB (it drove --list to 1.78 GB resident), and a virtual table.
  const std::vector<std::pair<std::string, std::string>> computed = {
      {"data BLOB GENERATED ALWAYS AS (zeroblob(900000000)) VIRTUAL", "column messages.data is generated"},
      {"data BLOB, big BLOB GENERATED ALWAYS AS (zeroblob(16)) STORED", "column messages.big is generated"},
  };
  for (const auto& [column, problem] : computed) {
    const fs::path generated = *dir_ / "generated.db3";
    fs::remove(generated);
    fs::copy_file(bag("pose.db3"), generated);
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(generated.c_str(), &db), SQLITE_OK);
    const std::string sql = "ALTER TABLE messages RENAME TO stored; CREATE TABLE messages(id INTEGER PRIMARY KEY, "
                            "topic_id INTEGER, timestamp INTEGER, " + column + "); INSERT INTO messages(id, "
                            "topic_id, timestamp) SELECT id, topic_id, timestamp FROM stored LIMIT 3; DROP TABLE stored";
    EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
    sqlite3_close(db);
    expectError(generated, problem);
    EXPECT_NE(messageOf<FormatError>([&] { listBag(generated); }).find(problem), std::string::npos);
  }
  // Neither MCAP nor SQLite.
  test::writeBytes(*dir_ / "text.mcap", std::string("not an mcap file at all, but long enough to look at it"));
  expectError(*dir_ / "text.mcap", "not an MCAP file");
  EXPECT_THROW(listBag(*dir_ / "missing.mcap"), UsageError);
}

// Bit flips anywhere in a .db3 (fuzz_db3's kind of input, with a fixed seed): each reads, or
// is refused with a chronomap error; none may crash or throw anything else.
TEST_F(Ros2BagTest, CorruptSqliteBagsAreErrorsNotCrashes) {
  const auto seed = test::bytesOf(bag("pose.db3"));
  ASSERT_GT(seed.size(), 4096u);
  uint64_t state = 2026;
  const auto next = [&] { return state = state * 6364136223846793005ull + 1442695040888963407ull; };
  size_t refused = 0;
  for (int round = 0; round < 60; ++round) {
    auto mutated = seed;
    // The first 8 KiB hold SQLite's header and the schema and topics pages; flip there often.
    for (int flip = 0; flip < 4; ++flip) {
      const size_t span = flip % 2 == 0 ? size_t{8192} : mutated.size();
      mutated[(next() >> 33) % span] ^= static_cast<uint8_t>(1u << ((next() >> 33) % 8));
    }
    const fs::path path = *dir_ / "mutated.db3";
    test::writeBytes(path, mutated);
    try {
      listBag(path);
      const auto dataset = openDataset(path, bagSettings());
      for (size_t i = 0; i < dataset->size() && i < 4; ++i) dataset->load(i);
    } catch (const Error&) {
      ++refused;
    }
  }
  RecordProperty("refused", std::to_string(refused));
}

TEST_F(Ros2BagTest, MissingTopicsAndBadFoldersAreNamed) {
  DatasetSettings s = bagSettings();
  s.bag.depth_topic = "/nope";
  std::string what = messageOf<UsageError>([&] { openDataset(bag("pose.db3"), s); });
  EXPECT_NE(what.find(bag("pose.db3").string() + ": --depth-topic: no topic '/nope' in the bag (candidates: "),
            std::string::npos)
      << what;
  s = bagSettings();
  s.bag.fixed_frame = "world";
  what = messageOf<DataError>([&] { openDataset(bag("tf.mcap"), s); });
  EXPECT_NE(what.find("none of the 32 frames"), std::string::npos) << what;
  EXPECT_NE(what.find("/tf holds the frames base_link, camera_depth_optical_frame, map, odom"), std::string::npos)
      << what;
  // A folder whose metadata.yaml names a missing file, or several.
  const fs::path folder = *dir_ / "folder";
  fs::create_directories(folder);
  std::ofstream(folder / "metadata.yaml") << "rosbag2_bagfile_information:\n  relative_file_paths:\n    - gone.mcap\n";
  what = messageOf<DataError>([&] { openDataset(folder, bagSettings()); });
  EXPECT_NE(what.find("names gone.mcap, which is missing"), std::string::npos) << what;
  // A split bag whose second file is missing, and one whose second file is cut short.
  const fs::path split = *dir_ / "split_cut";
  fs::create_directories(split);
  fs::copy_file(bag("split_tf/metadata.yaml"), split / "metadata.yaml");
  fs::copy_file(bag("split_tf/split_tf_0.mcap"), split / "split_tf_0.mcap");
  fs::copy_file(bag("split_tf/split_tf_2.mcap"), split / "split_tf_2.mcap");
  what = messageOf<DataError>([&] { openDataset(split, bagSettings()); });
  EXPECT_NE(what.find((split / "metadata.yaml").string() + ": names split_tf_1.mcap, which is missing"),
            std::string::npos)
      << what;
  const auto second = test::bytesOf(bag("split_tf/split_tf_1.mcap"));
  test::writeBytes(split / "split_tf_1.mcap", std::vector<uint8_t>(second.begin(), second.begin() + 5000));
  // The part cut short is read up to its cut, and the dataset says so.
  DatasetSettings tf = bagSettings();
  tf.bag.fixed_frame = "map";
  const auto from_cut = openDataset(split, tf);
  EXPECT_GT(from_cut->size(), 0u);
  EXPECT_NE(from_cut->droppedReasons().find("split_tf_1.mcap cut short"), std::string::npos)
      << from_cut->droppedReasons();
}

// A bag rosbag2 split into three storage files (lz4, zstd, lz4; /tf_static only in the first):
// read as one, it lists the whole bag's counts and gives the poses and the map of the same
// recording in one file.
TEST_F(Ros2BagTest, ASplitBagReadsAsOneRecording) {
  const std::vector<BagTopic> topics = listBag(bag("split_tf"));
  const std::vector<BagTopic> whole = listBag(bag("tf.mcap"));
  ASSERT_EQ(topics.size(), whole.size());
  for (size_t i = 0; i < topics.size(); ++i) {
    EXPECT_EQ(topics[i].name, whole[i].name);
    EXPECT_EQ(topics[i].type, whole[i].type);
    EXPECT_EQ(topics[i].messages, whole[i].messages) << topics[i].name;
    EXPECT_EQ(topics[i].encoding, whole[i].encoding);
  }
  DatasetSettings s = bagSettings();
  s.bag.fixed_frame = "map";
  const auto from_split = openDataset(bag("split_tf"), s);
  const auto from_one = openDataset(bag("tf.mcap"), s);
  ASSERT_EQ(from_split->size(), 32u);
  EXPECT_EQ(from_split->framesDropped(), 0u);
  for (size_t i = 0; i < from_one->size(); ++i) {
    EXPECT_TRUE(from_split->poseOf(i).matrix() == from_one->poseOf(i).matrix()) << i;
  }
  // Frames of the last file are decoded from it.
  const Frame last = from_split->load(31), same = from_one->load(31);
  EXPECT_EQ(last.cloud.colours, same.cloud.colours);
  EXPECT_NE(last.source.find("split_tf: /camera/depth/image_raw at "), std::string::npos) << last.source;
  EXPECT_TRUE(mapBytes(bag("split_tf"), s) == mapBytes(bag("tf.mcap"), s));
}

TEST_F(Ros2BagTest, TheCommandLineListsAndIntegratesARos2Bag) {
  const auto list = test::runCommand(test::cli() + " integrate " + bag("tf.db3").string() + " --list");
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_NE(list.out.find("/tf  tf2_msgs/msg/TFMessage  64 message(s)"), std::string::npos) << list.out;
  const fs::path out = *dir_ / "cli.cmap";
  const auto run = test::runCommand(test::cli() + " integrate " + bag("tf.mcap").string() +
                                    " --fixed-frame map --depth-scale 5000 -o " + out.string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(out));
  const auto missing = test::runCommand(test::cli() + " integrate " + bag("tf.mcap").string() +
                                        " --depth-topic /nope -o " + out.string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("no topic '/nope'"), std::string::npos) << missing.err;
}

// ---- CDR, by hand: alignment counted from the end of the encapsulation header ----

/// A CDR message being built, little- or big-endian.
struct CdrBuilder {
  explicit CdrBuilder(bool little = true) : little_(little) { bytes = {0, static_cast<uint8_t>(little ? 1 : 0), 0, 0}; }
  void align(size_t n) {
    while ((bytes.size() - 4) % n) bytes.push_back(0xAA);  // padding (any value)
  }
  template <class T>
  void put(T v) {
    align(sizeof(T));
    uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (size_t i = 0; i < sizeof(T); ++i) bytes.push_back(b[little_ ? i : sizeof(T) - 1 - i]);
  }
  void str(const std::string& s) {
    put<uint32_t>(static_cast<uint32_t>(s.size() + 1));
    bytes.insert(bytes.end(), s.begin(), s.end());
    bytes.push_back(0);
  }
  void header(int32_t sec, uint32_t nsec, const std::string& frame) {
    put(sec);
    put(nsec);
    str(frame);
  }
  std::vector<uint8_t> bytes;
  bool little_;
};

TEST(Cdr, ImagesAndPosesDecodeWithTheirAlignment) {
  for (const bool little : {true, false}) {
    SCOPED_TRACE(little ? "little-endian" : "big-endian");
    CdrBuilder im(little);
    im.header(7, 500000000, "cam");  // frame "cam\0": 12 + 4 = 16 bytes, then 4-byte fields
    im.put<uint32_t>(2);             // height
    im.put<uint32_t>(3);             // width
    im.str("mono16");                // 4 + 7 bytes: the next u8 lands unaligned, fine for one byte
    im.put<uint8_t>(0);
    im.put<uint32_t>(6);  // step: padded to 4
    im.put<uint32_t>(12);
    for (uint8_t i = 0; i < 12; ++i) im.bytes.push_back(i);
    const cdr::Image decoded = cdr::image(im.bytes, "test");
    EXPECT_EQ(decoded.header.stamp, 7.5);
    EXPECT_EQ(decoded.header.frame_id, "cam");
    EXPECT_EQ(decoded.view.height, 2u);
    EXPECT_EQ(decoded.view.width, 3u);
    EXPECT_EQ(decoded.view.encoding, "mono16");
    EXPECT_EQ(decoded.view.step, 6u);
    ASSERT_EQ(decoded.view.data.size(), 12u);
    EXPECT_EQ(decoded.view.data[11], 11);

    CdrBuilder ps(little);
    ps.header(1, 2, "ab");  // 8 + 4 + 3 = 15 bytes: the doubles start at 16
    const double values[7] = {1.5, -2.25, 3.0, 0.0, 0.0, std::sqrt(0.5), std::sqrt(0.5)};
    for (double v : values) ps.put(v);
    const cdr::Transform pose = cdr::poseStamped(ps.bytes, "test");
    EXPECT_EQ(pose.header.stamp, 1.0 + 2e-9);
    EXPECT_EQ(pose.header.frame_id, "ab");
    EXPECT_EQ(pose.xyz[0], 1.5);
    EXPECT_EQ(pose.xyz[1], -2.25);
    EXPECT_EQ(pose.q[3], std::sqrt(0.5));
  }
}

TEST(Cdr, TruncatedAndForeignMessagesAreFormatErrors) {
  CdrBuilder ps;
  ps.header(1, 2, "map");
  for (int i = 0; i < 7; ++i) ps.put(1.0);
  for (size_t keep = 0; keep < ps.bytes.size(); keep += 5) {
    const std::vector<uint8_t> cut(ps.bytes.begin(), ps.bytes.begin() + static_cast<long>(keep));
    EXPECT_THROW(cdr::poseStamped(cut, "cut"), FormatError) << keep;
  }
  auto xcdr2 = ps.bytes;
  xcdr2[1] = 0x07;  // XCDR2 little-endian: not what ROS 2 writes, refused
  const std::string what = messageOf<FormatError>([&] { cdr::poseStamped(xcdr2, "/odom"); });
  EXPECT_EQ(what, "/odom: CDR: unknown CDR encapsulation 0,7 (read: plain CDR, big- or little-endian)");
  // A sequence longer than the message: refused before anything is allocated.
  CdrBuilder tf;
  tf.put<uint32_t>(0x7fffffff);
  EXPECT_THROW(cdr::tfMessage(tf.bytes, "tf"), FormatError);
  CdrBuilder str;
  str.put<uint32_t>(0);
  str.put<uint32_t>(0);
  str.put<uint32_t>(3);
  str.bytes.insert(str.bytes.end(), {'a', 'b', 'c'});  // no terminating NUL
  EXPECT_THROW(cdr::header(str.bytes, "h"), FormatError);
}

// ---------------------------------------------------------------- CompressedImage, analytic

/// The bytes of a PNG file of `image`.
template <class Image>
std::vector<uint8_t> pngBytes(const Image& image) {
  test::TempDir tmp;
  writePng(tmp / "x.png", image);
  return test::bytesOf(tmp / "x.png");
}

/// compressedDepth's 12-byte header (compression 0, quantisation A and B) before `png`.
std::vector<uint8_t> compressedDepth(const std::vector<uint8_t>& png, float a = 0.0f, float b = 0.0f) {
  std::vector<uint8_t> out(12, 0);
  std::memcpy(out.data() + 4, &a, 4);
  std::memcpy(out.data() + 8, &b, 4);
  out.insert(out.end(), png.begin(), png.end());
  return out;
}

TEST(CompressedImage, FormatsAreToldApart) {
  for (const char* f : {"jpeg", "png", "rgb8; jpeg compressed bgr8", "bgr8; png compressed bgr8", "JPEG"}) {
    EXPECT_TRUE(rosmsg::isCompressedColourFormat(f)) << f;
    EXPECT_FALSE(rosmsg::isCompressedDepthFormat(f)) << f;
  }
  for (const char* f : {"16UC1; compressedDepth", "16UC1; compressedDepth png", "32FC1; compressedDepth",
                        "16UC1; compressedDepth rvl"}) {
    EXPECT_TRUE(rosmsg::isCompressedDepthFormat(f)) << f;
    EXPECT_FALSE(rosmsg::isCompressedColourFormat(f)) << f;
  }
  EXPECT_FALSE(rosmsg::isCompressedColourFormat("webp"));
}

// 16UC1: the PNG's numbers as they are; 32FC1: the inverse-depth quantisation undone,
// depth = A / (v - B), with 0 as no measurement.
TEST(CompressedImage, DepthDecodesToTheWrittenUnitsAndTheQuantisedMetres) {
  const ImageU16 units{3, 2, {0, 1000, 2000, 3000, 65535, 7}};
  const auto png = pngBytes(units);
  const auto bytes = compressedDepth(png);
  rosmsg::OwnedImage d16 = rosmsg::compressedDepthImage({"16UC1; compressedDepth png", bytes}, "t");
  EXPECT_EQ(d16.view.encoding, "16UC1");
  ASSERT_EQ(d16.view.width, 3u);
  ASSERT_EQ(d16.view.height, 2u);
  EXPECT_EQ(d16.view.step, 6u);
  for (size_t i = 0; i < units.pixels.size(); ++i) {
    uint16_t v = 0;
    std::memcpy(&v, d16.view.data.data() + 2 * i, 2);
    EXPECT_EQ(v, units.pixels[i]) << i;
  }
  const PointCloud cloud = rosmsg::depthCloud(d16.view, nullptr, {1, 1, 0, 0}, 1000.0, "t");
  EXPECT_TRUE(std::isnan(cloud.points[0].z()));
  EXPECT_FLOAT_EQ(cloud.points[1].z(), 1.0f);

  const float a = 10100.0f, b = -1009.0f;  // image_transport's defaults: quantisation 100, 10 m
  const rosmsg::OwnedImage d32 = rosmsg::compressedDepthImage({"32FC1; compressedDepth", compressedDepth(png, a, b)}, "t");
  EXPECT_EQ(d32.view.encoding, "32FC1");
  EXPECT_EQ(d32.view.step, 12u);
  for (size_t i = 0; i < units.pixels.size(); ++i) {
    float m = 0.0f;
    std::memcpy(&m, d32.view.data.data() + 4 * i, 4);
    if (units.pixels[i] == 0) {
      EXPECT_TRUE(std::isnan(m));
    } else {
      EXPECT_FLOAT_EQ(m, a / (static_cast<float>(units.pixels[i]) - b)) << i;
    }
  }
  // Moving the decoded image keeps its view on its bytes.
  const rosmsg::OwnedImage moved = std::move(d16);
  EXPECT_EQ(moved.view.data.data(), moved.bytes.data());
}

TEST(CompressedImage, ColourDecodesFromJpegAndPng) {
  ImageRgb rgb{4, 2, std::vector<Rgb>(8)};
  for (size_t i = 0; i < 8; ++i) rgb.pixels[i] = {static_cast<uint8_t>(120 + 4 * i), 100, static_cast<uint8_t>(80 - 4 * i)};
  const auto png = pngBytes(rgb);
  const ImageRgb from_png = rosmsg::compressedColourImage({"rgb8; png compressed bgr8", png}, "t");
  EXPECT_TRUE(from_png.pixels == rgb.pixels);
  const auto jpeg = encodeJpeg(rgb, {95});
  const ImageRgb from_jpeg = rosmsg::compressedColourImage({"jpeg", jpeg}, "t");
  ASSERT_EQ(from_jpeg.width, 4u);
  ASSERT_EQ(from_jpeg.height, 2u);
  // JPEG's loss: chroma is averaged over 2 x 2 pixels, so single pixels move by up to a dozen
  // units where the colour varies, the image's mean colour by very little.
  double mean_error[3] = {0.0, 0.0, 0.0};
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_NEAR(from_jpeg.pixels[i].r, rgb.pixels[i].r, 16) << i;
    EXPECT_NEAR(from_jpeg.pixels[i].g, rgb.pixels[i].g, 16) << i;
    EXPECT_NEAR(from_jpeg.pixels[i].b, rgb.pixels[i].b, 16) << i;
    mean_error[0] += (from_jpeg.pixels[i].r - rgb.pixels[i].r) / 8.0;
    mean_error[1] += (from_jpeg.pixels[i].g - rgb.pixels[i].g) / 8.0;
    mean_error[2] += (from_jpeg.pixels[i].b - rgb.pixels[i].b) / 8.0;
  }
  for (double e : mean_error) EXPECT_LT(std::abs(e), 3.0);
}

TEST(CompressedImage, OtherCompressionsAndBrokenDataAreOneLineErrors) {
  const auto png = pngBytes(ImageU16{2, 2, {1, 2, 3, 4}});
  const auto bytes = compressedDepth(png);
  EXPECT_EQ(messageOf<DataError>([&] { rosmsg::compressedDepthImage({"16UC1; compressedDepth rvl", bytes}, "/d"); }),
            "/d: compressedDepth with RVL compression ('16UC1; compressedDepth rvl') is not read (PNG only)");
  EXPECT_THROW(rosmsg::compressedDepthImage({"8UC3; compressedDepth", bytes}, "/d"), DataError);
  EXPECT_THROW(rosmsg::compressedDepthImage({"rgb8; jpeg compressed bgr8", bytes}, "/d"), DataError);
  EXPECT_THROW(rosmsg::compressedDepthImage({"16UC1; compressedDepth", png}, "/d"), FormatError);  // no header
  const std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() / 2));
  EXPECT_THROW(rosmsg::compressedDepthImage({"16UC1; compressedDepth", cut}, "/d"), Error);
  EXPECT_THROW(rosmsg::compressedDepthImage({"32FC1; compressedDepth", compressedDepth(png, 0.0f, 1.0f)}, "/d"),
               FormatError);
  EXPECT_THROW(rosmsg::compressedColourImage({"16UC1; compressedDepth", bytes}, "/c"), DataError);
  const std::vector<uint8_t> webp{'R', 'I', 'F', 'F', 0, 0, 0, 0, 'W', 'E', 'B', 'P'};
  EXPECT_EQ(messageOf<DataError>([&] { rosmsg::compressedColourImage({"webp", webp}, "/c"); }),
            "/c: compressed image of format 'webp' is neither a JPEG nor a PNG (the compressions read)");
  const std::vector<uint8_t> half_png(png.begin(), png.begin() + static_cast<long>(png.size() / 2));
  EXPECT_THROW(rosmsg::compressedColourImage({"png", half_png}, "/c"), Error);
}

// Found by fuzz_cdr: a cloud of 4 billion rows of width 0 (fits any data: 0 bytes) walked every
// row. It is an empty cloud, returned at once.
TEST(Cdr, AnEmptyCloudWithBillionsOfRowsIsEmptyAtOnce) {
  CdrBuilder c;
  c.header(1, 0, "cam");
  c.put<uint32_t>(0xfa000000u);  // height
  c.put<uint32_t>(0);            // width
  c.put<uint32_t>(3);            // fields
  for (const char* name : {"x", "y", "z"}) {
    c.str(name);
    c.put<uint32_t>(static_cast<uint32_t>(4 * (name[0] - 'x')));
    c.put<uint8_t>(7);
    c.put<uint32_t>(1);
  }
  c.put<uint8_t>(0);
  c.put<uint32_t>(12);  // point_step
  c.put<uint32_t>(0);   // row_step
  c.put<uint32_t>(0);   // data
  c.put<uint8_t>(1);
  const cdr::Cloud cloud = cdr::cloud(c.bytes, "cloud");
  EXPECT_EQ(cloud.view.height, 0xfa000000u);
  const PointCloud points = rosmsg::pointCloud(cloud.view, "cloud");
  EXPECT_EQ(points.size(), 0u);
}

}  // namespace
}  // namespace chronomap
