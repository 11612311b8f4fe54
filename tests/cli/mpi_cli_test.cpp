// `mpirun -np N chronomap build`: the same bytes as one process whatever N, the previous map kept
// when a rank is killed, and bad input refused on every rank without a hang. Registered only
// when chronomap was built with MPI (always under CI=true: CMake fails without it).

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;
using test::cli;
using test::runCommand;

/// mpirun with N ranks (as root in containers, more ranks than cores allowed), each process
/// limited to 120 s so that a hang fails the test instead of stalling the suite (a registered
/// build under AddressSanitizer took over 60 s on a loaded 2-core machine). LeakSanitizer
/// would report Open MPI's own allocations that it keeps to the end: off under MPI. Shared
/// memory without the kernel's cross-process copy, which containers often forbid.
std::string mpirun(int ranks) {
  return "ASAN_OPTIONS=detect_leaks=0 OMPI_MCA_btl_vader_single_copy_mechanism=none timeout 120 " +
         std::string(CHRONOMAP_MPIEXEC) +
         " --allow-run-as-root --oversubscribe -np " + std::to_string(ranks) + " ";
}

/// A tiny simulated scene of `sessions` TUM folders. @return their paths, space-separated.
std::string simulate(const test::TempDir& tmp, int sessions, double scale) {
  const test::CommandResult r = runCommand(cli() + " simulate --preset tiny --sessions " + std::to_string(sessions) +
                                           " --resolution-scale " + std::to_string(scale) + " -o " +
                                           (tmp / "sim").string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::string paths;
  for (int i = 0; i < sessions; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "session_%02d", i);
    paths += " " + (tmp / "sim" / name).string();
  }
  return paths;
}

nlohmann::json withoutMap(const std::string& out) {
  nlohmann::json j = nlohmann::json::parse(out);
  j.erase("map");
  return j;
}

TEST(MpiBuild, AnyNumberOfRanksWritesTheSameBytes) {
  test::TempDir tmp;
  const std::string sessions = simulate(tmp, 3, 0.1);
  const fs::path plain = tmp / "plain.cmap";
  const test::CommandResult one = runCommand(cli() + " build " + plain.string() + sessions + " --json");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  const std::vector<uint8_t> expected = test::bytesOf(plain);
  ASSERT_FALSE(expected.empty());
  // 4 ranks hand out 48 frames of each next recording ahead, more than its 32.
  for (int n = 1; n <= 4; ++n) {
    const fs::path map = tmp / ("ranks" + std::to_string(n) + ".cmap");
    const test::CommandResult r = runCommand(mpirun(n) + cli() + " build " + map.string() + sessions + " --json");
    ASSERT_EQ(r.exit_code, 0) << n << " rank(s): " << r.err;
    EXPECT_TRUE(test::bytesOf(map) == expected) << n << " rank(s)";
    // One report (rank 0's), the same as the process alone gives.
    EXPECT_EQ(withoutMap(r.out), withoutMap(one.out)) << n << " rank(s)";
  }
  // Adding to an existing map: the sessions read from it stay as they are.
  const fs::path grown = tmp / "grown.cmap";
  fs::copy_file(plain, grown);
  fs::copy_file(plain, tmp / "grown_plain.cmap");
  const std::string more = " --replace" + sessions;
  ASSERT_EQ(runCommand(cli() + " build " + (tmp / "grown_plain.cmap").string() + more).exit_code, 0);
  ASSERT_EQ(runCommand(mpirun(2) + cli() + " build " + grown.string() + more).exit_code, 0);
  EXPECT_TRUE(test::bytesOf(grown) == test::bytesOf(tmp / "grown_plain.cmap"));
}

