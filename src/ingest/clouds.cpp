// Point clouds: one PCD, PLY or XYZ file (one frame, posed by --pose), or a text list of
// "cloud tx ty tz qx qy qz qw" lines (one frame each).

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/core/pose.h"
#include "chronomap/ingest/cloud_io.h"
#include "image_dataset.h"
#include "readers.h"
#include "text_util.h"

namespace chronomap {

std::vector<CloudListEntry> parseCloudList(const std::string& text, const std::string& name) {
  std::vector<CloudListEntry> out;
  for (const auto& [number, line] : contentLines(text)) {
    const auto tok = splitWhitespace(line);
    const std::string ctx = name + ":" + std::to_string(number);
    if (tok.size() != 8) throw FormatError(ctx + ": expected 'cloud_file tx ty tz qx qy qz qw'");
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = parseDouble(tok[static_cast<size_t>(i) + 1], ctx);
    out.push_back({tok[0], poseFromTranslationQuaternion({v[0], v[1], v[2]}, v[3], v[4], v[5], v[6], ctx), ctx});
  }
  return out;
}

namespace readers {

namespace {


std::unique_ptr<Dataset> openClouds(const fs::path& path, const DatasetSettings& o) {
  if (isCloudFile(path)) {
    return std::make_unique<CloudDataset>(
        std::vector<CloudDataset::Item>{{path, o.pose.value_or(Eigen::Isometry3d::Identity())}});
  }
  if (o.pose) throw UsageError("--pose applies to a single cloud file, not to a list");
  std::vector<CloudDataset::Item> items;
  const std::string name = path.string();
  for (auto& entry : parseCloudList(readTextFile(path), name)) {
    fs::path cloud = entry.cloud;
    if (cloud.is_relative()) cloud = path.parent_path() / cloud;
    requireFile(cloud, "cloud listed at " + entry.source);
    items.push_back({cloud, entry.pose});
  }
  if (items.empty()) throw DataError(name + ": the cloud list is empty");
  return std::make_unique<CloudDataset>(std::move(items));
}

bool isClouds(const fs::path& path) {
  std::error_code ec;
  return !fs::is_directory(path, ec) && (isCloudFile(path) || dataExtension(path) == ".txt");
}

std::unique_ptr<Dataset> openCloudsChecked(const fs::path& path, const DatasetSettings& o) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    throw UsageError(path.string() + ": for clouds give one cloud file or a list file, not a folder");
  }
  return openClouds(path, o);
}

}  // namespace

DatasetReader clouds() {
  return {"clouds", {}, "a PCD, PLY or XYZ cloud (--pose), or a .txt list of 'cloud tx ty tz qx qy qz qw'", isClouds,
          openCloudsChecked, true};
}

}  // namespace readers

}  // namespace chronomap
