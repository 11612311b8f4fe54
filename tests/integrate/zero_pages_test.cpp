// Zeroed blocks for fast mode's range cube (src/integrate/zero_pages.h): every byte reads zero
// when taken; the pool hands back the smallest kept block that fits and keeps within its limits.
// (Integrations that take a kept cube: integrator_test.cpp.)

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <utility>

#include "integrate/zero_pages.h"

namespace chronomap {
namespace {

using integrate_detail::ZeroPages;
using integrate_detail::ZeroPool;

bool allZero(const ZeroPages& z) {
  const auto* p = static_cast<const unsigned char*>(z.data());
  for (size_t i = 0; i < z.bytes(); ++i) {
    if (p[i] != 0) return false;
  }
  return true;
}

TEST(ZeroPages, BlocksReadZeroWhenTaken) {
  EXPECT_EQ(ZeroPages().bytes(), 0u);
  EXPECT_EQ(ZeroPages(0).data(), nullptr);
  for (size_t bytes : {size_t{1}, size_t{4096}, size_t{3} << 20, size_t{7'800'000}}) {
    ZeroPages z(bytes);
    ASSERT_GE(z.bytes(), bytes);
    ASSERT_NE(z.data(), nullptr);
    EXPECT_TRUE(allZero(z)) << bytes;
    std::memset(z.data(), 0xAB, z.bytes());
  }
}

TEST(ZeroPages, MovesHandTheBlockOver) {
  ZeroPages a(100);
  static_cast<uint32_t*>(a.data())[3] = 7;
  void* const block = a.data();
  ZeroPages b(std::move(a));
  EXPECT_EQ(a.data(), nullptr);  // NOLINT(bugprone-use-after-move): a moved-from block is empty
  EXPECT_EQ(b.data(), block);
  EXPECT_EQ(static_cast<uint32_t*>(b.data())[3], 7u);
  ZeroPages c(10);
  c = std::move(b);
  EXPECT_EQ(c.data(), block);
}

TEST(ZeroPool, GivesTheSmallestKeptBlockThatFitsAndKeepsItsLimits) {
  ZeroPool::clear();
  ZeroPages small(size_t{1} << 20), large(size_t{8} << 20);
  void* const small_at = small.data();
  void* const large_at = large.data();
  const size_t small_bytes = small.bytes(), large_bytes = large.bytes();
  ZeroPool::giveBack(std::move(large));
  ZeroPool::giveBack(std::move(small));
  EXPECT_EQ(ZeroPool::keptBlocks(), 2u);
  EXPECT_EQ(ZeroPool::keptBytes(), small_bytes + large_bytes);
  ZeroPages a = ZeroPool::take(1000);
  EXPECT_EQ(a.data(), small_at);  // the smallest that fits
  ZeroPages b = ZeroPool::take(size_t{3} << 20);
  EXPECT_EQ(b.data(), large_at);
  EXPECT_EQ(ZeroPool::keptBlocks(), 0u);
  ZeroPages c = ZeroPool::take(100);  // nothing kept: a new block
  EXPECT_NE(c.data(), nullptr);
  EXPECT_TRUE(allZero(c));
  // A new block has the room asked for; a kept one need only hold the bytes.
  ZeroPages d = ZeroPool::take(100, size_t{1} << 20);
  EXPECT_GE(d.bytes(), size_t{1} << 20);
  EXPECT_TRUE(allZero(d));
  const size_t d_bytes = d.bytes();
  ZeroPool::giveBack(std::move(d));
  ZeroPages e = ZeroPool::take(1000, size_t{4} << 20);
  EXPECT_EQ(e.bytes(), d_bytes);
  // At most kMaxBlocks blocks: giving back more drops the smallest.
  for (size_t i = 0; i < ZeroPool::kMaxBlocks + 2; ++i) ZeroPool::giveBack(ZeroPages((i + 1) << 20));
  EXPECT_EQ(ZeroPool::keptBlocks(), ZeroPool::kMaxBlocks);
  EXPECT_LE(ZeroPool::keptBytes(), ZeroPool::kMaxBytes);
  ZeroPages largest = ZeroPool::take((ZeroPool::kMaxBlocks + 2) << 20);
  EXPECT_NE(largest.data(), nullptr);
  EXPECT_EQ(ZeroPool::keptBlocks(), ZeroPool::kMaxBlocks - 1);  // it was kept
  // A block beyond kMaxBytes is not kept.
  ZeroPool::clear();
  ZeroPool::giveBack(ZeroPages(ZeroPool::kMaxBytes + 1));
  EXPECT_EQ(ZeroPool::keptBlocks(), 0u);
  ZeroPool::clear();
}

}  // namespace
}  // namespace chronomap
