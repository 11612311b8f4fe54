#pragma once
/// @file
/// File helpers: whole-file reads with clear errors, and atomic writes.

#include <cstdint>
#include <filesystem>
#include <new>
#include <string>
#include <vector>

namespace chronomap::io {

/// Reads a whole file. Files ending in .bz2 are decompressed, up to a bound on how far they may
/// expand (docs/reliability.md, "Limits").
/// @throw IoError naming the file when it cannot be read or memory runs out; FormatError for a
/// corrupt .bz2 or one that expands beyond the bound.
std::vector<uint8_t> readFileBytes(const std::filesystem::path& path);

/// @throw IoError "PATH: not enough memory to read it (SIZE on disk)".
[[noreturn]] void throwOutOfMemory(const std::filesystem::path& path);

/// Runs `read`, a reader of `path`, turning std::bad_alloc into throwOutOfMemory(path): so that
/// running out of memory names the file whatever command reads it.
template <class Read>
auto readNamingMemory(const std::filesystem::path& path, Read&& read) -> decltype(read()) {
  try {
    return read();
  } catch (const std::bad_alloc&) {
    throwOutOfMemory(path);
  }
}

/// Reads a whole text file (see readFileBytes).
std::string readTextFile(const std::filesystem::path& path);

/// Writes `bytes` to `path` atomically: into a temporary file in the same folder, flushed to
/// disk, then renamed over `path`. On any failure the temporary file is removed and `path` is
/// left as it was.
/// @throw IoError naming the file (disk full, permission, missing folder).
void writeFileAtomic(const std::filesystem::path& path, const std::vector<uint8_t>& bytes);

/// Appends `bytes` to `path` after its first `keep_bytes` bytes (anything beyond them, such as
/// an interrupted earlier append, is cut off first), then flushes the file to disk. On failure
/// (disk full, a write limit) the file is cut back to `keep_bytes`, so it holds what it held.
/// A kill during the call leaves the first `keep_bytes` bytes followed by a prefix of `bytes`.
/// @throw IoError naming the file.
void appendToFile(const std::filesystem::path& path, uint64_t keep_bytes, const std::vector<uint8_t>& bytes);

/// An exclusive advisory lock (flock) on a file, held until destruction, so that two processes
/// updating one map run one after the other. The lock follows the name: when another process
/// replaced the file (rename) while this one waited, the new file is locked.
class FileLock {
 public:
  /// What to lock when the file does not exist (yet).
  enum class Missing : uint8_t {
    Fail,        ///< throw IoError
    LockFolder,  ///< lock its folder instead, for the holder to create the file: two commands
                 ///< creating one map run one after the other, and one that finds the file
                 ///< created meanwhile locks the file as usual
  };
  /// Blocks until the lock is held. @throw IoError when the file (or folder) cannot be opened.
  explicit FileLock(const std::filesystem::path& path, Missing missing = Missing::Fail);
  ~FileLock();
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  /// True when the file did not exist once the lock was held (its folder is locked).
  bool creating() const { return creating_; }

 private:
  int fd_ = -1;
  bool creating_ = false;
};

/// Refuses to write `output` over one of `inputs`, before any work: throws UsageError when it
/// names the same existing file as an input, however either is spelled (links, "..", hard
/// links). Outputs that do not exist yet are never an input.
void refuseOverwritingInputs(const std::filesystem::path& output, const std::vector<std::filesystem::path>& inputs);

/// `path` without a trailing ".bz2", lower-cased extension of what remains (".pcd", ".ply", ...).
std::string dataExtension(const std::filesystem::path& path);

}  // namespace chronomap::io
