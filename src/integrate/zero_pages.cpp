#include "zero_pages.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <new>
#include <utility>
#include <vector>
// AddressSanitizer sees overflows of heap blocks only: its builds take calloc's.
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CHRONOMAP_ZERO_PAGES_FROM_HEAP 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define CHRONOMAP_ZERO_PAGES_FROM_HEAP 1
#endif
#if defined(__linux__) && !defined(CHRONOMAP_ZERO_PAGES_FROM_HEAP)
#define CHRONOMAP_ZERO_PAGES_MMAP 1
#include <sys/mman.h>
#endif

namespace chronomap::integrate_detail {

ZeroPages::ZeroPages(size_t bytes) {
  if (bytes == 0) return;
#if defined(CHRONOMAP_ZERO_PAGES_MMAP)
  // Whole huge pages at a huge page's boundary (what transparent huge pages need): one huge
  // page more is mapped, and what lies outside the aligned block is given back.
  constexpr size_t kHugePage = size_t{2} << 20;
  if (bytes > SIZE_MAX - 2 * kHugePage) throw std::bad_alloc();
  const size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = mmap(nullptr, rounded + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  const auto at = reinterpret_cast<uintptr_t>(p);
  const uintptr_t aligned = (at + kHugePage - 1) / kHugePage * kHugePage;
  if (aligned > at) munmap(p, aligned - at);
  if (const size_t tail = kHugePage - (aligned - at); tail > 0) {
    munmap(reinterpret_cast<void*>(aligned + rounded), tail);
  }
  // A hint: where the system has no huge pages to give, the block keeps small ones.
  (void)madvise(reinterpret_cast<void*>(aligned), rounded, MADV_HUGEPAGE);
  data_ = reinterpret_cast<void*>(aligned);
  bytes_ = rounded;
#else
  data_ = std::calloc(bytes, 1);
  if (!data_) throw std::bad_alloc();
  bytes_ = bytes;
#endif
}

ZeroPages::~ZeroPages() { release(); }

ZeroPages::ZeroPages(ZeroPages&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)), bytes_(std::exchange(other.bytes_, 0)) {}

ZeroPages& ZeroPages::operator=(ZeroPages&& other) noexcept {
  if (this != &other) {
    release();
    data_ = std::exchange(other.data_, nullptr);
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

void ZeroPages::release() noexcept {
  if (!data_) return;
#if defined(CHRONOMAP_ZERO_PAGES_MMAP)
  munmap(data_, bytes_);
#else
  std::free(data_);
#endif
  data_ = nullptr;
  bytes_ = 0;
}

namespace {

struct Kept {
  std::mutex mutex;
  std::vector<ZeroPages> blocks;
  size_t bytes = 0;
};

// Never destroyed: an accumulator destroyed during the program's exit may still give back.
// Room for every block it keeps, so that giving back never allocates (nor throws).
Kept& kept() {
  static Kept* const k = [] {
    auto* made = new Kept;
    made->blocks.reserve(ZeroPool::kMaxBlocks);
    return made;
  }();
  return *k;
}

}  // namespace

ZeroPages ZeroPool::take(size_t bytes, size_t room) {
  {
    Kept& k = kept();
    std::lock_guard<std::mutex> lock(k.mutex);
    size_t best = k.blocks.size();
    for (size_t i = 0; i < k.blocks.size(); ++i) {
      if (k.blocks[i].bytes() >= bytes && (best == k.blocks.size() || k.blocks[i].bytes() < k.blocks[best].bytes())) {
        best = i;
      }
    }
    if (best < k.blocks.size()) {
      ZeroPages out = std::move(k.blocks[best]);
      k.blocks.erase(k.blocks.begin() + static_cast<std::ptrdiff_t>(best));
      k.bytes -= out.bytes();
      return out;
    }
  }
  return ZeroPages(std::max(bytes, room));
}

void ZeroPool::giveBack(ZeroPages block) noexcept {
  if (block.bytes() == 0 || block.bytes() > kMaxBytes) return;
  Kept& k = kept();
  std::lock_guard<std::mutex> lock(k.mutex);
  // Room by dropping the smallest kept blocks first: a larger block serves more takers.
  while (!k.blocks.empty() && (k.blocks.size() >= kMaxBlocks || k.bytes + block.bytes() > kMaxBytes)) {
    size_t smallest = 0;
    for (size_t i = 1; i < k.blocks.size(); ++i) {
      if (k.blocks[i].bytes() < k.blocks[smallest].bytes()) smallest = i;
    }
    if (k.blocks[smallest].bytes() > block.bytes()) return;  // the block given back is the smallest: dropped
    k.bytes -= k.blocks[smallest].bytes();
    k.blocks.erase(k.blocks.begin() + static_cast<std::ptrdiff_t>(smallest));
  }
  const size_t bytes = block.bytes();
  k.blocks.push_back(std::move(block));  // within the reserved room: no allocation
  k.bytes += bytes;
}

void ZeroPool::replace(ZeroPages& block, size_t bytes, size_t room, bool clean) {
  ZeroPages old = std::exchange(block, take(bytes, room));
  if (clean) giveBack(std::move(old));
}

void ZeroPool::clear() {
  Kept& k = kept();
  std::lock_guard<std::mutex> lock(k.mutex);
  k.blocks.clear();
  k.bytes = 0;
}

size_t ZeroPool::keptBlocks() {
  Kept& k = kept();
  std::lock_guard<std::mutex> lock(k.mutex);
  return k.blocks.size();
}

size_t ZeroPool::keptBytes() {
  Kept& k = kept();
  std::lock_guard<std::mutex> lock(k.mutex);
  return k.bytes;
}

}  // namespace chronomap::integrate_detail

// Unity builds put the next file of the batch after this one.
#undef CHRONOMAP_ZERO_PAGES_FROM_HEAP
#undef CHRONOMAP_ZERO_PAGES_MMAP
