#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <string>

#include "chronomap/core/error.h"
#include "chronomap/io/export.h"
#include "chronomap/io/file.h"
#include "test_support.h"

namespace chronomap::io {
namespace {

namespace fs = std::filesystem;

std::string messageOf(const fs::path& path) {
  try {
    readFileBytes(path);
  } catch (const IoError& e) {
    return e.what();
  }
  return "(read without an error)";
}

TEST(ReadFile, OnlyRegularFilesAreRead) {
  test::TempDir tmp;
  // A FIFO nobody writes to would block the reader for ever: refused at once.
  ASSERT_EQ(::mkfifo((tmp / "pipe.pcd").c_str(), 0600), 0);
  EXPECT_NE(messageOf(tmp / "pipe.pcd").find("not a regular file"), std::string::npos);
  // A device that never ends.
  EXPECT_NE(messageOf("/dev/zero").find("not a regular file"), std::string::npos);
  // A link loop, named as such.
  fs::create_symlink(tmp / "b.ply", tmp / "a.ply");
  fs::create_symlink(tmp / "a.ply", tmp / "b.ply");
  const std::string loop = messageOf(tmp / "a.ply");
  EXPECT_NE(loop.find("a.ply"), std::string::npos) << loop;
  EXPECT_NE(loop.find("symbolic links"), std::string::npos) << loop;
  // A folder, and a file that is missing.
  EXPECT_NE(messageOf(tmp.path()).find("is a folder"), std::string::npos);
  EXPECT_NE(messageOf(tmp / "missing.ply").find("cannot open"), std::string::npos);
  // A regular file through a link is read.
  test::writeBytes(tmp / "real.txt", std::string("abc"));
  fs::create_symlink(tmp / "real.txt", tmp / "link.txt");
  EXPECT_EQ(readTextFile(tmp / "link.txt"), "abc");
}

TEST(ExportOctomap, FullDiskLeavesTheOldFileIntact) {
  test::TempDir tmp;
  const SessionMap map = test::randomSessionMap(5, 32, 0.3);
  exportOctomap(tmp / "m.ot", test::wallSession(10));
  const auto before = test::bytesOf(tmp / "m.ot");
  ASSERT_FALSE(before.empty());
  // A 4 KiB file-size limit in a child process stands in for a full disk.
  const int code = test::exitCodeUnderFileSizeLimit(4096, [&] {
    try {
      exportOctomap(tmp / "m.ot", map);
    } catch (const IoError&) {
      return 42;
    }
    return 0;
  });
  EXPECT_EQ(code, 42) << "the export should fail with an IoError";
  EXPECT_EQ(test::bytesOf(tmp / "m.ot"), before);
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(tmp.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);  // no temporary file left
}

}  // namespace
}  // namespace chronomap::io
