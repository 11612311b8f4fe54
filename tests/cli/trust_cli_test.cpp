// Trust on the command line: no session lost to a race between commands that create one map,
// no input destroyed by an output that names it.

#include <gtest/gtest.h>

#include <sstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "chronomap/io/cmap.h"
#include "chronomap/io/temporal_file.h"
#include "test_support.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

using test::bytesOf;
using test::cli;

// The parts written one after the other (a chain of string + trips GCC 12's -Wrestrict).
template <class... Parts>
std::string cat(const Parts&... parts) {
  std::ostringstream s;
  (s << ... << parts);
  return s.str();
}

TEST(TrustCli, CommandsCreatingOneMapAtOnceKeepEverySession) {
  test::TempDir tmp;
  constexpr int kWriters = 4;
  for (int i = 0; i < kWriters; ++i) {
    io::writeSessionMap(tmp / cat("s", i, ".cmap"), test::randomSessionMap(60 + i, 16, 0.3), {});
  }
  const fs::path dataset = test::writeWallDataset(tmp.path(), "wall", 2.0f);
  for (int attempt = 0; attempt < 6; ++attempt) {
    const fs::path map = tmp / cat("map", attempt, ".cmap");
    // Every writer starts while the map does not exist yet; odd attempts mix in a build.
    std::ostringstream script;
    for (int i = 0; i < kWriters; ++i) {
      script << cli() << " add " << map.string() << " " << (tmp / cat("s", i, ".cmap")).string() << " --time "
             << 1000 + i << " >/dev/null 2>&1 & ";
    }
    if (attempt % 2) script << cli() << " build " << map.string() << " " << dataset.string() << " --times 5000 >/dev/null 2>&1 & ";
    script << "wait";
    ASSERT_EQ(test::runCommand(script.str()).exit_code, 0);
    const TemporalMap m = io::readTemporalMap(map);
    EXPECT_EQ(m.sessionCount(), static_cast<size_t>(kWriters + attempt % 2)) << "attempt " << attempt;
  }
}

struct Case {
  std::string command;  // {A}, {B}, {M}, {D}, {DIR} stand for the files below
  std::string input;    // the input the output names
};

TEST(TrustCli, AnOutputThatIsAnInputIsRefusedBeforeWork) {
  test::TempDir tmp;
  io::writeSessionMap(tmp / "a.cmap", test::randomSessionMap(1, 16, 0.3), {});
  io::writeSessionMap(tmp / "b.cmap", test::randomSessionMap(2, 16, 0.3), {});
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string(), m = (tmp / "m.cmap").string();
  ASSERT_EQ(test::runCommand(cat(cli(), " add ", m, " ", a, " --time 1000 && ", cli(), " add ", m, " ", b, " --time 2000"))
                .exit_code,
            0);
  // A segmentation's own folder as its input's folder: component 1 would replace the diff.
  fs::create_directories(tmp / "objects");
  const std::string d = (tmp / "objects" / "component_0001.cmap").string();
  ASSERT_EQ(test::runCommand(cat(cli(), " diff ", a, " ", b, " -o ", d)).exit_code, 0);
  fs::create_symlink(tmp / "a.cmap", tmp / "link.cmap");
  fs::create_symlink(tmp / "a.cmap", tmp / "alias.ply");
  const std::string link = (tmp / "link.cmap").string(), alias = (tmp / "alias.ply").string();
  const std::string out = (tmp / "out.cmap").string();
  const std::string b_again = (tmp / ".." / tmp.path().filename() / "b.cmap").string();
  const std::vector<Case> cases = {
      {cat("diff ", a, " ", b, " -o ", a), a},
      {cat("diff ", a, " ", b, " -o ", b), b},
      {cat("diff ", a, " ", b, " -o ", b_again), b},
      {cat("diff ", link, " ", b, " -o ", a), a},  // the input named through a link
      {cat("diff ", a, " ", b, " -o ", link), a},  // the output named through a link
      {cat("diff ", a, " ", b, " -o ", out, " --ply ", alias), a},  // the PLY over an input
      {cat("diff ", m, "@1000 ", m, "@2000 -o ", m), m},
      {cat("snapshot ", m, " --at 2000 -o ", m), m},
      {cat("add ", m, " ", m, " --time 3000"), m},
      {cat("segment ", d, " -o ", (tmp / "objects").string()), d},
  };
  for (const Case& c : cases) {
    const auto before = bytesOf(c.input);
    const auto r = test::runCommand(cat(cli(), " ", c.command));
    EXPECT_EQ(r.exit_code, 2) << c.command << "\n" << r.err;
    EXPECT_NE(r.err.find("input"), std::string::npos) << c.command << "\n" << r.err;
    EXPECT_EQ(bytesOf(c.input), before) << c.command;
  }
}

