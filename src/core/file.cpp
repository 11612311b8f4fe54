#include "chronomap/core/file.h"

#include <bzlib.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <string_view>

#include "chronomap/core/error.h"
#include "chronomap/core/format.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

/// The most a .bz2 input may expand. bzip2 packs real data a few times (binary and text point
/// clouds 1.3-3x, OctoMap's scan.dat.bz2 2.9x), but a file of one repeated byte more than a
/// million times (a 208-byte stream holds 256 MiB of zeros), so a small file could claim all
/// memory.
/// Up to kMinBzip2Output every file may expand (small files are never refused); past it, at most
/// kMaxBzip2Ratio times its compressed size (30 times what real point data reaches), and never
/// past kMaxBzip2Output. A genuine file beyond them can be decompressed with bunzip2 first.
constexpr uint64_t kMaxBzip2Ratio = 100;
constexpr uint64_t kMinBzip2Output = uint64_t{64} << 20;
constexpr uint64_t kMaxBzip2Output = uint64_t{8} << 30;

uint64_t bzip2OutputLimit(size_t compressed_bytes) {
  return std::min(kMaxBzip2Output, std::max(kMinBzip2Output, kMaxBzip2Ratio * compressed_bytes));
}

[[noreturn]] void refuseBzip2Bomb(const fs::path& path, size_t compressed_bytes, uint64_t limit) {
  std::string msg = path.string();
  msg.append(": expands beyond ").append(humanBytes(static_cast<double>(limit))).append(" from ");
  msg.append(humanBytes(static_cast<double>(compressed_bytes)))
      .append(" of bzip2 data (more than a ")
      .append(std::to_string(kMaxBzip2Ratio))
      .append(":1 ratio, as a decompression bomb does); refusing. Decompress it with bunzip2 if it is genuine");
  throw FormatError(msg);
}

/// A bzip2 decoder, ended when it goes out of scope (also when an allocation throws).
struct Bzip2Decoder {
  bz_stream stream{};
  explicit Bzip2Decoder(const fs::path& path) {
    if (BZ2_bzDecompressInit(&stream, 0, 0) != BZ_OK) throw IoError(path.string() + ": cannot start bzip2 decoder");
  }
  ~Bzip2Decoder() { BZ2_bzDecompressEnd(&stream); }
  Bzip2Decoder(const Bzip2Decoder&) = delete;
  Bzip2Decoder& operator=(const Bzip2Decoder&) = delete;
};

std::vector<uint8_t> bunzip(const std::vector<uint8_t>& in, const fs::path& path) {
  Bzip2Decoder decoder(path);
  bz_stream& stream = decoder.stream;
  stream.next_in = reinterpret_cast<char*>(const_cast<uint8_t*>(in.data()));
  stream.avail_in = static_cast<unsigned>(in.size());
  const uint64_t limit = bzip2OutputLimit(in.size());
  // One byte more than the limit: producing it shows the stream goes on past the limit.
  const size_t capacity = static_cast<size_t>(limit) + 1;
  std::vector<uint8_t> out(std::min(capacity, std::max<size_t>(in.size() * 4, 1 << 16)));
  size_t produced = 0;
  int rc = BZ_OK;
  while (rc == BZ_OK) {
    if (produced == out.size()) {
      if (out.size() == capacity) refuseBzip2Bomb(path, in.size(), limit);
      out.resize(std::min(capacity, out.size() * 2));
    }
    stream.next_out = reinterpret_cast<char*>(out.data() + produced);
    stream.avail_out = static_cast<unsigned>(std::min<size_t>(out.size() - produced, 1u << 30));
    const unsigned before = stream.avail_out;
    rc = BZ2_bzDecompress(&stream);
    produced += before - stream.avail_out;
    if (rc == BZ_OK && stream.avail_in == 0 && before == stream.avail_out) break;  // truncated
  }
  if (produced > limit) refuseBzip2Bomb(path, in.size(), limit);
  if (rc != BZ_STREAM_END) throw FormatError(path.string() + ": corrupt or truncated bzip2 data");
  out.resize(produced);
  return out;
}

}  // namespace

void throwOutOfMemory(const fs::path& path) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  std::string msg = path.string();
  msg.append(": not enough memory to read it");
  if (!ec) msg.append(" (").append(humanBytes(static_cast<double>(size))).append(" on disk)");
  throw IoError(msg);
}

