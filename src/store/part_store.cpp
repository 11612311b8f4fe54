#include "chronomap/store/part_store.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

std::string cubeFile(const Cube& c) {
  return std::to_string(c.level) + "_" + std::to_string(c.corner.x) + "_" + std::to_string(c.corner.y) + "_" +
         std::to_string(c.corner.z) + ".parts";
}

}  // namespace

PartStore::PartStore(fs::path folder, size_t limit_bytes) : folder_(std::move(folder)), limit_(limit_bytes) {}

PartStore::~PartStore() {
  std::error_code ec;
  if (created_) fs::remove_all(folder_, ec);
}

void PartStore::add(const Cube& cube, const SessionPart& p) {
  if (limit_ != 0 && bytes_ + sizeof(SessionPart) > limit_) spill();
  held_[cube].push_back(p);
  bytes_ += sizeof(SessionPart);
  stats_.peak_bytes = std::max(stats_.peak_bytes, bytes_);
  cubes_.insert(cube);
}

std::vector<SessionPart> PartStore::take(const Cube& cube) {
  std::vector<SessionPart> out;
  const fs::path file = folder_ / cubeFile(cube);
  if (created_ && fs::exists(file)) {
    const std::vector<uint8_t> bytes = readFileBytes(file);
    out.resize(bytes.size() / sizeof(SessionPart));
    std::memcpy(static_cast<void*>(out.data()), bytes.data(), out.size() * sizeof(SessionPart));
    fs::remove(file);
  }
  if (const auto it = held_.find(cube); it != held_.end()) {
    out.insert(out.end(), it->second.begin(), it->second.end());
    bytes_ -= it->second.size() * sizeof(SessionPart);
    held_.erase(it);
  }
  return out;
}

void PartStore::spill() {
  if (!created_) {
    fs::create_directories(folder_);
    created_ = true;
  }
  for (auto& [cube, parts] : held_) {
    std::ofstream out(folder_ / cubeFile(cube), std::ios::binary | std::ios::app);
    out.write(reinterpret_cast<const char*>(parts.data()),
              static_cast<std::streamsize>(parts.size() * sizeof(SessionPart)));
    if (!out) throw IoError((folder_ / cubeFile(cube)).string() + ": cannot write (disk full?)");
    stats_.spilled_bytes += parts.size() * sizeof(SessionPart);
  }
  held_.clear();
  bytes_ = 0;
  ++stats_.spills;
}

}  // namespace chronomap
