// chronomap --version: what a user quotes in a bug report must say which chronomap it was: the
// project's version, the commit, the file formats it reads and writes, the optional parts built.

#include <gtest/gtest.h>

#include <string>

#include "chronomap/store/cmap.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/store/tiled_file.h"
#include "test_support.h"

namespace chronomap {
namespace {

using test::cli;

/// The line of `text` that starts with `prefix` (without the prefix), or "(missing)".
std::string lineAfter(const std::string& text, const std::string& prefix) {
  const std::string lines = "\n" + text;
  const size_t at = lines.find("\n" + prefix);
  if (at == std::string::npos) return "(missing)";
  const size_t from = at + 1 + prefix.size();
  return lines.substr(from, lines.find('\n', from) - from);
}

std::string yesNo(bool built) { return built ? "yes" : "no"; }

TEST(VersionCli, NamesTheVersionFromTheProjectAndTheFormatsOfTheStore) {
  const auto r = test::runCommand(cli() + " --version");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The first line is what help2man and scripts read.
  EXPECT_EQ(r.out.substr(0, r.out.find('\n')), std::string("chronomap ") + CHRONOMAP_TEST_VERSION);
  const std::string cmap = std::to_string(kCmapFormatVersion);
  EXPECT_EQ(lineAfter(r.out, "  .cmap (session, 4D, diff and tiled maps): "), "reads 1 to " + cmap + ", writes " + cmap);
  EXPECT_EQ(lineAfter(r.out, "  tiled map tile table (index.cmap): "),
            "reads " + std::to_string(kOldestTileTableVersion) + " to " + std::to_string(kTileTableVersion) +
                ", writes " + std::to_string(kTileTableVersion));
  const std::string rhythm = std::to_string(kRhythmVersion);
  EXPECT_EQ(lineAfter(r.out, "  .rhythm (rhythm models): "), "reads 1 to " + rhythm + ", writes " + rhythm);
  const std::string colour = std::to_string(kColourVersion);
  EXPECT_EQ(lineAfter(r.out, "  .colour (colour models): "), "reads 1 to " + colour + ", writes " + colour);
}

TEST(VersionCli, NamesTheOptionalPartsThisBuildHas) {
  const auto r = test::runCommand(cli() + " --version");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(lineAfter(r.out, "  ROS 1 bags (librosbag): "), yesNo(CHRONOMAP_TEST_ROS1));
  EXPECT_EQ(lineAfter(r.out, "  ROS 2 bags (MCAP and SQLite .db3 storage): "), yesNo(CHRONOMAP_TEST_ROS2));
  EXPECT_EQ(lineAfter(r.out, "  MPI (mpirun -np N chronomap build): "), yesNo(CHRONOMAP_TEST_MPI));
  EXPECT_EQ(lineAfter(r.out, "  Python module: "), yesNo(CHRONOMAP_TEST_PYTHON));
}

TEST(VersionCli, NamesTheCommitItWasBuiltFrom) {
  const auto r = test::runCommand(cli() + " --version");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::string commit = lineAfter(r.out, "commit: ");
  const std::string source = CHRONOMAP_SOURCE_DIR;
  const auto head = test::runCommand("git -C '" + source + "' rev-parse HEAD");
  if (head.exit_code != 0) {
    EXPECT_EQ(commit, "unknown") << "not a git checkout: " << head.err;
    return;
  }
  // git describe's words (a tag, TAG-N-gHASH or HASH, and -dirty) name the checked-out commit.
  // Built, then committed without building again, this fails: build before testing.
  const std::string dirty = "-dirty";
  if (commit.size() > dirty.size() && commit.compare(commit.size() - dirty.size(), dirty.size(), dirty) == 0) {
    commit.resize(commit.size() - dirty.size());
  }
  ASSERT_NE(commit, "(missing)") << r.out;
  const auto named = test::runCommand("git -C '" + source + "' rev-parse --verify '" + commit + "^{commit}'");
  EXPECT_EQ(named.exit_code, 0) << commit << ": " << named.err;
  EXPECT_EQ(named.out, head.out) << commit;
}

}  // namespace
}  // namespace chronomap