TEST(MpiBuild, BadInputFailsOnEveryRankWithoutWaiting) {
  test::TempDir tmp;
  const std::string sessions = simulate(tmp, 2, 0.1);
  const std::string map = (tmp / "m.cmap").string();
  // A missing folder: every rank refuses it before integrating; rank 0 says so.
  const std::string missing = (tmp / "no_such_session").string();
  test::CommandResult r = runCommand(mpirun(3) + cli() + " build " + map + sessions + " " + missing);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, 124) << "timed out: a rank waited for another";
  EXPECT_NE(r.err.find("dataset '" + missing + "' does not exist"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(map));
  // An empty folder (the second of three), found when rank 0 opens it: the error the process
  // alone gives.
  fs::create_directories(tmp / "empty");
  const std::string with_bad = " " + (tmp / "sim" / "session_00").string() + " " + (tmp / "empty").string() + " " +
                               (tmp / "sim" / "session_01").string();
  const test::CommandResult alone = runCommand(cli() + " build " + map + with_bad);
  ASSERT_NE(alone.exit_code, 0);
  r = runCommand(mpirun(3) + cli() + " build " + map + with_bad);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, 124) << "timed out: a rank waited for another";
  const std::string message = alone.err.substr(0, alone.err.find('\n'));
  EXPECT_NE(r.err.find(message), std::string::npos) << "alone: " << alone.err << "\nranks: " << r.err;
  EXPECT_FALSE(fs::exists(map));
}

// One recording's frames are cast on every rank (rank 0 merging them in frame order): the bytes of
// one process, and rank 0 says how many frames each rank cast.
TEST(MpiBuild, OneRecordingsFramesAreCastOnEveryRank) {
  test::TempDir tmp;
  const std::string session = simulate(tmp, 1, 0.2);
  const fs::path plain = tmp / "plain.cmap";
  ASSERT_EQ(runCommand(cli() + " build " + plain.string() + session).exit_code, 0);
  for (int n : {2, 3}) {
    const fs::path map = tmp / ("ranks" + std::to_string(n) + ".cmap");
    const test::CommandResult r = runCommand(mpirun(n) + cli() + " build " + map.string() + session);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(test::bytesOf(map) == test::bytesOf(plain)) << n << " ranks";
    // "rank 0 cast F frame(s), rank 1 G, ...": every other rank cast some.
    const size_t at = r.err.find("rank 0 cast ");
    ASSERT_NE(at, std::string::npos) << r.err;
    const std::string line = r.err.substr(at, r.err.find('\n', at) - at);
    for (int k = 1; k < n; ++k) {
      const std::string rank = ", rank " + std::to_string(k) + " ";
      const size_t p = line.find(rank);
      ASSERT_NE(p, std::string::npos) << line;
      EXPECT_GT(std::stoul(line.substr(p + rank.size())), 0u) << line;
    }
  }
}

// Rank 0 adds each session as soon as every earlier one is (while the others cast the next
// recording's frames): recordings given out of time order, with registration (which adds them all
// at the end), and with two at the same time (refused as one process refuses them) give one
// process's bytes and report.
TEST(MpiBuild, SessionsAreAddedInTimeOrderWhateverTheOrderGiven) {
  test::TempDir tmp;
  simulate(tmp, 3, 0.1);
  const auto at = [&](int k) { return " " + (tmp / "sim" / ("session_0" + std::to_string(k))).string(); };
  const std::string shuffled = at(2) + at(0) + at(1);
  for (const std::string& flags : {std::string(" --json"), std::string(" --json --register")}) {
    const fs::path plain = tmp / "plain.cmap", ranks = tmp / "ranks.cmap";
    fs::remove(plain);
    fs::remove(ranks);
    const test::CommandResult one = runCommand(cli() + " build " + plain.string() + shuffled + flags);
    ASSERT_EQ(one.exit_code, 0) << one.err;
    const test::CommandResult two = runCommand(mpirun(2) + cli() + " build " + ranks.string() + shuffled + flags);
    ASSERT_EQ(two.exit_code, 0) << two.err;
    EXPECT_TRUE(test::bytesOf(ranks) == test::bytesOf(plain)) << flags;
    EXPECT_EQ(withoutMap(two.out), withoutMap(one.out)) << flags;
  }
  const std::string same = " --times 2012-03-01T10:00:00Z,2012-03-02T10:00:00Z,2012-03-01T10:00:00Z";
  const fs::path map = tmp / "same.cmap";
  const test::CommandResult alone = runCommand(cli() + " build " + map.string() + at(0) + at(1) + at(2) + same);
  ASSERT_EQ(alone.exit_code, 2) << alone.err;
  const test::CommandResult r = runCommand(mpirun(2) + cli() + " build " + map.string() + at(0) + at(1) + at(2) + same);
  EXPECT_EQ(r.exit_code, 2);
  const size_t error = alone.err.find("error: ");
  ASSERT_NE(error, std::string::npos) << alone.err;
  const std::string message = alone.err.substr(error, alone.err.find('\n', error) - error);
  EXPECT_NE(message.find("have the same time"), std::string::npos) << message;
  EXPECT_NE(r.err.find(message), std::string::npos) << "alone: " << alone.err << "\nranks: " << r.err;
  EXPECT_FALSE(fs::exists(map));
}

