// Trust on the command line: no session lost to a race between commands that create one map,
// no input destroyed by an output that names it.

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <map>
#include <sstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "chronomap/store/cmap.h"
#include "chronomap/store/temporal_file.h"
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
    writeSessionMap(tmp / cat("s", i, ".cmap"), test::randomSessionMap(60 + i, 16, 0.3), {});
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
    const TemporalMap m = readTemporalMap(map);
    EXPECT_EQ(m.sessionCount(), static_cast<size_t>(kWriters + attempt % 2)) << "attempt " << attempt;
  }
}

struct Case {
  std::string command;  // {A}, {B}, {M}, {D}, {DIR} stand for the files below
  std::string input;    // the input the output names
};

TEST(TrustCli, AnOutputThatIsAnInputIsRefusedBeforeWork) {
  test::TempDir tmp;
  writeSessionMap(tmp / "a.cmap", test::randomSessionMap(1, 16, 0.3), {});
  writeSessionMap(tmp / "b.cmap", test::randomSessionMap(2, 16, 0.3), {});
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

// Every output of a command is checked before work, not only the main one: a secondary output
// that names an input or another output, and a FIFO or a folder where a file goes, are refused
// and left as they were.
TEST(TrustCli, EveryOutputOfACommandIsCheckedBeforeWork) {
  test::TempDir tmp;
  writeSessionMap(tmp / "a.cmap", test::randomSessionMap(1, 16, 0.3), {});
  writeSessionMap(tmp / "b.cmap", test::randomSessionMap(2, 16, 0.3), {});
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string(), m = (tmp / "m.cmap").string();
  ASSERT_EQ(test::runCommand(cat(cli(), " add ", m, " ", a, " --time 1000 && ", cli(), " add ", m, " ", b, " --time 2000"))
                .exit_code,
            0);
  const fs::path fifo = tmp / "pipe.cmap", folder = tmp / "folder.cmap", file = tmp / "file";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  fs::create_directories(folder);
  test::writeBytes(file, std::string("a file where a folder goes\n"));
  const std::string x = (tmp / "x.cmap").string(), c = (tmp / "c.yaml").string(), y = (tmp / "y.ply").string();
  fs::create_symlink(x, y);
  struct OutputCase {
    std::string command, says;
    fs::path kept;  // what must be left as it was
  };
  const std::vector<OutputCase> cases = {
      {cat("costmap ", m, " --at 2000 -o ", c, " --save-rhythm ", m), "--save-rhythm", m},
      {cat("predict ", m, " --at 2000 -o ", x, " --save-rhythm ", x), "same file", x},
      {cat("predict ", m, " --at 2000 -o ", x, " --save-rhythm ", (tmp / "r.rhythm").string(), " --save-colour ", x),
       "same file", x},
      {cat("costmap ", m, " --at 2000 -o ", c, " --save-rhythm ", c), "same file", c},
      {cat("diff ", a, " ", b, " -o ", x, " --ply ", y), "same file", x},  // y.ply links to x.cmap
      {cat("snapshot ", m, " --at 2000 -o ", fifo.string()), "FIFO", fifo},
      {cat("diff ", a, " ", b, " -o ", fifo.string()), "FIFO", fifo},
      {cat("snapshot ", m, " --at 2000 -o ", folder.string()), "a folder", folder},
      {cat("alerts ", m, " --at 2000 -o ", file.string()), "not a folder", file},
  };
  for (const OutputCase& k : cases) {
    const bool existed = fs::exists(k.kept);
    const auto before = existed && fs::is_regular_file(k.kept) ? bytesOf(k.kept) : std::vector<uint8_t>{};
    const auto type = fs::symlink_status(k.kept).type();
    const auto r = test::runCommand(cat(cli(), " ", k.command));
    EXPECT_EQ(r.exit_code, 2) << k.command << "\n" << r.err;
    EXPECT_NE(r.err.find(k.says), std::string::npos) << k.command << "\n" << r.err;
    EXPECT_EQ(fs::symlink_status(k.kept).type(), type) << k.command;
    if (existed && fs::is_regular_file(k.kept)) {
      EXPECT_EQ(bytesOf(k.kept), before) << k.command;
    }
    if (!existed) {
      EXPECT_FALSE(fs::exists(k.kept)) << k.command << ": written although refused";
    }
  }
}

TEST(TrustCli, ARepeatedFlagIsSaidPlainly) {
  const auto r = test::runCommand(cat(cli(), " snapshot m.cmap --at 1 --at 2 -o x.cmap"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--at was given 2 times; give it once"), std::string::npos) << r.err;
}

TEST(TrustCli, SegmentReplacesAnEarlierSegmentationWhole) {
  test::TempDir tmp;
  writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
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
  writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
  const fs::path dataset = test::writeWallDataset(tmp.path(), "wall", 2.0f);
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string(), m = (tmp / "m.cmap").string();
  const std::string d = (tmp / "ab.cmap").string();
  ASSERT_EQ(test::runCommand(cat(cli(), " diff ", a, " ", b, " -o ", d)).exit_code, 0);
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
      // Limits of the key space and of the machine: refused with the limit, not wrapped.
      {cat("integrate ", dataset.string(), " --resolution 1e300 -o ", (tmp / "s.cmap").string()), "--resolution",
       tmp / "s.cmap"},
      {cat("integrate ", dataset.string(), " --resolution 1e-9 -o ", (tmp / "s.cmap").string()), "--resolution",
       tmp / "s.cmap"},
      {cat("integrate ", dataset.string(), " --threads 100000 -o ", (tmp / "s.cmap").string()), "--threads",
       tmp / "s.cmap"},
      {cat("integrate ", dataset.string(), " --pose 0,0,nan,0,0,0,1 -o ", (tmp / "s.cmap").string()), "--pose",
       tmp / "s.cmap"},
      // A value the mode does not use is refused, not ignored (raw: hard mode, which has no alpha).
      {cat("diff ", a, " ", b, " --preset raw --alpha 0.3 -o ", (tmp / "d.cmap").string()), "threshold and band modes only",
       tmp / "d.cmap"},
      // Negative counts used to wrap to huge ones (no component kept); a negative tolerance meant "no colour".
      {cat("segment ", d, " --min-voxels -1 -o ", (tmp / "objects").string()), "--min-voxels", tmp / "objects"},
      {cat("segment ", d, " --color-tolerance -1 -o ", (tmp / "objects").string()), "--color-tolerance",
       tmp / "objects"},
      {cat("simulate --preset tiny --sessions 1 --resolution-scale 0.1 --noise inf -o ", (tmp / "sim").string()),
       "--noise", tmp / "sim"},
      {cat("simulate --preset tiny --sessions 1 --resolution-scale 0.1 --seed -1 -o ", (tmp / "sim").string()),
       "--seed", tmp / "sim"},
      {cat("simulate --preset tiny --sessions 1 --resolution-scale 0.1 --threads -1 -o ", (tmp / "sim").string()),
       "--threads", tmp / "sim"},
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

TEST(TrustCli, OutputsThroughALinkUpdateItsTarget) {
  test::TempDir tmp;
  fs::create_directories(tmp / "real");
  writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string();
  const fs::path dataset = test::writeWallDataset(tmp.path(), "wall", 2.0f);
  // One link per output kind; the map links point at files that exist, the others dangle
  // (a first write through a link creates the target).
  writeSessionMap(tmp / "real" / "map.cmap", test::wallSession(11), {});
  ASSERT_EQ(test::runCommand(cat(cli(), " add ", (tmp / "real" / "4d.cmap").string(), " ", a, " --time 1000"))
                .exit_code,
            0);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"session.cmap", cat("integrate ", dataset.string(), " -o ")},
      {"map.cmap", cat("integrate ", dataset.string(), " -o ")},
      {"diff.cmap", cat("diff ", a, " ", b, " -o ")},
      {"cloud.ply", cat("export ", a, " -o ")},
      {"tree.ot", cat("export ", a, " -o ")},
      {"top.png", cat("export ", a, " -o ")},
      {"new4d.cmap", cat("build --times 1000 ")},  // the map is the first argument: built below
      {"4d.cmap", cat("add ")},
  };
  for (const auto& [name, command] : cases) {
    const fs::path link = tmp / name, target = tmp / "real" / name;
    fs::create_symlink(fs::path("real") / name, link);
    std::string args = cat(command, link.string());
    if (name == "new4d.cmap") args = cat("build ", link.string(), " ", dataset.string(), " --times 1000");
    if (name == "4d.cmap") args = cat("add ", link.string(), " ", b, " --time 2000 --write rewrite");
    const auto r = test::runCommand(cat(cli(), " ", args));
    ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.err;
    EXPECT_TRUE(fs::is_symlink(fs::symlink_status(link))) << name << ": the link was replaced by a file";
    ASSERT_TRUE(fs::is_regular_file(target)) << name;
    EXPECT_GT(fs::file_size(target), 0u) << name;
  }
  // Through the link, the 4D map gained the session: the target holds both.
  EXPECT_EQ(readTemporalMap(tmp / "real" / "4d.cmap").sessionCount(), 2u);
}

/// Every file under `dir` with its size, by path relative to `dir`.
std::map<std::string, uintmax_t> treeOf(const fs::path& dir) {
  std::map<std::string, uintmax_t> tree;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    tree[fs::relative(e.path(), dir).string()] = e.is_regular_file() ? e.file_size() : 0;
  }
  return tree;
}

bool anyStagingLeftIn(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename().string().find(".tmp-") != std::string::npos) return true;
  }
  return false;
}

