#include <bzlib.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/export/export.h"
#include "chronomap/core/file.h"
#include "test_support.h"

namespace chronomap {
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

/// Bits of a byte string, most significant first (bzip2's order).
uint64_t bitsAt(const std::vector<uint8_t>& bytes, size_t bit, int count) {
  uint64_t v = 0;
  for (int i = 0; i < count; ++i, ++bit) v = (v << 1) | ((bytes[bit / 8] >> (7 - bit % 8)) & 1u);
  return v;
}

struct BitWriter {
  std::vector<uint8_t> bytes;
  size_t bits = 0;
  void put(uint64_t v, int count) {
    for (int i = count - 1; i >= 0; --i, ++bits) {
      if (bits % 8 == 0) bytes.push_back(0);
      bytes.back() |= static_cast<uint8_t>(((v >> i) & 1u) << (7 - bits % 8));
    }
  }
};

constexpr uint64_t kBzip2EndMagic = 0x177245385090;

/// A valid bzip2 stream of `blocks` copies of one block of 40,000,000 zeros, about 40 bytes per
/// block: a decompression bomb made in a fraction of a second. The block is compressed once and
/// its bits repeated (blocks need not start on a byte), then the stream's combined CRC is
/// computed as bzip2 does: rotate left by one, xor the block's CRC.
std::vector<uint8_t> bzip2OfZeros(int blocks) {
  std::vector<char> zeros(40'000'000, 0);
  std::vector<char> one(4096);
  unsigned len = static_cast<unsigned>(one.size());
  EXPECT_EQ(BZ2_bzBuffToBuffCompress(one.data(), &len, zeros.data(), static_cast<unsigned>(zeros.size()), 9, 0, 0),
            BZ_OK);
  const std::vector<uint8_t> stream(one.begin(), one.begin() + len);
  // "BZh9", then the block from bit 32 (its magic, its CRC at bit 80), then the end magic and
  // the combined CRC, padded to a byte.
  const uint64_t block_crc = bitsAt(stream, 80, 32);
  size_t end = 0;
  for (size_t pad = 0; pad < 8 && end == 0; ++pad) {
    const size_t at = stream.size() * 8 - pad - 80;
    if (bitsAt(stream, at, 48) == kBzip2EndMagic && bitsAt(stream, at + 48, 32) == block_crc) end = at;
  }
  EXPECT_GT(end, 32u) << "not a one-block bzip2 stream";
  BitWriter out;
  for (char c : std::string("BZh9")) out.put(static_cast<uint8_t>(c), 8);
  uint32_t combined = 0;
  for (int b = 0; b < blocks; ++b) {
    for (size_t bit = 32; bit < end; ++bit) out.put(bitsAt(stream, bit, 1), 1);
    combined = ((combined << 1) | (combined >> 31)) ^ static_cast<uint32_t>(block_crc);
  }
  out.put(kBzip2EndMagic, 48);
  out.put(combined, 32);
  return out.bytes;
}

// The writers replace regular files only: a FIFO, a device or a folder is left as it was, and the
// append of a 4D map does not wait for a FIFO's reader. The check in front of the command
// (checkOutputs) says the same before any work.
TEST(WriteFile, OnlyRegularFilesAreReplaced) {
  test::TempDir tmp;
  const fs::path fifo = tmp / "pipe", folder = tmp / "folder";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  fs::create_directories(folder);
  const std::vector<uint8_t> bytes = {1, 2, 3};
  for (const fs::path& p : {fifo, folder}) {
    EXPECT_THROW(writeFileAtomic(p, bytes), IoError) << p;
    EXPECT_THROW(appendToFile(p, 0, bytes), IoError) << p;
    EXPECT_THROW(checkOutputs({{p, "-o"}}, {}), UsageError) << p;
  }
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_directory(folder));
  // Through a link, what it points to counts.
  fs::create_symlink(fifo, tmp / "link");
  EXPECT_THROW(writeFileAtomic(tmp / "link", bytes), IoError);
  EXPECT_TRUE(fs::is_fifo(fifo));
  // A folder output is refused where a file is, and accepted where a folder or nothing is.
  writeFileAtomic(tmp / "file", bytes);
  EXPECT_THROW(checkOutputs({{tmp / "file", "-o", true}}, {}), UsageError);
  EXPECT_NO_THROW(checkOutputs({{folder, "-o", true}, {tmp / "new", "--other", true}}, {}));
}

