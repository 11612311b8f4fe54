// ScanNet's exported folder: depth/N.png, pose/N.txt (-inf where its reconstruction lost
// the camera), color/N.jpg with intrinsics of its own, intrinsic/.

#include <algorithm>

#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "image_dataset.h"
#include "readers.h"

namespace chronomap::readers {

namespace {

/// Files "N.ext" of `dir` (N a whole number), in the order of N.
std::vector<std::pair<long, fs::path>> numberedFiles(const fs::path& dir, const std::string& ext) {
  std::vector<std::pair<long, fs::path>> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() != ext) continue;
    const std::string digits = name.substr(0, name.size() - ext.size());
    if (digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    found.emplace_back(std::stol(digits), e.path());
  }
  std::sort(found.begin(), found.end());
  return found;
}

bool isScanNet(const fs::path& root) {
  std::error_code ec;
  return fs::is_directory(root / "depth", ec) && fs::is_directory(root / "pose", ec) &&
         fs::is_directory(root / "intrinsic", ec);
}

std::unique_ptr<Dataset> openScanNet(const fs::path& root, const DatasetSettings& o) {
  const fs::path depth_k_file = root / "intrinsic" / "intrinsic_depth.txt";
  const fs::path colour_k_file = root / "intrinsic" / "intrinsic_color.txt";
  const CameraIntrinsics k = o.intrinsics ? *o.intrinsics : (requireFile(depth_k_file, "depth intrinsics file"),
                                                               readIntrinsicsFile(depth_k_file));
  std::error_code ec;
  const bool has_colour = fs::is_directory(root / "color", ec);
  std::optional<CameraIntrinsics> colour_k;
  if (has_colour) {
    requireFile(colour_k_file, "colour intrinsics file");
    colour_k = readIntrinsicsFile(colour_k_file);
  }
  std::vector<ImageFrame> frames;
  size_t dropped = 0;
  for (const auto& [n, depth] : numberedFiles(root / "depth", ".png")) {
    const fs::path pose = root / "pose" / (std::to_string(n) + ".txt");
    requireFile(pose, "pose file");
    const Eigen::Matrix4d m = readMatrix4(pose);
    // ScanNet marks frames its reconstruction lost with -inf poses: left out and counted.
    if (!m.allFinite()) {
      ++dropped;
      continue;
    }
    ImageFrame f;
    f.depth = depth;
    if (has_colour) {
      fs::path colour = root / "color" / (std::to_string(n) + ".jpg");
      if (!fs::exists(colour, ec)) colour = root / "color" / (std::to_string(n) + ".png");
      requireFile(colour, "colour frame");
      f.colour = colour;
    }
    f.pose = poseFromMatrix(m, pose.string());
    f.timestamp_s = static_cast<double>(n);
    frames.push_back(f);
  }
  if (frames.empty()) {
    throw DataError(root.string() + ": no depth/N.png frame with a valid pose (" + std::to_string(dropped) +
                    " with invalid poses)");
  }
  return std::make_unique<ImageDataset>("scannet", std::move(frames), k, checkedScale(o, 1000.0), dropped,
                                        colour_k, o.colour, o.depth_cache);
}

std::unique_ptr<Dataset> openScanNetChecked(const fs::path& root, const DatasetSettings& o) {
  if (!isScanNet(root)) {
    throw UsageError(root.string() + ": a ScanNet export is a folder with depth/, pose/ and intrinsic/");
  }
  return openScanNet(root, o);
}

}  // namespace

DatasetReader scanNet() {
  return {"scannet", {}, "ScanNet export folder: depth/, pose/ and intrinsic/ (color/ optional)", isScanNet,
          openScanNetChecked};
}

}  // namespace chronomap::readers