TEST(TrustCli, SimulateOnAFullDiskLeavesNoPartialTree) {
  test::TempDir tmp;
  const fs::path sim = tmp / "sim";
  auto simulate = [&](int seed) {
    return cat(cli(), " simulate --preset tiny --sessions 2 --resolution-scale 0.1 --seed ", seed, " -o ", sim.string());
  };
  // A full disk (a 16 KiB file-size limit) part-way: no folder at all, nothing left beside it.
  const int code = test::exitCodeUnderFileSizeLimit(16 << 10, [&] { return test::runCommand(simulate(1)).exit_code; });
  EXPECT_EQ(code, 1);
  EXPECT_FALSE(fs::exists(sim)) << "a failed simulation left a partial tree";
  EXPECT_FALSE(anyStagingLeftIn(tmp.path()));
  // Over an earlier simulation: the earlier tree stays exactly as it was.
  ASSERT_EQ(test::runCommand(simulate(1)).exit_code, 0);
  test::writeBytes(sim / "notes.txt", std::string("mine"));
  const auto before = treeOf(sim);
  const auto scene = bytesOf(sim / "scene.json");
  EXPECT_EQ(test::exitCodeUnderFileSizeLimit(16 << 10, [&] { return test::runCommand(simulate(2)).exit_code; }), 1);
  EXPECT_EQ(treeOf(sim), before);
  EXPECT_EQ(bytesOf(sim / "scene.json"), scene);
  EXPECT_FALSE(anyStagingLeftIn(tmp.path()));
  // A successful run replaces what it writes and leaves other files alone.
  ASSERT_EQ(test::runCommand(simulate(2)).exit_code, 0);
  EXPECT_NE(bytesOf(sim / "scene.json"), scene);
  EXPECT_EQ(bytesOf(sim / "notes.txt").size(), 4u);
  EXPECT_FALSE(anyStagingLeftIn(tmp.path()));
}