// A frame that cannot be read, wherever it is cast: the error the process alone gives, on every
// rank count, without a hang, and no map written.
TEST(MpiBuild, AnUnreadableFrameGivesTheErrorOfOneProcess) {
  test::TempDir tmp;
  const std::string sessions = simulate(tmp, 2, 0.1);
  std::vector<fs::path> depths;
  for (const auto& e : fs::directory_iterator(tmp / "sim" / "session_01" / "depth")) depths.push_back(e.path());
  std::sort(depths.begin(), depths.end());
  ASSERT_GT(depths.size(), 6u);
  for (size_t k : {depths.size() / 2, depths.size() / 2 + 3}) fs::resize_file(depths[k], 20);  // cut short
  const fs::path map = tmp / "m.cmap";
  const test::CommandResult alone = runCommand(cli() + " build " + map.string() + sessions);
  ASSERT_NE(alone.exit_code, 0);
  ASSERT_FALSE(fs::exists(map));
  const std::string message = alone.err.substr(alone.err.find("error"), alone.err.find('\n', alone.err.find("error")) - alone.err.find("error"));
  EXPECT_NE(message.find(depths[depths.size() / 2].filename().string()), std::string::npos) << message;
  for (int n : {2, 3}) {
    const test::CommandResult r = runCommand(mpirun(n) + cli() + " build " + map.string() + sessions);
    EXPECT_EQ(r.exit_code, alone.exit_code) << n << " ranks: " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << "alone: " << alone.err << "\nranks: " << r.err;
    EXPECT_FALSE(fs::exists(map));
  }
}

TEST(MpiBuild, KilledRankLeavesThePreviousMap) {
  test::TempDir tmp;
  const std::string sessions = simulate(tmp, 4, 0.3);
  const fs::path map = tmp / "m.cmap";
  const std::string first = " " + (tmp / "sim" / "session_00").string();
  ASSERT_EQ(runCommand(cli() + " build " + map.string() + first).exit_code, 0);
  const std::vector<uint8_t> before = test::bytesOf(map);
  // Rank 1 is killed once rank 0 has begun integrating (every rank is past its checks then, and
  // integrating its share): mpirun ends the job and the map is the one before, not a part.
  const std::string log = (tmp / "log").string();
  const std::string build = mpirun(2) + cli() + " build " + map.string() + " --replace" + sessions;
  const std::string script = "( " + build + " 2>" + log + " & m=$!; for k in $(seq 1000); do grep -q '^\\[1/' " + log +
                             " 2>/dev/null && break; sleep 0.01; done; "
                             "for c in $(pgrep -P $m) $(for p in $(pgrep -P $m); do pgrep -P $p; done); do "
                             "  tr '\\0' '\\n' < /proc/$c/environ 2>/dev/null | grep -qx OMPI_COMM_WORLD_RANK=1 && "
                             "kill -9 $c && echo killed; "
                             "done; wait $m; echo rc=$? )";
  const test::CommandResult r = runCommand(script);
  EXPECT_NE(r.out.find("killed"), std::string::npos) << r.out << r.err;
  EXPECT_EQ(r.out.find("rc=0"), std::string::npos) << "the build ended before the kill: " << r.out;
  EXPECT_TRUE(test::bytesOf(map) == before);
}

}  // namespace
}  // namespace chronomap
