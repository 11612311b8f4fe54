// The MCAP writer and the Foxglove export (export/mcap_writer.h, export/foxglove.h), read back
// with chronomap's own MCAP reader (ingest/ros/mcap.h): the analytic changes scene of builders.h
// as a 4D map of three sessions, whose objects, voxels and times are known.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <nlohmann/json.hpp>

#include "builders.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/core/error.h"
#include "chronomap/export/foxglove.h"
#include "chronomap/export/mcap_writer.h"
#include "ingest/ros/mcap.h"
#include "test_support.h"

namespace chronomap {
namespace {

using nlohmann::json;

/// Every message of a file: topic, log time and text, in file order.
struct ReadMessage {
  std::string topic;
  uint64_t log_time = 0;
  std::string data;
};
std::vector<ReadMessage> readAll(mcap::Reader& reader) {
  std::vector<ReadMessage> out;
  reader.forEachMessage([&](const mcap::Message& m) {
    out.push_back({reader.channels().at(m.channel).topic, m.log_time,
                   std::string(reinterpret_cast<const char*>(m.data.data()), m.data.size())});
  });
  return out;
}

std::string unbase64(const std::string& text) {
  std::string out;
  uint32_t bits = 0;
  int n = 0;
  for (char ch : text) {
    const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    if (ch == '=') break;
    bits = bits << 6 | static_cast<uint32_t>(std::strchr(digits, ch) - digits);
    if ((n += 6) >= 8) out.push_back(static_cast<char>((bits >> (n -= 8)) & 0xff));
  }
  return out;
}

TEST(McapWriter, ManyChunksReadBackInOrderWithTheirChannelsAndCrcs) {
  for (const int level : {0, 3}) {
    test::TempDir tmp;
    McapWriterSettings settings;
    settings.zstd_level = level;
    settings.chunk_bytes = 4096;
    McapWriter writer(settings);
    const uint16_t schema = writer.addSchema("demo.Text", "jsonschema", R"({"type":"object"})");
    const uint16_t a = writer.addChannel(schema, "/a", "json"), b = writer.addChannel(0, "/b", "json");
    for (uint64_t i = 0; i < 1000; ++i) writer.addMessage(i % 3 ? a : b, 1'000'000'000u + i, std::to_string(i));
    EXPECT_EQ(writer.messageCounts().at(b), 334u);
    writer.write(tmp / "m.mcap");
    mcap::Reader reader(tmp / "m.mcap");
    ASSERT_TRUE(reader.indexed()) << "level " << level;
    EXPECT_EQ(reader.schemas().at(schema).name, "demo.Text");
    EXPECT_EQ(reader.schemas().at(schema).encoding, "jsonschema");
    EXPECT_EQ(reader.channels().at(a).topic, "/a");
    EXPECT_EQ(reader.channels().at(b).schema_id, 0);
    const std::vector<ReadMessage> read = readAll(reader);
    ASSERT_EQ(read.size(), 1000u);
    for (uint64_t i = 0; i < 1000; ++i) {
      EXPECT_EQ(read[i].data, std::to_string(i));
      EXPECT_EQ(read[i].log_time, 1'000'000'000u + i);
      EXPECT_EQ(read[i].topic, i % 3 ? "/a" : "/b");
    }
    // Its CRCs are real: a byte changed inside the last message of a stored chunk is caught.
    if (level == 0) {
      std::vector<uint8_t> bytes = test::bytesOf(tmp / "m.mcap");
      const std::string last = "999";
      const auto at = std::search(bytes.begin(), bytes.end(), last.begin(), last.end());
      ASSERT_NE(at, bytes.end());
      *at = '8';
      test::writeBytes(tmp / "bad.mcap", bytes);
      mcap::Reader bad(tmp / "bad.mcap");
      EXPECT_THROW(readAll(bad), FormatError);
    }
  }
}

TEST(McapWriter, RefusesUnknownChannelsAndSchemas) {
  McapWriter writer;
  EXPECT_THROW(writer.addChannel(7, "/x", "json"), UsageError);
  EXPECT_THROW(writer.addMessage(1, 0, "{}"), UsageError);
  McapWriterSettings bad;
  bad.zstd_level = 20;
  EXPECT_THROW(McapWriter{bad}, UsageError);
}

class FoxgloveExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    map_.add(100.25, test::changesScene(false));
    map_.add(200.5, test::changesScene(true));
    map_.add(300.0, test::changesScene(false));
    written_ = exportFoxglove(tmp_ / "map.mcap", map_);
  }
  test::TempDir tmp_;
  TemporalMap map_{0.05};
  FoxgloveExport written_;
};

TEST_F(FoxgloveExportTest, ChannelsSchemasCountsAndTimes) {
  mcap::Reader reader(tmp_ / "map.mcap");
  ASSERT_TRUE(reader.indexed());
  std::map<std::string, std::string> schema_of;
  for (const auto& [id, c] : reader.channels()) {
    EXPECT_EQ(c.message_encoding, "json");
    EXPECT_EQ(reader.schemas().at(c.schema_id).encoding, "jsonschema");
    schema_of[c.topic] = reader.schemas().at(c.schema_id).name;
  }
  const std::map<std::string, std::string> expected = {{"/tf", "foxglove.FrameTransform"},
                                                       {"/map/occupied", "foxglove.PointCloud"},
                                                       {"/map/changes", "foxglove.SceneUpdate"},
                                                       {"/map/costmap", "foxglove.Grid"}};
  EXPECT_EQ(schema_of, expected);
  std::map<std::string, std::vector<uint64_t>> times;
  for (const ReadMessage& m : readAll(reader)) times[m.topic].push_back(m.log_time);
  const std::vector<uint64_t> sessions = {100'250'000'000u, 200'500'000'000u, 300'000'000'000u};
  EXPECT_EQ(times["/tf"], sessions);
  EXPECT_EQ(times["/map/occupied"], sessions);
  EXPECT_EQ(times["/map/costmap"], sessions);
  EXPECT_EQ(times["/map/changes"], std::vector<uint64_t>(sessions.begin() + 1, sessions.end()));
  EXPECT_EQ(written_.sessions, 3u);
  ASSERT_EQ(written_.topics.size(), 4u);
  EXPECT_EQ(written_.topics[2].messages, 2u);
}

TEST_F(FoxgloveExportTest, TheSceneGivesItsKnownVoxelsObjectsAndCosts) {
  mcap::Reader reader(tmp_ / "map.mcap");
  std::map<std::string, std::vector<json>> messages;
  for (const ReadMessage& m : readAll(reader)) messages[m.topic].push_back(json::parse(m.data));
  // The first session: the wall (16 x 10), box A (4^3) and box C (3^3), each in its colour.
  const json& cloud = messages["/map/occupied"][0];
  EXPECT_EQ(cloud["timestamp"], (json{{"sec", 100}, {"nsec", 250'000'000}}));
  const std::string points = unbase64(cloud["data"]);
  ASSERT_EQ(points.size(), 16u * (160 + 64 + 27));
  std::map<std::tuple<int, int, int>, int> colours;
  for (size_t i = 0; i < points.size(); i += 16) {
    ++colours[{static_cast<uint8_t>(points[i + 12]), static_cast<uint8_t>(points[i + 13]), static_cast<uint8_t>(points[i + 14])}];
  }
  EXPECT_EQ(colours, (std::map<std::tuple<int, int, int>, int>{{{128, 128, 128}, 160}, {{200, 40, 40}, 64}, {{40, 200, 40}, 27}}));
  // The pair 100 -> 200: B appeared, A vanished, C moved 0.9 m, as findChanges() lists them.
  const Changes found = findChanges(map_, 100.25, 200.5);
  const json& update = messages["/map/changes"][0];
  EXPECT_EQ(update["deletions"][0]["type"], 1);
  ASSERT_EQ(update["entities"].size(), found.objects.size());
  ASSERT_EQ(found.objects.size(), 3u);
  std::vector<std::string> labels;
  for (size_t i = 0; i < found.objects.size(); ++i) {
    const json& e = update["entities"][i];
    labels.push_back(e["texts"][0]["text"]);
    const Eigen::Vector3d centre = 0.5 * (found.objects[i].bbox_min_m + found.objects[i].bbox_max_m);
    EXPECT_NEAR(e["cubes"][0]["pose"]["position"]["x"].get<double>(), centre.x(), 1e-9);
    EXPECT_NEAR(e["cubes"][0]["size"]["z"].get<double>(), found.objects[i].size_m().z(), 1e-9);
  }
  EXPECT_EQ(labels, (std::vector<std::string>{"1 appeared", "2 vanished", "3 moved 0.90 m"}));
  EXPECT_EQ(update["entities"][2]["cubes"].size(), 2u);  // a move: where it went and where it was
  EXPECT_EQ(written_.objects, 6u);                         // and back again from 200 to 300
  // The cost grid of the first session: the wall and the boxes lethal, free floor between.
  const json& grid = messages["/map/costmap"][0];
  const std::string cost = unbase64(grid["data"]);
  ASSERT_EQ(cost.size() % grid["column_count"].get<size_t>(), 0u);
  EXPECT_EQ(grid["cell_size"]["x"], 0.05);
  EXPECT_NE(cost.find(static_cast<char>(100)), std::string::npos);
  EXPECT_NE(cost.find(static_cast<char>(0)), std::string::npos);
  EXPECT_EQ(messages["/tf"][0]["child_frame_id"], "map");
}

TEST(FoxgloveExport, RefusesAnEmptyMapAndTimesBefore1970) {
  test::TempDir tmp;
  TemporalMap map(0.05);
  EXPECT_THROW(exportFoxglove(tmp / "e.mcap", map), UsageError);
  map.add(-10.0, test::changesScene(false));
  EXPECT_THROW(exportFoxglove(tmp / "e.mcap", map), UsageError);
  EXPECT_FALSE(std::filesystem::exists(tmp / "e.mcap"));
}

}  // namespace
}  // namespace chronomap
