#include "chronomap/ingest/dataset.h"

namespace chronomap {

std::shared_ptr<const ImageU16> DepthImageCache::find(const std::filesystem::path& path) const {
  std::shared_ptr<const ImageU16> found;
  {
    const std::lock_guard lock(mutex_);
    const auto it = images_.find(path.string());
    if (it != images_.end()) found = it->second;
  }
  if (found) ++hits_;
  return found;
}

bool DepthImageCache::keep(const std::filesystem::path& path, std::shared_ptr<const ImageU16> image) {
  if (!image) return false;
  const size_t need = bytesOf(path, *image);
  const std::lock_guard lock(mutex_);
  if (need > budget_ - bytes_) return false;
  if (!images_.try_emplace(path.string(), std::move(image)).second) return false;
  bytes_ += need;
  return true;
}

size_t DepthImageCache::bytesOf(const std::filesystem::path& path, const ImageU16& image) {
  // The pixels, the key, the image and its node in the table (two pointers and a hash), and the
  // shared pointer's control block.
  constexpr size_t kOverhead = sizeof(ImageU16) + sizeof(std::string) + 3 * sizeof(void*) + 32;
  return image.pixels.size() * sizeof(uint16_t) + path.native().size() + kOverhead;
}

size_t DepthImageCache::bytes() const {
  const std::lock_guard lock(mutex_);
  return bytes_;
}

void DepthImageCache::clear() {
  const std::lock_guard lock(mutex_);
  images_ = {};
  bytes_ = 0;
}

size_t DepthImageCache::images() const {
  const std::lock_guard lock(mutex_);
  return images_.size();
}

}  // namespace chronomap
