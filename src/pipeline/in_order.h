#pragma once
// Independent pieces of work on several threads with one thread's outcome: the streaming build's
// groups of tiles, the tiles `untile` and the consensus of a tiled map read. Each piece writes
// only its own output; the caller joins the outputs in order afterwards.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace chronomap::pipeline_detail {

/// Threads to use for `pieces` pieces: `threads` (0: one per core), at most one per piece, at
/// least one.
inline int threadsFor(int threads, size_t pieces) {
  const int wanted = threads > 0 ? threads : static_cast<int>(std::thread::hardware_concurrency());
  return static_cast<int>(std::max<size_t>(1, std::min<size_t>(pieces, static_cast<size_t>(std::max(wanted, 1)))));
}

/// Calls piece(k) for every k in [0, n) on up to `threads` threads (0: one per core; with one,
/// in order on the calling thread). A piece that throws stops the pieces after it from starting
/// (those before it still run), and the exception rethrown is the first failing piece's in
/// order, so the error is the one a single thread gives whatever the threads and the timing.
template <class Piece>
void runInOrder(size_t n, int threads, Piece&& piece) {
  threads = threadsFor(threads, n);
  if (threads == 1) {
    for (size_t k = 0; k < n; ++k) piece(k);
    return;
  }
  std::vector<std::exception_ptr> errors(n);
  std::atomic<size_t> first_failed{n};
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, n, 1),
        [&](const tbb::blocked_range<size_t>& range) {
          for (size_t k = range.begin(); k != range.end(); ++k) {
            if (k > first_failed.load()) continue;  // a piece before it failed
            try {
              piece(k);
            } catch (...) {
              errors[k] = std::current_exception();
              size_t seen = first_failed.load();
              while (k < seen && !first_failed.compare_exchange_weak(seen, k)) {
              }
            }
          }
        },
        tbb::simple_partitioner());
  });
  const size_t failed = first_failed.load();
  if (failed < n) std::rethrow_exception(errors[failed]);
}

}  // namespace chronomap::pipeline_detail
