// 3DMatch and 7-Scenes: frame-NNNNNN.depth.png (millimetres), frame-NNNNNN.pose.txt (4x4
// camera-to-world), colour as .color.png or .color.jpg, camera-intrinsics.txt; frames in the
// folder itself or in its seq-*/ folders.

#include <algorithm>

#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "image_dataset.h"
#include "readers.h"

namespace chronomap::readers {

namespace {

/// The frame number of "frame-NNNNNN.depth.png", or -1 for any other name.
long frameNumber(const std::string& name) {
  const std::string prefix = "frame-", suffix = ".depth.png";
  if (name.size() <= prefix.size() + suffix.size() || name.compare(0, prefix.size(), prefix) != 0 ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0) {
    return -1;
  }
  const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return -1;
  return std::stol(digits);
}

std::vector<fs::path> sortedFrames(const fs::path& dir) {
  std::vector<std::pair<long, fs::path>> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    const long n = frameNumber(e.path().filename().string());
    if (n >= 0) found.emplace_back(n, e.path());
  }
  std::sort(found.begin(), found.end());
  std::vector<fs::path> out;
  out.reserve(found.size());
  for (auto& [n, p] : found) out.push_back(p);
  return out;
}

std::vector<fs::path> threeDMatchSequences(const fs::path& root) {
  std::vector<fs::path> seqs;
  if (!sortedFrames(root).empty()) seqs.push_back(root);
  std::vector<fs::path> subdirs;
  for (const auto& e : fs::directory_iterator(root)) {
    if (e.is_directory() && e.path().filename().string().rfind("seq-", 0) == 0) subdirs.push_back(e.path());
  }
  std::sort(subdirs.begin(), subdirs.end());
  for (auto& s : subdirs) {
    if (!sortedFrames(s).empty()) seqs.push_back(s);
  }
  return seqs;
}

std::unique_ptr<Dataset> openThreeDMatch(const fs::path& root, const DatasetSettings& o) {
  fs::path intrinsics = root / "camera-intrinsics.txt";
  std::error_code ec;
  if (!fs::exists(intrinsics, ec)) intrinsics = root.parent_path() / "camera-intrinsics.txt";
  const CameraIntrinsics k = o.intrinsics ? *o.intrinsics : (requireFile(intrinsics, "camera intrinsics file"),
                                                               readIntrinsicsFile(intrinsics));
  std::vector<ImageFrame> frames;
  for (const auto& seq : threeDMatchSequences(root)) {
    for (const auto& depth : sortedFrames(seq)) {
      const std::string stem = depth.filename().string().substr(0, depth.filename().string().size() - 10);
      const fs::path pose = seq / (stem + ".pose.txt");
      // Colour as PNG or, as 7-Scenes, ScanNet and many copies store it, JPEG.
      fs::path colour = seq / (stem + ".color.png");
      if (!fs::exists(colour, ec)) colour = seq / (stem + ".color.jpg");
      requireFile(pose, "pose file");
      ImageFrame f;
      f.depth = depth;
      if (fs::exists(colour, ec)) f.colour = colour;
      f.pose = poseFromMatrix(readMatrix4(pose), pose.string());
      f.timestamp_s = static_cast<double>(frames.size());
      frames.push_back(f);
    }
  }
  if (frames.empty()) throw DataError(root.string() + ": no frame-*.depth.png files found");
  return std::make_unique<ImageDataset>("3dmatch", std::move(frames), k, checkedScale(o, 1000.0), 0,
                                        std::nullopt, o.colour, o.depth_cache);
}

bool isThreeDMatch(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec) && !threeDMatchSequences(path).empty();
}

std::unique_ptr<Dataset> openThreeDMatchChecked(const fs::path& root, const DatasetSettings& o) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw UsageError(root.string() + ": a 3DMatch dataset is a folder");
  return openThreeDMatch(root, o);
}

}  // namespace

DatasetReader threeDMatch() {
  return {"3dmatch", {"7scenes"}, "3DMatch / 7-Scenes folder: frame-*.depth.png (in it or seq-*/), frame-*.pose.txt",
          isThreeDMatch, openThreeDMatchChecked};
}

}  // namespace chronomap::readers
