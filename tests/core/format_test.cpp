// Numbers for people: counts with their noun in the singular or plural, and numbers in as many
// digits as tell them apart.

#include <gtest/gtest.h>

#include "chronomap/core/format.h"

namespace chronomap {
namespace {

TEST(Format, CountsAndExactNumbers) {
  EXPECT_EQ(countOf(1, "session"), "1 session");
  EXPECT_EQ(countOf(0, "session"), "0 sessions");
  EXPECT_EQ(countOf(12, "changed object"), "12 changed objects");
  EXPECT_EQ(exactNumber(0.05), "0.05");
  EXPECT_EQ(exactNumber(0.05 + 1e-12), "0.050000000001");
  EXPECT_EQ(exactNumber(-3.0), "-3");
}

}  // namespace
}  // namespace chronomap
