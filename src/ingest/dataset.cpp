#include "chronomap/ingest/dataset.h"

#include <algorithm>
#include <cmath>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/core/pose.h"
#include "chronomap/ingest/registry.h"
#include "text_util.h"

namespace chronomap {

namespace fs = std::filesystem;

CameraIntrinsics parseIntrinsics(const std::string& text) {
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  const auto tok = splitWhitespace(s);
  if (tok.size() != 4) throw UsageError("intrinsics '" + text + "' must be four numbers: fx,fy,cx,cy");
  CameraIntrinsics k;
  try {
    k = {parseDouble(tok[0], "fx"), parseDouble(tok[1], "fy"), parseDouble(tok[2], "cx"), parseDouble(tok[3], "cy")};
  } catch (const FormatError& e) {
    throw UsageError(std::string("intrinsics: ") + e.what());
  }
  if (!intrinsicsValid(k)) {
    throw UsageError("intrinsics '" + text + "': focal lengths must be positive and all values finite");
  }
  return k;
}

CameraIntrinsics readIntrinsicsFile(const fs::path& path) {
  return parseIntrinsicsText(readTextFile(path), path.string());
}

CameraIntrinsics parseIntrinsicsText(const std::string& text, const std::string& name) {
  std::vector<double> v;
  for (const auto& [number, line] : contentLines(text)) {
    for (const auto& t : splitWhitespace(line)) v.push_back(parseDouble(t, name + ":" + std::to_string(number)));
  }
  CameraIntrinsics k;
  if (v.size() == 9) {
    k = {v[0], v[4], v[2], v[5]};
  } else if (v.size() == 16) {  // a 4x4 projection (ScanNet's intrinsic_*.txt)
    k = {v[0], v[5], v[2], v[6]};
  } else if (v.size() == 4) {
    k = {v[0], v[1], v[2], v[3]};
  } else {
    throw FormatError(name + ": expected a 3x3 matrix or 'fx fy cx cy', found " + std::to_string(v.size()) + " numbers");
  }
  if (!intrinsicsValid(k)) {
    throw FormatError(name + ": focal lengths must be positive and all values finite");
  }
  return k;
}

Eigen::Matrix4d parseMatrix4(const std::string& text, const std::string& name) {
  std::vector<double> v;
  for (const auto& [number, line] : contentLines(text)) {
    for (const auto& t : splitWhitespace(line)) v.push_back(parseDouble(t, name + ":" + std::to_string(number)));
  }
  if (v.size() != 16) throw FormatError(name + ": expected a 4x4 matrix, found " + std::to_string(v.size()) + " numbers");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<size_t>(r) * 4 + static_cast<size_t>(c)];
  }
  return m;
}

namespace {

/// Another dataset read with its world frame turned (DatasetSettings::world_rotation).
class RotatedDataset : public Dataset {
 public:
  RotatedDataset(std::unique_ptr<Dataset> inner, const Eigen::Matrix3d& rotation) : inner_(std::move(inner)) {
    rotation_.linear() = rotation;
  }
  size_t size() const override { return inner_->size(); }
  Frame load(size_t i) const override {
    Frame f = inner_->load(i);
    f.T_world_sensor = rotation_ * f.T_world_sensor;
    return f;
  }
  Eigen::Isometry3d poseOf(size_t i) const override { return rotation_ * inner_->poseOf(i); }
  std::string format() const override { return inner_->format(); }
  size_t framesDropped() const override { return inner_->framesDropped(); }
  std::string droppedReasons() const override { return inner_->droppedReasons(); }
  std::optional<double> recordedAt() const override { return inner_->recordedAt(); }

 private:
  std::unique_ptr<Dataset> inner_;
  Eigen::Isometry3d rotation_ = Eigen::Isometry3d::Identity();
};

}  // namespace

std::unique_ptr<Dataset> openDataset(const fs::path& path, const DatasetSettings& options) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file or folder");
  if (options.depth_scale && !(*options.depth_scale > 0.0 && std::isfinite(*options.depth_scale))) {
    throw UsageError("the depth scale must be a positive number of image units per metre, got " +
                     std::to_string(*options.depth_scale));
  }
  const DatasetReader reader =
      options.format == "auto" ? detectDatasetReader(path) : datasetReaderNamed(options.format);
  if (!reader.takes_pose && options.pose) throw UsageError("--pose applies to a single cloud file");
  if (!options.world_rotation || options.world_rotation->isIdentity()) return reader.open(path, options);
  const Eigen::Matrix3d& r = *options.world_rotation;
  if (!r.allFinite() || !(r.transpose() * r).isIdentity(kRotationOrthonormalityTolerance) || r.determinant() < 0.0) {
    throw UsageError(path.string() + ": the world rotation is not a proper rotation");
  }
  return std::make_unique<RotatedDataset>(reader.open(path, options), r);
}

}  // namespace chronomap
