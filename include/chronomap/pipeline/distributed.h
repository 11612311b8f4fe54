#pragma once
/// @file
/// build() spread over the processes of an MPI job (`mpirun -np N chronomap build ...`). Rank 0
/// integrates every recording in turn and the other ranks cast its frames with it: frames are
/// handed out ahead of the one rank 0 merges, each rank sends a frame's deltas (every counter bit
/// for bit), and rank 0 merges every frame in frame order, casting frames itself while it waits
/// (integrate()'s FrameSharing). Rank 0 then does what build() does after integrating: sorts the
/// sessions by time, registers and re-aligns them when asked, adds them in time order and writes
/// the map once, atomically, holding its file lock. The file is byte-identical whatever N, and to
/// build()'s. Registration and re-alignment run on rank 0 alone (they need every session's map).
///
/// Without MPI in the build (CMake CHRONOMAP_MPI=OFF, or no MPI found), or without mpirun, the
/// same calls run on this process alone.

#include <exception>
#include <optional>

#include "chronomap/pipeline/map4d.h"

namespace chronomap {

/// True when this chronomap was built with MPI.
bool mpiBuilt();

/// The processes of this run: the ranks of an MPI job when launched by mpirun (MPI is started
/// here and finished by the destructor), else this process alone (MPI is not touched).
class Ranks {
 public:
  /// @throw UsageError when launched by mpirun with several processes but built without MPI
  /// (each would build the whole map).
  Ranks();
  ~Ranks();
  Ranks(const Ranks&) = delete;
  Ranks& operator=(const Ranks&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  int rank_ = 0;
  int size_ = 1;
  bool started_ = false;
};

/// Thrown on the ranks other than 0 when the build failed anywhere: rank 0 reports the error
/// (the one build() would have given), the others end with the same exit code and say nothing.
class RankStopped : public std::exception {
 public:
  explicit RankStopped(int exit_code) : exit_code_(exit_code) {}
  const char* what() const noexcept override { return "the build failed on another rank"; }
  int exitCode() const { return exit_code_; }  ///< 2 for bad usage, 1 otherwise

 private:
  int exit_code_;
};

/// build() over `ranks` (above). Every failure is agreed on by all ranks before any goes on, so
/// that none waits for one that stopped; a rank killed meanwhile ends the job (mpirun) before the
/// map is written, leaving the previous file.
/// @return the result on rank 0, nullopt on the others.
/// @throw on rank 0, what build() throws for the same input (for a recording that fails, the
/// error of the first in the given order); RankStopped on the others.
std::optional<BuildResult> buildOnRanks(const BuildSettings& settings, const Ranks& ranks);

}  // namespace chronomap