namespace {

/// Refuses what is not a regular file: a FIFO would block for ever, a device (/dev/zero) never
/// ends, a link loop cannot be followed.
void requireRegularFile(const fs::path& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) throw IoError(path.string() + ": " + ec.message());
  if (fs::is_directory(st)) throw IoError(path.string() + ": is a folder, expected a file");
  if (fs::exists(st) && !fs::is_regular_file(st)) {
    throw IoError(path.string() + ": not a regular file (a FIFO, device or socket cannot be read as data)");
  }
}

}  // namespace

std::vector<uint8_t> readFileBytes(const fs::path& path) {
  requireRegularFile(path);
  return readNamingMemory(path, [&] {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path.string() + ": cannot open (" + std::strerror(errno) + ")");
    // In large reads (the size it has now, then whatever it grew by), not a byte at a time.
    std::error_code ec;
    const uintmax_t size = fs::file_size(path, ec);
    std::vector<uint8_t> bytes(ec ? 0 : static_cast<size_t>(size));
    in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    size_t got = static_cast<size_t>(in.gcount());
    if (in && in.peek() != std::char_traits<char>::eof()) {
      while (in) {
        bytes.resize(std::max<size_t>(2 * bytes.size(), got + (size_t{1} << 16)));
        in.read(reinterpret_cast<char*>(bytes.data() + got), static_cast<std::streamsize>(bytes.size() - got));
        got += static_cast<size_t>(in.gcount());
      }
    }
    bytes.resize(got);
    if (in.bad()) throw IoError(path.string() + ": read failed");
    if (path.extension() == ".bz2") return bunzip(bytes, path);
    return bytes;
  });
}

std::string readTextFile(const fs::path& path) {
  return readNamingMemory(path, [&] {
    const auto bytes = readFileBytes(path);
    return std::string(bytes.begin(), bytes.end());
  });
}

namespace {

/// ".NAME.tmp-PID-": the prefix of NAME's staging folders (and of its temporary files).
std::string temporaryPrefix(const fs::path& path) {
  std::string prefix(".");
  prefix.append(path.filename().string()).append(".tmp-");
  return prefix;
}

fs::path parentOf(const fs::path& path) {
  return path.has_parent_path() ? path.parent_path() : fs::path(".");
}

/// A fresh temporary name beside `path`: the prefix, this process's id and a random number.
fs::path temporaryBeside(const fs::path& path) {
  std::random_device rd;
  // Built with append: GCC 12 warns falsely (-Wrestrict) on a chain of string operator+.
  std::string name = temporaryPrefix(path);
  name.append(std::to_string(::getpid())).append("-").append(std::to_string(rd() & 0xffffff));
  return parentOf(path) / name;
}

/// True when `text` is 1 to `most` decimal digits.
bool allDigits(std::string_view text, size_t most) {
  return !text.empty() && text.size() <= most &&
         std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

/// A temporary file or staging folder that a writer no longer running left: its name, and the
/// prefix (temporaryPrefix) of the file it was writing.
struct StaleTemporary {
  std::string name, prefix;
};

/// `name` as a StaleTemporary when it has the exact form temporaryBeside gives,
/// ".NAME.tmp-PID-RANDOM" (PID and RANDOM decimal), and process PID does not exist.
std::optional<StaleTemporary> staleTemporary(const std::string& name) {
  // PID and RANDOM hold no ".tmp-": the last one in the name ends NAME.
  const size_t at = name.rfind(".tmp-");
  if (at == std::string::npos || at == 0 || name[0] != '.') return std::nullopt;
  const std::string_view rest = std::string_view(name).substr(at + 5);  // "PID-RANDOM"
  const size_t dash = rest.find('-');
  if (dash == std::string_view::npos) return std::nullopt;
  const std::string_view pid_text = rest.substr(0, dash);
  if (!allDigits(pid_text, 7) || !allDigits(rest.substr(dash + 1), 8)) return std::nullopt;
  const long pid = std::strtol(std::string(pid_text).c_str(), nullptr, 10);
  if (pid <= 0 || pid > 4194304 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) return std::nullopt;
  return StaleTemporary{name, name.substr(0, at + 5)};
}

/// What this process found the last time it listed a folder for stale temporaries.
struct FolderSweep {
  std::chrono::steady_clock::time_point listed_at;
  std::vector<StaleTemporary> stale;  // not removed yet
};

// Removes the temporary files and staging folders that writers of `path` killed before they
// finished left beside it (their names carry the writer's process id, and that process no longer
// exists). The folder is listed at most once a minute by a process, not before every write: a
// tiled map's folder holds thousands of files and a night writes hundreds of them, so a listing
// before each write cost time that grew with the folder (about 0.9 s of a 4.7 s night after a
// year of nights). What a listing found is removed when its file is next written.
void removeStaleTemporaries(const fs::path& dir, const fs::path& path) {
  constexpr std::chrono::seconds kListAgainAfter{60};
  // Never destroyed: a write may still run on another thread while the process exits.
  static std::mutex& mutex = *new std::mutex;
  static std::map<std::string, FolderSweep>& folders = *new std::map<std::string, FolderSweep>;
  std::error_code ec;
  const fs::path absolute = fs::absolute(dir, ec);
  const std::string key = (ec ? dir : absolute.lexically_normal()).string();
  const std::string prefix = temporaryPrefix(path);
  std::vector<std::string> remove;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    const auto now = std::chrono::steady_clock::now();
    auto [it, fresh] = folders.try_emplace(key);
    FolderSweep& sweep = it->second;
    if (fresh || now - sweep.listed_at >= kListAgainAfter) {
      sweep = FolderSweep{now, {}};
      for (fs::directory_iterator e(dir, ec), end; !ec && e != end; e.increment(ec)) {
        if (auto stale = staleTemporary(e->path().filename().string())) sweep.stale.push_back(std::move(*stale));
      }
    }
    std::erase_if(sweep.stale, [&](const StaleTemporary& t) {
      if (t.prefix != prefix) return false;
      remove.push_back(t.name);
      return true;
    });
  }
  for (const std::string& name : remove) {
    std::error_code ignored;
    fs::remove_all(dir / name, ignored);  // a temporary file, or a staging folder
  }
}

}  // namespace