TEST(TrustCli, SegmentOnAFullDiskLeavesTheEarlierSegmentation) {
  test::TempDir tmp;
  for (int i = 0; i < 3; ++i) {
    writeSessionMap(tmp / cat("r", i, ".cmap"), test::randomSessionMap(70 + i, 6, 0.3), {});
  }
  auto diff = [&](int a, int b, const std::string& out) {
    return test::runCommand(cat(cli(), " diff ", (tmp / cat("r", a, ".cmap")).string(), " ",
                                (tmp / cat("r", b, ".cmap")).string(), " -o ", (tmp / out).string()))
        .exit_code;
  };
  ASSERT_EQ(diff(0, 1, "d1.cmap"), 0);
  ASSERT_EQ(diff(0, 2, "d2.cmap"), 0);
  const fs::path objects = tmp / "objects";
  auto segment = [&](const char* d, const fs::path& out) {
    return cat(cli(), " segment ", (tmp / d).string(), " -o ", out.string());
  };
  ASSERT_EQ(test::runCommand(segment("d1.cmap", objects)).exit_code, 0);
  const auto before = treeOf(objects);
  // The second segmentation, written unlimited elsewhere, gives a limit that every component
  // file passes and the index (written last, the largest) does not: the disk fills at the end.
  ASSERT_EQ(test::runCommand(segment("d2.cmap", tmp / "scratch")).exit_code, 0);
  // The limit sits just above the largest component file, far below the index (which also
  // holds timings, so its exact size varies from run to run).
  auto files = treeOf(tmp / "scratch");
  const uintmax_t index = files.at("components.json");
  files.erase("components.json");
  ASSERT_GT(files.size(), 4u);
  uintmax_t largest = 0;
  for (const auto& [name, size] : files) largest = std::max(largest, size);
  const uintmax_t limit = largest + 1;
  ASSERT_GT(index, 2 * limit);
  const int code = test::exitCodeUnderFileSizeLimit(limit, [&] { return test::runCommand(segment("d2.cmap", objects)).exit_code; });
  EXPECT_EQ(code, 1);
  EXPECT_EQ(treeOf(objects), before) << "a failed segmentation changed the earlier one";
  EXPECT_FALSE(anyStagingLeftIn(tmp.path()));
}