TEST(TrustCli, SegmentReplacesAnEarlierSegmentationWhole) {
  test::TempDir tmp;
  io::writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  io::writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
  const std::string d = (tmp / "d.cmap").string(), objects = (tmp / "objects").string();
  ASSERT_EQ(test::runCommand(cat(cli(), " diff ", (tmp / "a.cmap").string(), " ", (tmp / "b.cmap").string(), " -o ", d))
                .exit_code,
            0);
  fs::create_directories(tmp / "objects");
  test::writeBytes(tmp / "objects" / "component_0099.cmap", std::string("stale"));
  test::writeBytes(tmp / "objects" / "component_0099.ply", std::string("stale"));
  test::writeBytes(tmp / "objects" / "notes.txt", std::string("mine"));
  const auto r = test::runCommand(cat(cli(), " segment ", d, " -o ", objects, " --json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "objects" / "component_0099.cmap"));  // not in the new index
  EXPECT_FALSE(fs::exists(tmp / "objects" / "component_0099.ply"));
  EXPECT_TRUE(fs::exists(tmp / "objects" / "component_0001.cmap"));
  EXPECT_TRUE(fs::exists(tmp / "objects" / "components.json"));
  EXPECT_EQ(bytesOf(tmp / "objects" / "notes.txt").size(), 4u);  // other files are left alone
}

TEST(TrustCli, OutOfRangeValuesAreRefusedNotReplacedByDefaults) {
  test::TempDir tmp;
  io::writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  io::writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
  const fs::path dataset = test::writeWallDataset(tmp.path(), "wall", 2.0f);
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string(), m = (tmp / "m.cmap").string();
  struct Refused {
    std::string args;
    std::string message;
    fs::path not_written;
  };
  const std::vector<Refused> cases = {
      {cat("diff ", a, " ", b, " --mode band --alpha -0.5 -o ", (tmp / "d.cmap").string()), "--alpha", tmp / "d.cmap"},
      {cat("integrate ", dataset.string(), " --depth-scale 0 -o ", (tmp / "s.cmap").string()), "depth scale",
       tmp / "s.cmap"},
      {cat("add ", m, " ", a, " --time 1e300"), "years 1 to 9999", m},
      {cat("add ", m, " ", a, " --time -1e300"), "years 1 to 9999", m},
  };
  for (const Refused& c : cases) {
    const auto r = test::runCommand(cat(cli(), " ", c.args));
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(c.not_written)) << c.args;
  }
  // In range, the given value is used as given.
  const auto r = test::runCommand(cat(cli(), " diff ", a, " ", b, " --mode band --alpha 0.2 --json -o ",
                                      (tmp / "d.cmap").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["alpha"], 0.2);
}

TEST(TrustCli, AResolutionTooFineStopsAtTheMemoryLimit) {
  // A 1 x 1 m wall 2 m away at half a millimetre: its rays cross millions of voxels. Integration
  // stops at --memory-limit with the reason and the way out, nothing written (before, it took
  // memory until the system refused: "out of memory"). The shell's address-space limit (2 GiB,
  // not under sanitizers) makes a missed limit a failure, not a machine out of memory.
  test::TempDir tmp;
  const fs::path dataset = test::writeWallDataset(tmp.path(), "wall", 2.0f);
  const fs::path out = tmp / "s.cmap";
  const std::string limit = test::memoryLimitsApply() ? "ulimit -v 2097152; " : "";
  for (const char* threads : {"1", "2"}) {
    const auto r = test::runCommand(cat(limit, cli(), " integrate ", dataset.string(), " --resolution 0.0005",
                                        " --memory-limit 0.25 --threads ", threads, " -o ", out.string()));
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("at resolution 0.0005 m; use a coarser --resolution or raise --memory-limit"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(out));
  }
  const auto bad = test::runCommand(cat(cli(), " integrate ", dataset.string(), " --memory-limit -1 -o ", out.string()));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--memory-limit must be a number of GiB"), std::string::npos) << bad.err;
  // At a sensible resolution the same limit is plenty.
  const auto ok = test::runCommand(cat(limit, cli(), " integrate ", dataset.string(), " --memory-limit 0.25 -o ",
                                       out.string()));
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

TEST(TrustCli, SpecialFilesAreRefusedAtOnceNamingThem) {
  test::TempDir tmp;
  io::writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
  ASSERT_EQ(test::runCommand(cat("mkfifo ", (tmp / "pipe.ply").string())).exit_code, 0);
  fs::create_symlink(tmp / "loop2.cmap", tmp / "loop.cmap");
  fs::create_symlink(tmp / "loop.cmap", tmp / "loop2.cmap");
  const std::vector<std::pair<std::string, std::string>> cases = {
      // A FIFO as a cloud would block for ever: `timeout` turns a hang into exit 124.
      {cat("integrate ", (tmp / "pipe.ply").string(), " -o ", (tmp / "p.cmap").string()), "pipe.ply"},
      {cat("diff ", (tmp / "loop.cmap").string(), " ", (tmp / "b.cmap").string(), " -o ", (tmp / "d.cmap").string()),
       "loop.cmap"},
      {cat("stats ", (tmp / "loop.cmap").string()), "loop.cmap"},
      {cat("stats /dev/zero"), "/dev/zero"},
  };
  for (const auto& [args, name] : cases) {
    const auto r = test::runCommand(cat("timeout 60 ", cli(), " ", args));
    EXPECT_TRUE(r.exit_code == 1 || r.exit_code == 2) << args << " exited " << r.exit_code << "\n" << r.err;
    EXPECT_NE(r.err.find(name), std::string::npos) << args << "\n" << r.err;
    EXPECT_EQ(r.err.find("internal error"), std::string::npos) << args << "\n" << r.err;
  }
}

}  // namespace
}  // namespace chronomap