namespace {

/// What an existing entry is, in words, when it is not a regular file; empty for a regular file.
std::string nonRegularKind(const struct stat& st) {
  if (S_ISREG(st.st_mode)) return {};
  if (S_ISDIR(st.st_mode)) return "a folder";
  if (S_ISFIFO(st.st_mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(st.st_mode)) return "a character device";
  if (S_ISBLK(st.st_mode)) return "a block device";
  if (S_ISSOCK(st.st_mode)) return "a socket";
  return "not a regular file";
}

/// The kind of what exists at `path` (links followed) when it is not a regular file; empty when
/// it is one or nothing is there.
std::string existingNonRegular(const fs::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {};
  return nonRegularKind(st);
}

}  // namespace

fs::path followLinks(const fs::path& path) {
  fs::path p = path;
  for (int hops = 0; hops < 40; ++hops) {
    std::error_code ec;
    if (!fs::is_symlink(fs::symlink_status(p, ec)) || ec) return p;
    const fs::path target = fs::read_symlink(p, ec);
    if (ec) throw IoError(path.string() + ": cannot read the link (" + ec.message() + ")");
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  throw IoError(path.string() + ": too many levels of symbolic links");
}

void writeFileAtomic(const fs::path& link_or_path, const std::vector<uint8_t>& bytes) {
  // Through a link, the target is replaced and the link stays (as a plain write would do).
  const fs::path path = followLinks(link_or_path);
  refuseNonRegularFile(path);
  const fs::path dir = parentOf(path);
  removeStaleTemporaries(dir, path);
  const fs::path tmp = temporaryBeside(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (errno == ENOENT || errno == ENOTDIR) {
      throw IoError(path.string() + ": cannot create: the folder '" + dir.string() + "' does not exist");
    }
    throw IoError(path.string() + ": cannot create (" + std::strerror(errno) + ")");
  }
  auto fail = [&](const char* what) {
    const int err = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    throw IoError(path.string() + ": " + what + " (" + std::strerror(err) + "); the previous file is unchanged");
  };
  size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write failed");
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) fail("flush to disk failed");
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw IoError(path.string() + ": close failed (" + std::strerror(err) + ")");
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw IoError(path.string() + ": cannot move into place (" + std::strerror(err) + ")");
  }
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);  // best effort: the rename itself is already atomic
    ::close(dfd);
  }
}