TEST(TrustCli, EveryFailureIsOneLineNamingTheFile) {
  test::TempDir tmp;
  writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  const std::string a = (tmp / "a.cmap").string();
  const std::string nowhere = (tmp / "no" / "such" / "folder").string();
  const std::string missing_folder = cat("'", nowhere, "' does not exist");
  const std::vector<uint8_t> whole = bytesOf(tmp / "a.cmap");
  test::writeBytes(tmp / "cut.cmap", std::vector<uint8_t>(whole.begin(), whole.begin() + 40));
  const std::vector<std::pair<std::string, std::string>> cases = {
      {cat("export ", a, " -o ", nowhere, "/x.ot"), missing_folder},
      {cat("export ", a, " -o ", nowhere, "/x.png"), missing_folder},
      {cat("export ", a, " -o ", nowhere, "/x.ply"), missing_folder},
      {cat("diff ", a, " ", a, " --mode threshold -o ", nowhere, "/d.cmap"), missing_folder},
      {cat("stats ", (tmp / "missing.cmap").string()), "missing.cmap"},
      {cat("stats ", tmp.path().string()), tmp.path().string()},
      {cat("stats ", (tmp / "cut.cmap").string()), "cut.cmap"},
      {cat("integrate ", (tmp / "cut.cmap").string(), " -o ", (tmp / "s.cmap").string()), "cut.cmap"},
      {"stats /dev/zero", "/dev/zero"},
  };
  for (const auto& [args, name] : cases) {
    const auto r = test::runCommand(cat(cli(), " ", args));
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_EQ(r.err.rfind("chronomap: error: ", 0), 0u) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "one line: " << args << "\n" << r.err;
    EXPECT_NE(r.err.find(name), std::string::npos) << args << "\n" << r.err;
    for (const char* foreign : {"internal error", "filesystem error", "libpng", "std::", "basic_string"}) {
      EXPECT_EQ(r.err.find(foreign), std::string::npos) << args << "\n" << r.err;
    }
  }
}

