// How much memory the process may use, memory limits from flags, and the words of running out.

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <new>
#include <stdexcept>

#include "chronomap/core/error.h"
#include "chronomap/core/memory.h"
#include "test_support.h"

namespace chronomap {
namespace {

TEST(Memory, TheSmallestLimitOfMachineAddressSpaceAndCgroupCounts) {
  EXPECT_EQ(parseCgroupLimit("max"), std::nullopt);
  EXPECT_EQ(parseCgroupLimit(""), std::nullopt);
  EXPECT_EQ(parseCgroupLimit("9223372036854771712"), std::nullopt);  // cgroup v1's "no limit"
  EXPECT_EQ(parseCgroupLimit("1073741824"), uint64_t{1} << 30);
  EXPECT_EQ(parseCgroupLimit("-5"), std::nullopt);
  EXPECT_EQ(smallestMemoryLimit(size_t{8} << 30, std::nullopt, std::nullopt), size_t{8} << 30);
  EXPECT_EQ(smallestMemoryLimit(size_t{8} << 30, uint64_t{2} << 30, uint64_t{3} << 30), size_t{2} << 30);
  EXPECT_EQ(smallestMemoryLimit(size_t{8} << 30, std::nullopt, uint64_t{1} << 30), size_t{1} << 30);
  EXPECT_EQ(smallestMemoryLimit(0, std::nullopt, uint64_t{1} << 30), size_t{1} << 30);
  EXPECT_GT(processMemoryBytes(), 0u);
  if (!test::memoryLimitsApply()) return;  // sanitizers reserve address space of their own
  // Under an address-space limit the process may use at most that much.
  const uint64_t extra = uint64_t{1} << 30;
  EXPECT_EQ(test::exitCodeUnderMemoryLimit(extra, [] {
              rlimit limit{};
              ::getrlimit(RLIMIT_AS, &limit);
              return processMemoryBytes() <= limit.rlim_cur ? 0 : 1;
            }),
            0);
}

TEST(Memory, ATinyLimitIsALimit) {
  EXPECT_EQ(memoryLimitFromGib(0), 0u);
  EXPECT_EQ(memoryLimitFromGib(1e-12), 1u);
  EXPECT_EQ(memoryLimitFromGib(2), size_t{2} << 30);
  EXPECT_THROW(memoryLimitFromGib(-1), UsageError);
  EXPECT_THROW(memoryLimitFromGib(std::nan("")), UsageError);
  try {
    memoryLimitFromGib(1e9, "--cache");
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("--cache must be a number of GiB"), std::string::npos) << e.what();
  }
}

TEST(Memory, RunningOutSaysWhatWasBeingDoneAndWhatHelps) {
  EXPECT_EQ(outOfMemoryMessage(), "out of memory");
  std::string said;
  try {
    const MemoryActivity command("running chronomap integrate", "free memory");
    EXPECT_EQ(outOfMemoryMessage(), "out of memory while running chronomap integrate: free memory");
    {
      const MemoryActivity step("integrating 3 frame(s) at resolution 0.001 m", "use a coarser --resolution");
      throw std::bad_alloc();
    }
  } catch (const std::bad_alloc&) {
    said = describeError(std::current_exception()).message;  // after both scopes have ended
  }
  EXPECT_EQ(said, "out of memory while integrating 3 frame(s) at resolution 0.001 m: use a coarser --resolution");
  // The next command starts afresh.
  const MemoryActivity next("running chronomap diff", "give it less");
  EXPECT_EQ(outOfMemoryMessage(), "out of memory while running chronomap diff: give it less");
}

}  // namespace
}  // namespace chronomap