void appendToFile(const fs::path& path, uint64_t keep_bytes, const std::vector<uint8_t>& bytes) {
  refuseNonRegularFile(path);  // before open: opening a FIFO to write waits for a reader
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) throw IoError(path.string() + ": cannot open for appending (" + std::strerror(errno) + ")");
  struct stat st {};
  const bool stated = ::fstat(fd, &st) == 0;
  if (stated && !S_ISREG(st.st_mode)) {  // replaced by something else since the check above
    ::close(fd);
    throw IoError(path.string() + ": is " + nonRegularKind(st) + ", not a regular file; nothing was written");
  }
  if (!stated || static_cast<uint64_t>(st.st_size) < keep_bytes) {
    ::close(fd);
    throw IoError(path.string() + ": changed while it was being read; nothing was written");
  }
  auto fail = [&](const char* what) {
    const int err = errno;
    const bool restored = ::ftruncate(fd, static_cast<off_t>(keep_bytes)) == 0;
    ::close(fd);
    throw IoError(path.string() + ": " + what + " (" + std::strerror(err) + ")" +
                  (restored ? "; the map is unchanged" : "; the unfinished append at its end is ignored by readers"));
  };
  if (static_cast<uint64_t>(st.st_size) > keep_bytes && ::ftruncate(fd, static_cast<off_t>(keep_bytes)) != 0) {
    fail("cannot remove an interrupted append");
  }
  size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::pwrite(fd, bytes.data() + written, bytes.size() - written,
                               static_cast<off_t>(keep_bytes + written));
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write failed");
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) fail("flush to disk failed");
  if (::close(fd) != 0) throw IoError(path.string() + ": close failed (" + std::strerror(errno) + ")");
}

namespace {

/// Takes an exclusive flock on `fd`, retrying when interrupted. @return 0 or the errno.
int lockExclusive(int fd) {
  while (::flock(fd, LOCK_EX) != 0) {
    if (errno != EINTR) return errno;
  }
  return 0;
}

bool missing(const fs::path& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) != 0 && errno == ENOENT;
}

}  // namespace

FileLock::FileLock(const fs::path& link_or_path, Missing if_missing) {
  // A map reached through a link is created where the link points: that folder is locked.
  const fs::path path = followLinks(link_or_path);
  for (;;) {
    if (if_missing == Missing::LockFolder && missing(path)) {
      const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
      fd_ = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
      if (fd_ < 0) {
        throw IoError(path.string() + ": cannot open its folder to create it (" + std::strerror(errno) + ")");
      }
      if (const int err = lockExclusive(fd_)) {
        ::close(fd_);
        throw IoError(path.string() + ": cannot lock its folder (" + std::strerror(err) + ")");
      }
      // Still missing once the folder is ours: this holder creates it. Else another command
      // created it meanwhile: lock the file like any update.
      if (missing(path)) {
        creating_ = true;
        return;
      }
      ::close(fd_);
      continue;
    }
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) {
      if (errno == ENOENT && if_missing == Missing::LockFolder) continue;
      throw IoError(path.string() + ": cannot open (" + std::strerror(errno) + ")");
    }
    if (const int err = lockExclusive(fd_)) {
      ::close(fd_);
      throw IoError(path.string() + ": cannot lock (" + std::strerror(err) + ")");
    }
    // Still the file under that name? (Another writer may have renamed a new one over it.)
    struct stat held {}, named {};
    if (::fstat(fd_, &held) == 0 && ::stat(path.c_str(), &named) == 0 && held.st_dev == named.st_dev &&
        held.st_ino == named.st_ino) {
      return;
    }
    ::close(fd_);
  }
}

namespace {

/// One spelling per file: absolute, links and ".." resolved as far as the path exists.
std::string canonicalName(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(followLinks(path), ec), ec);
  return ec ? fs::absolute(path).lexically_normal().string() : p.string();
}

bool sameFile(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::equivalent(a, b, ec) && !ec) return true;
  return canonicalName(a) == canonicalName(b);
}

std::string named(const PlannedOutput& o) { return o.flag + " '" + o.path.string() + "'"; }

