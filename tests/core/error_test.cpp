// describeError: the command line's exit code and message for each kind of failure.

#include <gtest/gtest.h>

#include <filesystem>
#include <new>
#include <stdexcept>
#include <system_error>

#include "chronomap/core/error.h"

namespace chronomap {
namespace {

template <typename E>
ErrorReport reportOf(const E& e) {
  return describeError(std::make_exception_ptr(e));
}

TEST(DescribeError, GivesEachKindOfFailureItsExitCodeAndWords) {
  const ErrorReport usage = reportOf(UsageError("--at is not a time"));
  EXPECT_EQ(usage.exit_code, 2);
  EXPECT_EQ(usage.message, "--at is not a time");
  const ErrorReport format = reportOf(FormatError("m.cmap: truncated"));
  EXPECT_EQ(format.exit_code, 1);
  EXPECT_EQ(format.message, "m.cmap: truncated");
  const ErrorReport io = reportOf(std::filesystem::filesystem_error(
      "cannot open", std::filesystem::path("/no/such/file"), std::make_error_code(std::errc::no_such_file_or_directory)));
  EXPECT_EQ(io.exit_code, 1);
  EXPECT_EQ(io.message, "/no/such/file: " + std::make_error_code(std::errc::no_such_file_or_directory).message());
  const ErrorReport pathless = reportOf(
      std::filesystem::filesystem_error("cannot list", std::make_error_code(std::errc::permission_denied)));
  EXPECT_EQ(pathless.message, std::make_error_code(std::errc::permission_denied).message());
  const ErrorReport memory = reportOf(std::bad_alloc());
  EXPECT_EQ(memory.exit_code, 1);
  EXPECT_EQ(memory.message, "out of memory");
  const ErrorReport other = reportOf(std::logic_error("broken invariant"));
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_EQ(other.message, "internal error: broken invariant");
  const ErrorReport unknown = reportOf(42);
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_EQ(unknown.message, "internal error");
}

}  // namespace
}  // namespace chronomap
