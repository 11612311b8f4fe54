#pragma once
/// @file
/// File helpers: whole-file reads with clear errors, and atomic writes.

#include <cstdint>
#include <filesystem>
#include <new>
#include <string>
#include <vector>

namespace chronomap {

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

/// The file that `path` names once symbolic links in its last component are followed (to a
/// file that may not exist yet); `path` itself when it is no link.
/// @throw IoError for a link loop.
std::filesystem::path followLinks(const std::filesystem::path& path);

/// Writes `bytes` to `path` atomically: into a temporary file in the same folder, flushed to
/// disk, then renamed over `path`. On any failure the temporary file is removed and `path` is
/// left as it was. When `path` is a symbolic link, the file it points to is replaced and the
/// link kept. Only a regular file is ever replaced (refuseNonRegularFile).
/// @throw IoError naming the file (disk full, permission, missing folder, not a regular file).
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

/// A folder of outputs written as a whole: files go into a hidden sibling folder first
/// (".NAME.tmp-PID-N"), and commit() moves them into `destination`. Destroyed without a commit
/// (an error, a full disk) it removes everything written, so the destination is never left
/// half written: it stays as it was, or does not exist. A missing or empty destination is
/// replaced by one rename; into a folder that holds files, each top-level entry is renamed into
/// place (what it replaces is removed, other files there are left alone). Staging folders left
/// by a killed process are removed by the next one.
class StagedFolder {
 public:
  /// @throw IoError when the staging folder cannot be created.
  explicit StagedFolder(const std::filesystem::path& destination);
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  /// Where to write until commit().
  const std::filesystem::path& path() const { return staging_; }
  /// Moves what was written into the destination. @throw IoError naming the destination.
  void commit();

 private:
  std::filesystem::path destination_;
  std::filesystem::path staging_;
  bool committed_ = false;
};

/// One file (or folder) a command is about to write, with the flag that asked for it.
struct PlannedOutput {
  std::filesystem::path path;  ///< empty: not asked for this time (skipped)
  std::string flag;            ///< how the user named it, for messages: "-o", "--save-rhythm"
  bool folder = false;         ///< a folder of outputs (StagedFolder) rather than one file
};

/// Checks all the outputs of one command together, before any work, so that nothing is
/// written unless everything can be: throws UsageError naming the flags when an output
/// - names an input (however either is spelled: links, "..", hard links),
/// - names the same file as another output of the command (the second would replace the first),
/// - exists but is not what it would be replaced by: a FIFO, a device, a socket or a folder
///   where a file goes, a file where a folder goes (writeFileAtomic refuses those too).
/// Outputs that do not exist yet are never an input.
void checkOutputs(const std::vector<PlannedOutput>& outputs, const std::vector<std::filesystem::path>& inputs);

/// checkOutputs for a command with one output.
void refuseOverwritingInputs(const std::filesystem::path& output, const std::vector<std::filesystem::path>& inputs);

/// @throw IoError when `path` (links followed) exists and is not a regular file: chronomap
/// replaces regular files only, never a FIFO, a device, a socket or a folder.
void refuseNonRegularFile(const std::filesystem::path& path);

/// `path` without a trailing ".bz2", lower-cased extension of what remains (".pcd", ".ply", ...).
std::string dataExtension(const std::filesystem::path& path);

}  // namespace chronomap
