// libFuzzer targets for every reader. One source, one target per reader (FUZZ_TARGET picks it).
// A reader may reject input only with a chronomap::Error; anything else (a crash, a sanitizer
// report, another exception) is a bug.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/fitted_on.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"
#include "model_map.h"
#if defined(FUZZ_BAG) || defined(FUZZ_MCAP) || defined(FUZZ_DB3)
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "chronomap/ingest/ros/readers.h"
#include "chronomap/ingest/ros/rosbag.h"
#endif
#if defined(FUZZ_ROSMSG)
#include "ingest/ros/ros_messages.h"
#endif
#if defined(FUZZ_CDR)
#include "ingest/ros/cdr.h"
#endif

namespace {

using namespace chronomap;

#if defined(FUZZ_BAG) || defined(FUZZ_MCAP) || defined(FUZZ_DB3)
/// The file of this process's inputs, removed when the process ends normally: libFuzzer's time
/// limit and a list of inputs both end in exit(), which runs this destructor. A crash, a timeout
/// or running out of memory ends in _Exit and leaves the file (beside the crash's artifact).
struct FuzzFile {
  std::filesystem::path path;
  explicit FuzzFile(const char* extension)
      : path(std::filesystem::temp_directory_path() / ("chronomap-fuzz-" + std::to_string(::getpid()) + extension)) {}
  ~FuzzFile() {
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  }
  FuzzFile(const FuzzFile&) = delete;
  FuzzFile& operator=(const FuzzFile&) = delete;
};

/// Both bag readers read files: the input goes to a file of this process (named with
/// `extension`), then through the listing and the dataset reader (topics detected, poses from a
/// pose topic or /tf into "map"), loading the first frames.
void fuzzBagFile(const std::vector<uint8_t>& bytes, const char* extension, const char* format) {
  static const FuzzFile file(extension);
  const std::filesystem::path& path = file.path;
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  registerRosReaders();
  listBag(path);
  for (const char* fixed_frame : {"", "map"}) {
    try {
      DatasetSettings settings;
      settings.format = format;
      settings.bag.fixed_frame = fixed_frame;
      const auto dataset = openDataset(path, settings);
      for (size_t i = 0; i < dataset->size() && i < 4; ++i) dataset->load(i);
    } catch (const Error&) {
    }
  }
}
#endif

void fuzzOne(const std::vector<uint8_t>& bytes) {
  const std::string name = "fuzz-input";
#if defined(FUZZ_CMAP)
  const CmapFile file = decodeCmap(bytes, name);
  if (file.header.kind == MapKind::Session) {
    const SessionMap map = sessionMapFrom(file, name);
    volatile size_t leaves = map.counts().leaves;
    (void)leaves;
    map.find(VoxelKey{32768, 32768, 32768});
    // A session map that reads must also merge and re-align against itself.
    const SessionMap* both[] = {&map, &map};
    const SessionMap avg = consensus(std::span<const SessionMap* const>(both));
    volatile size_t moved = realign(map, avg).leafCount();
    (void)moved;
  } else if (file.header.kind == MapKind::Temporal) {
    // A 4D map that reads must also answer queries without crashing.
    TemporalMap map = temporalMapFrom(file, name);
    if (map.sessionCount() > 0) {
      const SessionMap snap = map.snapshot(map.sessions().back().time_s);
      volatile size_t leaves = snap.leafCount();
      (void)leaves;
    }
    map.history(VoxelKey{32768, 32768, 32768});
    if (map.sessionCount() > 0) {
      volatile size_t leaves = consensus(map, map.sessions().front().time_s, map.sessions().back().time_s).leafCount();
      (void)leaves;
    }
    if (map.sessionCount() > 1) {
      volatile size_t cells = diff(map, map.sessions().front().time_s, map.sessions().back().time_s).cells().size();
      (void)cells;
    }
    map.compact();
  } else if (file.header.kind == MapKind::Tiled) {
    // A tile index (the top of a tiled map and its table of tiles) that reads must also answer
    // the queries a tiled map asks of its top.
    const TileIndex index = decodeTileIndex(bytes, name);
    index.top.history(VoxelKey{32768, 32768, 32768});
    for (const TileEntry& e : index.tiles) {
      index.find(e.key);
      if (index.windowed) {
        volatile size_t first = openWindowFirst(e);  // where a night would read the open window
        (void)first;
      }
    }
    if (index.top.sessionCount() > 1) {
      volatile size_t cells =
          diff(index.top, index.top.sessions().front().time_s, index.top.sessions().back().time_s).cells().size();
      (void)cells;
    }
  } else if (file.header.kind == MapKind::Diff) {
    // A diff that reads must also segment without crashing.
    const DiffMap d = diffMapFrom(file, name);
    SegmentSettings s;
    s.connectivity = Connectivity::Vertex;
    volatile size_t n = segment(d, s).components.size();
    (void)n;
  }
  metadataOf(file);
#elif defined(FUZZ_PCD)
  // With the extras too: the intensity field, and the VIEWPOINT as the dynamic-map reader takes it.
  PcdExtras extras;
  parsePcd(bytes, name, &extras);
  if (!extras.viewpoint.empty()) pcdViewpointPose(extras.viewpoint, name);
#elif defined(FUZZ_PLY)
  parsePly(bytes, name);
#elif defined(FUZZ_XYZ)
  parseXyz(std::string(bytes.begin(), bytes.end()), name);
#elif defined(FUZZ_PNG)
  // Colour frames: PNG or JPEG, as readColourImage tells them apart; depth is PNG only.
  if (looksLikeJpeg(bytes)) {
    decodeJpegRgb(bytes, name);
    return;
  }
  try {
    decodePngRgb(bytes, name);
  } catch (const Error&) {
  }
  decodePngU16(bytes, name);
#elif defined(FUZZ_TEXT)
  // The first byte picks the format, the rest is the text.
  if (bytes.empty()) return;
  const std::string text(bytes.begin() + 1, bytes.end());
  switch (bytes[0] % 5) {
    case 0: parseIntrinsicsText(text, name); break;
    case 1: chronomap::parseMatrix4(text, name); break;
    case 2: parseStampedList(text, name); break;
    case 3: parseTumTrajectory(text, name); break;
    default: parseCloudList(text, name); break;
  }
#elif defined(FUZZ_BAG)
  fuzzBagFile(bytes, ".bag", "rosbag");  // through librosbag
#elif defined(FUZZ_ROSMSG)
  // The message decoders behind every bag reader: a 12-byte head picks the message's shape
  // (kind, encoding or fields, size, row bytes, byte order), the rest is its data.
  if (bytes.size() < 12) return;
  static const char* const kEncodings[] = {"16UC1", "32FC1", "mono16", "rgb8", "bgr8", "mono8", "rgba8", "bgra8", "yuv422"};
  const std::span<const uint8_t> data(bytes.data() + 12, bytes.size() - 12);
  const uint32_t width = bytes[1] % 64u, height = bytes[2] % 64u, step = bytes[3] + 256u * (bytes[4] % 4u);
  const bool big_endian = bytes[5] & 1u;
  const CameraIntrinsics k{100.0, 100.0, 32.0, 24.0};
  static const char* const kFormats[] = {"16UC1; compressedDepth png", "32FC1; compressedDepth",
                                         "16UC1; compressedDepth rvl", "rgb8; jpeg compressed bgr8", "png", "8UC3; compressedDepth"};
  switch (bytes[0] % 5) {
    case 0: {
      const rosmsg::ImageView im{height, width, kEncodings[bytes[6] % 9], big_endian, step, data};
      rosmsg::depthCloud(im, nullptr, k, 1000.0, name);
      break;
    }
    case 3: {
      // sensor_msgs/CompressedImage: compressedDepth (a header and a PNG) or a JPEG/PNG colour image.
      const rosmsg::CompressedView im{kFormats[bytes[6] % 6], data};
      const rosmsg::OwnedImage depth = rosmsg::compressedDepthImage(im, name);
      rosmsg::depthCloud(depth.view, nullptr, k, 1000.0, name);
      break;
    }
    case 4: rosmsg::compressedColourImage({kFormats[bytes[6] % 6], data}, name); break;
    case 1: {
      const rosmsg::ImageView im{height, width, kEncodings[bytes[6] % 9], big_endian, step, data};
      rosmsg::colourImage(im, name);
      break;
    }
    default: {
      rosmsg::CloudView cloud{height, width, {}, big_endian, bytes[7] % 64u, step, data};
      static const char* const kNames[] = {"x", "y", "z", "rgb", "rgba", "intensity"};
      for (size_t f = 8; f < 12; ++f) {
        cloud.fields.push_back({kNames[bytes[f] % 6], (bytes[f] >> 3) % 32u, static_cast<uint8_t>(bytes[f] % 10), 1});
      }
      // x, y and z as FLOAT32 after the random fields, so that most inputs get past the field check.
      const char* const axes[] = {"x", "y", "z"};
      for (uint32_t a = 0; a < 3; ++a) cloud.fields.push_back({axes[a], 4 * a + bytes[7 + a] % 4u, 7, 1});
      rosmsg::pointCloud(cloud, name);
      break;
    }
  }
#elif defined(FUZZ_MCAP)
  fuzzBagFile(bytes, ".mcap", "ros2bag");  // chronomap's own MCAP reader
#elif defined(FUZZ_DB3)
  fuzzBagFile(bytes, ".db3", "ros2bag");  // rosbag2's SQLite storage through libsqlite3
#elif defined(FUZZ_CDR)
  // The CDR decoders of ROS 2 messages: the first byte picks the message type, the rest is the
  // message (encapsulation header first); images and clouds go on through ros_messages.
  if (bytes.empty()) return;
  const std::span<const uint8_t> msg(bytes.data() + 1, bytes.size() - 1);
  switch (bytes[0] % 9) {
    case 0: {
      const auto im = cdr::image(msg, name);
      rosmsg::colourImage(im.view, name);
      break;
    }
    case 1: {
      const auto im = cdr::image(msg, name);
      rosmsg::depthCloud(im.view, nullptr, CameraIntrinsics{100.0, 100.0, 32.0, 24.0}, 1000.0, name);
      break;
    }
    case 2: rosmsg::pointCloud(cdr::cloud(msg, name).view, name); break;
    case 3: cdr::cameraInfo(msg, name); break;
    case 4: cdr::tfMessage(msg, name); break;
    case 5: cdr::odometry(msg, name); break;
    case 7: rosmsg::compressedColourImage(cdr::compressedImage(msg, name).view, name); break;
    case 8: {
      const auto depth = rosmsg::compressedDepthImage(cdr::compressedImage(msg, name).view, name);
      rosmsg::depthCloud(depth.view, nullptr, CameraIntrinsics{100.0, 100.0, 32.0, 24.0}, 1000.0, name);
      break;
    }
    default: cdr::poseStamped(msg, name); break;
  }
#elif defined(FUZZ_MODEL)
  // Saved models: a .rhythm or a .colour, told apart by their magic. A model that reads is also
  // checked against the map its seeds were fitted on (model_map.h), as predict and view check a
  // saved model, strictly and with --allow-other-map; a colour model that reads must also predict.
  static const TemporalMap map = fuzz::modelMap();
  FittedOnCheck check{name, "model-map", "refit", "--allow-other-map", false};
  auto checkBoth = [&](const auto& model) {
    try {
      checkFittedOn(model, map, check);
    } catch (const Error&) {
    }
    check.allow_other_map = true;
    checkFittedOn(model, map, check);
  };
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), "CMRH", 4) == 0) {
    const RhythmModels models = deserializeRhythm(bytes, name);
    if (!models.voxels.empty()) {
      volatile double p = RhythmModels::predict(models.voxels.back(), RhythmModel::Combined, 2500.0);
      (void)p;
    }
    checkBoth(models);
    return;
  }
  const ColourModel m = deserializeColour(bytes, name);
  volatile double c = m.predictMean(7.5)[0];
  if (!m.keys.empty()) c = m.predict(m.keys.size() - 1, 23.9)[2];
  (void)c;
  checkBoth(m);
#else
#error "define one FUZZ_* target"
#endif
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    fuzzOne(std::vector<uint8_t>(data, data + size));
  } catch (const chronomap::Error&) {
    // Rejected with a clear error: the expected outcome for bad input.
  }
  return 0;
}
