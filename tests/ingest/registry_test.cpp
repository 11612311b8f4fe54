// The registry of readers: names and aliases, detection in order, the errors that list what
// there is, and the extension point itself (a reader registered from outside ingest is found
// by detection and by name, as ingest/ros's are).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/ingest/registry.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

/// A layout of this test: a folder with a file "marker.testlayout"; one frame of one point.
class MarkerDataset : public Dataset {
 public:
  size_t size() const override { return 1; }
  std::string format() const override { return "testlayout"; }
  Frame load(size_t) const override {
    Frame f;
    f.cloud.points.emplace_back(1.0f, 0.0f, 0.0f);
    f.cloud.width = 1;
    f.source = "marker";
    return f;
  }
};

bool hasMarker(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec) && fs::exists(path / "marker.testlayout", ec);
}

std::unique_ptr<Dataset> openMarker(const fs::path& path, const DatasetSettings&) {
  if (!hasMarker(path)) throw UsageError(path.string() + ": no marker.testlayout");
  return std::make_unique<MarkerDataset>();
}

void touch(const fs::path& p) { std::ofstream(p) << "x\n"; }

std::string usageMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const UsageError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no UsageError";
  return {};
}

TEST(Registry, BuiltInReadersInDetectionOrderWithTheirAliases) {
  const std::vector<DatasetReader> readers = datasetReaders();
  ASSERT_GE(readers.size(), 5u);
  EXPECT_EQ(readers[0].name, "tum");
  EXPECT_EQ(readers[1].name, "3dmatch");
  EXPECT_EQ(readers[2].name, "scannet");
  EXPECT_EQ(readers[3].name, "clouds");
  EXPECT_EQ(readers[4].name, "dynamic-map");
  EXPECT_EQ(parseDatasetFormat("dynamicmap"), "dynamic-map");
  for (const DatasetReader& r : readers) {
    EXPECT_FALSE(r.description.empty()) << r.name;
    EXPECT_EQ(datasetReaderNamed(r.name).name, r.name);
    for (const std::string& alias : r.aliases) EXPECT_EQ(parseDatasetFormat(alias), r.name) << alias;
  }
  EXPECT_EQ(parseDatasetFormat("7scenes"), "3dmatch");
  EXPECT_EQ(parseDatasetFormat("auto"), "auto");
  EXPECT_TRUE(readers[3].takes_pose);
  EXPECT_FALSE(readers[0].takes_pose);
}

TEST(Registry, UnknownNamesAndUnrecognisedInputAreRefusedListingTheReaders) {
  const std::string unknown = usageMessage([] { parseDatasetFormat("kinectfusion"); });
  // The readers this program has registered, in order; the last one after "or".
  EXPECT_NE(unknown.find("unknown dataset format 'kinectfusion' (expected auto, tum, 3dmatch, scannet"),
            std::string::npos)
      << unknown;
  EXPECT_NE(unknown.find("clouds"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find(" or " + datasetReaders().back().name + ")"), std::string::npos) << unknown;
  EXPECT_FALSE(findDatasetReader("kinectfusion"));
  test::TempDir tmp;
  const std::string folder = usageMessage([&] { openDataset(tmp.path()); });
  EXPECT_NE(folder.find("cannot tell the dataset format: no reader (tum, 3dmatch, scannet, clouds"), std::string::npos)
      << folder;
  EXPECT_NE(folder.find("recognises this folder"), std::string::npos) << folder;
  touch(tmp / "frames.unknownext");
  const std::string file = usageMessage([&] { openDataset(tmp / "frames.unknownext"); });
  EXPECT_NE(file.find("recognises this file"), std::string::npos) << file;
  // A reader named by --format still checks its input: a TUM dataset is a folder.
  DatasetSettings tum;
  tum.format = "tum";
  EXPECT_NE(usageMessage([&] { openDataset(tmp / "frames.unknownext", tum); }).find("a TUM dataset is a folder"),
            std::string::npos);
  // --pose is only for a single cloud.
  fs::create_directories(tmp / "tum");
  touch(tmp / "tum" / "depth.txt");
  DatasetSettings posed;
  posed.pose = Eigen::Isometry3d::Identity();
  EXPECT_NE(usageMessage([&] { openDataset(tmp / "tum", posed); }).find("--pose applies to a single cloud file"),
            std::string::npos);
}

TEST(Registry, ARegisteredReaderIsDetectedAndNamedAfterTheBuiltInOnes) {
  // Refused: a taken name, a taken alias, a reader without its functions.
  EXPECT_FALSE(registerDatasetReader({"tum", {}, "again", hasMarker, openMarker}));
  EXPECT_FALSE(registerDatasetReader({"tum2", {"7scenes"}, "alias taken", hasMarker, openMarker}));
  EXPECT_THROW(registerDatasetReader({"nofunctions", {}, "", nullptr, nullptr}), UsageError);
  EXPECT_THROW(registerDatasetReader({"", {}, "", hasMarker, openMarker}), UsageError);
  // The first registration wins; registering again is refused and changes nothing.
  const bool added = registerDatasetReader({"testlayout", {"tl"}, "a test layout", hasMarker, openMarker});
  EXPECT_FALSE(registerDatasetReader({"testlayout", {}, "twice", hasMarker, openMarker}));
  if (added) {
    EXPECT_EQ(datasetReaders().back().name, "testlayout");
  }
  EXPECT_EQ(parseDatasetFormat("tl"), "testlayout");

  test::TempDir tmp;
  const fs::path folder = tmp / "recording";
  fs::create_directories(folder);
  touch(folder / "marker.testlayout");
  EXPECT_EQ(detectDatasetReader(folder).name, "testlayout");
  const auto dataset = openDataset(folder);
  EXPECT_EQ(dataset->format(), "testlayout");
  ASSERT_EQ(dataset->size(), 1u);
  EXPECT_EQ(dataset->load(0).cloud.points.size(), 1u);
  DatasetSettings by_alias;
  by_alias.format = "tl";
  EXPECT_EQ(openDataset(folder, by_alias)->format(), "testlayout");
  // Detection asks in registry order: a folder that is also a TUM folder is read as TUM.
  touch(folder / "depth.txt");
  EXPECT_EQ(detectDatasetReader(folder).name, "tum");
}

}  // namespace
}  // namespace chronomap
