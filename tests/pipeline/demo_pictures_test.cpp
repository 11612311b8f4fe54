// The demo report's pictures of a pair of sessions (pipeline/demo_pictures.h): the rooms read
// from a scene.json, the pair's top view and a close-up per object.
#include <gtest/gtest.h>

#include "builders.h"
#include "chronomap/core/error.h"
#include "chronomap/ingest/png.h"
#include "pipeline/demo_pictures.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

TEST(DemoPictures, ReadsTheRoomsOfAScene) {
  test::TempDir tmp;
  test::writeBytes(tmp.path() / "scene.json",
                   std::string(R"({"rooms": [{"name": "corridor", "min": [0, 0], "max": [12, 2]},)"
                               R"( {"name": "kitchen", "min": [4.06, 2.12], "max": [7.96, 7.12]}], "events": []})"));
  const std::vector<Room> rooms = readRooms(tmp.path() / "scene.json");
  ASSERT_EQ(rooms.size(), 2u);
  EXPECT_EQ(rooms[1].name, "kitchen");
  EXPECT_TRUE(rooms[1].area.min().isApprox(Eigen::Vector2d(4.06, 2.12)));
  EXPECT_TRUE(rooms[1].area.max().isApprox(Eigen::Vector2d(7.96, 7.12)));
  test::writeBytes(tmp.path() / "none.json", std::string(R"({"events": []})"));
  EXPECT_TRUE(readRooms(tmp.path() / "none.json").empty());
  test::writeBytes(tmp.path() / "bad.json", std::string(R"({"rooms": [{"name": "x", "min": [1, 1], "max": [0, 2]}]})"));
  try {
    readRooms(tmp.path() / "bad.json");
    FAIL() << "a room with min above max was read";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
  }
  EXPECT_THROW(readRooms(tmp.path() / "missing.json"), IoError);
}

TEST(DemoPictures, APictureOfThePairAndOnePerObject) {
  test::TempDir tmp;
  const SessionMap before = test::changesScene(false), after = test::changesScene(true);
  const Changes c = findChanges(before, after);  // 3 objects: appeared, vanished, moved
  Room room;
  room.name = "lab";
  room.area = Eigen::AlignedBox2d(Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(1.8, 0.8));
  const std::vector<std::string> names = drawChangePictures(tmp.path(), "diff_01_02", after, c, {room});
  EXPECT_EQ(names, (std::vector<std::string>{"diff_01_02.png", "diff_01_02_object_01.png", "diff_01_02_object_02.png",
                                             "diff_01_02_object_03.png"}));
  const ImageRgb whole = readPngRgb(tmp.path() / names[0]);
  EXPECT_GT(whole.width, 36u * 3);  // 3 pixels a voxel and the frame
  for (size_t i = 1; i < names.size(); ++i) {
    const ImageRgb close = readPngRgb(tmp.path() / names[i]);
    EXPECT_GT(close.width, 100u) << names[i];  // scaled up to about 600 pixels
  }
}

}  // namespace
}  // namespace chronomap