// What killed writers of a file left beside it (".NAME.tmp-PID-RANDOM", files or staging
// folders, PID a process that no longer exists) is removed when the file is written; what live
// processes are writing, other files' temporaries and names of other forms stay. The folder is
// listed once a minute at most (a tiled map's folder holds thousands of files): what the listing
// found goes when its own file is written, and what turns up after it waits for the next listing.
TEST(WriteFile, AKilledWritersTemporariesGoWhenItsFileIsWritten) {
  test::TempDir tmp;
  const std::string dead = "4194304";  // no Linux pid (they stay below PID_MAX_LIMIT, 2^22)
  const std::string self = std::to_string(::getpid()), parent = std::to_string(::getppid());
  const std::vector<std::string> stale = {".c.cmap.tmp-" + dead + "-77", ".c.cmap.tmp-" + dead + "-4"};
  const std::vector<std::string> kept = {".c.cmap.tmp-" + self + "-78", ".c.cmap.tmp-" + parent + "-79",
                                         "c.cmap.tmp-" + dead + "-2",   ".c.cmap.tmp-" + dead,
                                         ".c.cmap.tmp--3",              ".c.cmap.tmp-x1-3",
                                         ".c.cmap.tmp-" + dead + "-5a", ".c.cmap.tmp-94194304-5",
                                         "notes.txt"};
  const std::string other = ".b.png.tmp-" + dead + "-1", nested = ".x.tmp-9.cmap.tmp-" + dead + "-5";
  test::writeBytes(tmp / stale[0], std::string("part"));
  fs::create_directories(tmp / stale[1] / "inside");  // a staging folder
  for (const std::string& name : kept) test::writeBytes(tmp / name, std::string("keep"));
  test::writeBytes(tmp / other, std::string("part"));
  test::writeBytes(tmp / nested, std::string("part"));
  writeFileAtomic(tmp / "c.cmap", {1, 2, 3});
  for (const std::string& name : stale) EXPECT_FALSE(fs::exists(tmp / name)) << name;
  for (const std::string& name : kept) EXPECT_TRUE(fs::exists(tmp / name)) << name;
  EXPECT_TRUE(fs::exists(tmp / other));
  EXPECT_TRUE(fs::exists(tmp / nested));
  EXPECT_EQ(readFileBytes(tmp / "c.cmap"), (std::vector<uint8_t>{1, 2, 3}));
  // The other files' temporaries go with their files, from the same listing.
  writeFileAtomic(tmp / "b.png", {4});
  EXPECT_FALSE(fs::exists(tmp / other));
  writeFileAtomic(tmp / "x.tmp-9.cmap", {5});
  EXPECT_FALSE(fs::exists(tmp / nested));
  // One that turns up after the listing waits for the next one.
  test::writeBytes(tmp / (".d.cmap.tmp-" + dead + "-6"), std::string("part"));
  writeFileAtomic(tmp / "d.cmap", {6});
  EXPECT_TRUE(fs::exists(tmp / (".d.cmap.tmp-" + dead + "-6")));
  for (const std::string& name : kept) EXPECT_TRUE(fs::exists(tmp / name)) << name;
  // A staged folder's destination: a dead writer's staging folder goes when a new one starts.
  fs::create_directories(tmp / "sub" / (".out.tmp-" + dead + "-8") / "inside");
  {
    const StagedFolder staged(tmp / "sub" / "out");
    EXPECT_FALSE(fs::exists(tmp / "sub" / (".out.tmp-" + dead + "-8")));
  }
}

TEST(WriteFile, OutputsOfOneCommandMayNotNameEachOtherOrAnInput) {
  test::TempDir tmp;
  writeFileAtomic(tmp / "in", {1});
  fs::create_symlink(tmp / "out.cmap", tmp / "alias.ply");  // to a file that does not exist yet
  auto message = [](const std::vector<PlannedOutput>& outputs, const std::vector<fs::path>& inputs) -> std::string {
    try {
      checkOutputs(outputs, inputs);
    } catch (const UsageError& e) {
      return e.what();
    }
    return "(accepted)";
  };
  EXPECT_NE(message({{tmp / "a", "-o"}, {tmp / "b", "--ply"}, {tmp / "in", "--save-rhythm"}}, {tmp / "in"})
                .find("--save-rhythm"),
            std::string::npos);
  EXPECT_NE(message({{tmp / "out.cmap", "-o"}, {tmp / "alias.ply", "--ply"}}, {}).find("same file as -o"),
            std::string::npos);
  EXPECT_NE(message({{tmp / "x", "-o"}, {tmp / "sub" / ".." / "x", "--save-colour"}}, {}).find("same file"),
            std::string::npos);
  EXPECT_EQ(message({{tmp / "x", "-o"}, {"", "--save-rhythm"}, {tmp / "y", "--ply"}}, {tmp / "in"}), "(accepted)");
}

TEST(ReadFile, RefusesBzip2BombsAndReadsRealFiles) {
  test::TempDir tmp;
  // 4 GB of zeros in about 4 KB: refused once the output passes the bound (64 MiB for a file
  // this small), in a child that may map 1 GiB more (before, it grew without end: bad_alloc).
  test::writeBytes(tmp / "bomb.xyz.bz2", bzip2OfZeros(100));
  const int code = test::exitCodeUnderMemoryLimit(uint64_t{1} << 30, [&] {
    try {
      readFileBytes(tmp / "bomb.xyz.bz2");
      return 1;
    } catch (const FormatError& e) {
      const std::string m = e.what();
      const bool named = m.find("bomb.xyz.bz2: expands beyond 64") != std::string::npos;
      return named && m.find("refusing") != std::string::npos ? 0 : 2;
    }
  });
  EXPECT_EQ(code, 0) << "0: refused naming the file, 1: read, 2: another message, 99: out of memory";
  // Small files may always expand up to the bound: 40 MB of zeros in 40 bytes is read.
  test::writeBytes(tmp / "zeros.bin.bz2", bzip2OfZeros(1));
  const std::vector<uint8_t> zeros = readFileBytes(tmp / "zeros.bin.bz2");
  EXPECT_EQ(zeros.size(), 40'000'000u);
  EXPECT_EQ(std::count(zeros.begin(), zeros.end(), 0), 40'000'000);
  // A real compressed scan.
  CHRONOMAP_REQUIRE_DATA(scan, "octomap-data/scan.dat.bz2");
  EXPECT_EQ(readFileBytes(scan).size(), 2'343'059u);
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
}  // namespace chronomap