TEST(TrustCli, EveryNumericFlagRefusesWhatIsNotAFiniteNumber) {
  // The flags come from each command's --help, so that a flag added later is swept too.
  test::TempDir tmp;
  writeSessionMap(tmp / "a.cmap", test::wallSession(10), {});
  writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
  const std::string a = (tmp / "a.cmap").string(), b = (tmp / "b.cmap").string();
  const std::string d = (tmp / "d.cmap").string(), m = (tmp / "m.cmap").string();
  const std::string dataset = test::writeWallDataset(tmp.path(), "wall", 2.0f).string();
  ASSERT_EQ(test::runCommand(cat(cli(), " diff ", a, " ", b, " -o ", d)).exit_code, 0);
  ASSERT_EQ(test::runCommand(cat(cli(), " add ", m, " ", a, " --time 1000")).exit_code, 0);
  const std::string out = (tmp / "out").string();
  // Each command with arguments that run it, flag by flag (a flag under test replaces its own).
  const std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::string>>>> commands = {
      {cat("integrate ", dataset), {{"-o", out + ".cmap"}}},
      {cat("export ", a), {{"-o", out + ".png"}}},
      {cat("add ", out, "4d.cmap ", a), {{"--time", "5000"}, {"--realign", ""}}},
      {cat("build ", out, "b4d.cmap ", dataset), {{"--times", "1000"}, {"--realign", ""}, {"--register", ""}}},
      {cat("changes ", m), {}},
      {cat("diff ", a, " ", b), {{"--mode", "band"}, {"-o", out + ".cmap"}}},
      {cat("segment ", d), {{"-o", out}}},
      {"simulate", {{"--preset", "tiny"}, {"--sessions", "1"}, {"--resolution-scale", "0.1"}, {"-o", out}}},
      {"demo", {{"--resolution-scale", "0.1"}, {"-o", out}}},
  };
  size_t swept = 0;
  for (const auto& [command, base] : commands) {
    const std::string name = command.substr(0, command.find(' '));
    const std::string help = test::runCommand(cat(cli(), " ", name, " --help")).out;
    std::istringstream lines(help);
    std::string line;
    while (std::getline(lines, line)) {
      const size_t dash = line.find("--");
      if (dash == std::string::npos) continue;
      const std::string rest = line.substr(dash);
      const size_t space = rest.find(' ');
      if (space == std::string::npos) continue;
      const std::string flag = rest.substr(0, space), type = rest.substr(space + 1, 4);
      if (type != "FLOA" && type != "INT " && type != "INT:" && type != "INT=" && type != "UINT") continue;
      for (const char* value : {"nan", "inf", "-inf", "1e400"}) {
        std::string args = cat(command, " ", flag, " ", value);
        for (const auto& [f, v] : base) {
          if (f != flag) args = cat(args, " ", f, v.empty() ? "" : " ", v);
        }
        const auto r = test::runCommand(cat("timeout 120 ", cli(), " ", args));
        EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
        EXPECT_FALSE(fs::exists(out)) << args;
        EXPECT_FALSE(fs::exists(out + ".cmap")) << args;
      }
      ++swept;
    }
  }
  EXPECT_GE(swept, 30u) << "the --help parsing found too few numeric flags";
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
  // A tiny limit is a limit (1e-12 GiB rounded to 0 bytes, which meant none), and without
  // --memory-limit the default follows the address-space limit: both stop at the limit, where
  // before they ran until "out of memory".
  for (const std::string& flags : {std::string(" --memory-limit 1e-12"), std::string(limit.empty() ? " --memory-limit 0.25" : "")}) {
    const auto r = test::runCommand(cat(limit, cli(), " integrate ", dataset.string(), " --resolution 0.0005", flags,
                                        " -o ", out.string()));
    EXPECT_EQ(r.exit_code, 2) << flags << "\n" << r.err;
    EXPECT_NE(r.err.find("use a coarser --resolution or raise --memory-limit"), std::string::npos) << flags << r.err;
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
  writeSessionMap(tmp / "b.cmap", test::wallSession(12), {});
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
