#pragma once
/// @file
/// A parallel loop over independent items on plain threads: each thread takes the next item
/// until none is left. Used where items are few and coarse (sessions, rendered frames), and
/// where ThreadSanitizer must see every hand-over (thread start and join are visible to it;
/// TBB's scheduler, from Debian's uninstrumented libtbb, is not).

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace chronomap {

/// Calls fn(i) for every i in [0, n) on up to `threads` threads (0: one per core). The first
/// exception thrown stops the handing out of further items and is rethrown here.
template <class Fn>
void parallelFor(size_t n, int threads, const Fn& fn) {
  size_t workers = threads > 0 ? static_cast<size_t>(threads) : std::max(1u, std::thread::hardware_concurrency());
  workers = std::min(workers, n);
  if (workers <= 1) {
    for (size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&] {
    for (size_t i = next++; i < n && !failed; i = next++) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  for (size_t t = 1; t < workers; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace chronomap
