#pragma once
/// @file
/// Internal to the integrate module: memory that reads as zero when it is taken, for the range
/// cube of fast mode and the bounding-box store (ray_accumulator.h, CubeStore and DenseStore),
/// and a pool that keeps such blocks for the next integration.

#include <cstddef>

namespace chronomap::integrate_detail {

/// A block of memory whose bytes are all zero when taken. On Linux it comes straight from the
/// system (mmap): the kernel gives each page its zeros when the page is first written, so a
/// large block costs only the pages that are used, and the block asks for transparent huge pages
/// (MADV_HUGEPAGE: one fault for 2 MiB instead of 512). Elsewhere, and in AddressSanitizer
/// builds (which check heap blocks only), calloc. Move-only.
class ZeroPages {
 public:
  ZeroPages() = default;
  /// A block of at least `bytes` (none for 0). @throw std::bad_alloc when the system has no room.
  explicit ZeroPages(size_t bytes);
  ~ZeroPages();
  ZeroPages(ZeroPages&& other) noexcept;
  ZeroPages& operator=(ZeroPages&& other) noexcept;
  ZeroPages(const ZeroPages&) = delete;
  ZeroPages& operator=(const ZeroPages&) = delete;

  void* data() const { return data_; }
  /// Bytes of the block (0 for none).
  size_t bytes() const { return bytes_; }

 private:
  void release() noexcept;
  void* data_ = nullptr;
  size_t bytes_ = 0;
};

/// Blocks given back with every byte zero, for the next taker: a range cube and a box store are
/// zero at rest (each frame clears the cells it wrote), so the next integration's need not be
/// zeroed or faulted in again (on the five 3DMatch frames at 0.05 m, zeroing a new 7.4 MiB cube
/// was 7 % of fast mode's time).
/// Thread-safe. Keeps at most kMaxBlocks blocks and kMaxBytes in all; what it cannot keep it
/// frees.
class ZeroPool {
 public:
  static constexpr size_t kMaxBlocks = 8;
  static constexpr size_t kMaxBytes = size_t{64} << 20;
  /// The smallest kept block of at least `bytes`, or a new one of `room` bytes when that is
  /// more (else `bytes`).
  static ZeroPages take(size_t bytes, size_t room = 0);
  /// Keeps `block`, whose bytes must all be zero (or frees it). Never throws.
  static void giveBack(ZeroPages block) noexcept;
  /// Replaces `block` by take(bytes, room), taken before the old block goes (back to the pool
  /// when `clean`, else freed): a failed take leaves `block` as it was.
  static void replace(ZeroPages& block, size_t bytes, size_t room, bool clean);
  /// Frees every kept block (for tests).
  static void clear();
  /// Blocks and bytes kept now (for tests).
  static size_t keptBlocks();
  static size_t keptBytes();
};

}  // namespace chronomap::integrate_detail