void checkOneOutput(const PlannedOutput& o) {
  std::error_code ec;
  const bool exists = fs::exists(o.path, ec);
  if (!exists) return;
  const bool is_folder = fs::is_directory(o.path, ec);
  if (o.folder) {
    if (!is_folder) throw UsageError(named(o) + " exists and is not a folder: refusing to replace it with one");
    return;
  }
  const std::string kind = existingNonRegular(o.path);
  if (!kind.empty()) {
    throw UsageError(named(o) + " is " + kind + ", not a regular file: chronomap replaces only regular files " +
                     "(write to a file path)");
  }
}

}  // namespace

void checkOutputs(const std::vector<PlannedOutput>& outputs, const std::vector<fs::path>& inputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const PlannedOutput& o = outputs[i];
    if (o.path.empty()) continue;
    for (const fs::path& input : inputs) {
      std::error_code ec;
      if (fs::equivalent(o.path, input, ec) && !ec) {
        throw UsageError(named(o) + " is the input '" + input.string() +
                         "': refusing to overwrite it (write to another file)");
      }
    }
    for (size_t j = 0; j < i; ++j) {
      if (!outputs[j].path.empty() && sameFile(o.path, outputs[j].path)) {
        throw UsageError(named(o) + " is the same file as " + named(outputs[j]) +
                         ": one would replace the other (give each output its own name)");
      }
    }
    checkOneOutput(o);
  }
}

void refuseOverwritingInputs(const fs::path& output, const std::vector<fs::path>& inputs) {
  checkOutputs({{output, "output"}}, inputs);
}

void refuseNonRegularFile(const fs::path& path) {
  const std::string kind = existingNonRegular(path);
  if (!kind.empty()) {
    throw IoError(path.string() + ": is " + kind + ", not a regular file: chronomap replaces only regular files, " +
                  "so it is left alone and nothing was written");
  }
}

StagedFolder::StagedFolder(const fs::path& destination) : destination_(followLinks(destination)) {
  if (destination_.filename().empty()) destination_ = destination_.parent_path();
  const fs::path dir = parentOf(destination_);
  std::error_code ec;
  if (fs::exists(destination_, ec) && !fs::is_directory(destination_, ec)) {
    throw IoError(destination_.string() + ": exists and is not a folder; nothing was written");
  }
  fs::create_directories(dir, ec);
  if (ec) throw IoError(dir.string() + ": cannot create folder (" + ec.message() + ")");
  removeStaleTemporaries(dir, destination_);
  staging_ = temporaryBeside(destination_);
  if (!fs::create_directory(staging_, ec) || ec) {
    throw IoError(destination.string() + ": cannot create a folder beside it (" +
                  (ec ? ec.message() : std::string("exists")) + ")");
  }
}

StagedFolder::~StagedFolder() {
  if (committed_) return;
  std::error_code ignored;
  fs::remove_all(staging_, ignored);
}

void StagedFolder::commit() {
  std::error_code ec;
  const bool exists = fs::exists(destination_, ec);
  if (exists && !fs::is_directory(destination_, ec)) {
    throw IoError(destination_.string() + ": exists and is not a folder; nothing was written");
  }
  if (!exists || fs::is_empty(destination_, ec)) {
    if (exists) fs::remove(destination_, ec);
    if (::rename(staging_.c_str(), destination_.c_str()) != 0) {
      throw IoError(destination_.string() + ": cannot move into place (" + std::strerror(errno) + ")");
    }
    committed_ = true;
    return;
  }
  // Entry by entry: what an entry replaces goes into the staging folder's ".replaced" first,
  // which is removed with the staging folder.
  const fs::path replaced = staging_ / ".replaced";
  fs::create_directory(replaced, ec);
  std::vector<fs::path> entries;
  for (const auto& entry : fs::directory_iterator(staging_)) {
    if (entry.path() != replaced) entries.push_back(entry.path());
  }
  for (const fs::path& entry : entries) {
    const fs::path target = destination_ / entry.filename();
    if (fs::exists(fs::symlink_status(target)) && ::rename(target.c_str(), (replaced / entry.filename()).c_str()) != 0) {
      throw IoError(target.string() + ": cannot replace (" + std::strerror(errno) + ")");
    }
    if (::rename(entry.c_str(), target.c_str()) != 0) {
      throw IoError(target.string() + ": cannot move into place (" + std::strerror(errno) + ")");
    }
  }
  fs::remove_all(staging_, ec);
  committed_ = true;
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the lock
}

std::string dataExtension(const fs::path& path) {
  fs::path p = path;
  if (p.extension() == ".bz2") p = p.stem();
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace chronomap
