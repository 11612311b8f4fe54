// The two guards every binding uses (docs/python.md, "Threads and Ctrl-C"): ObjectLock, which
// serialises the calls on one object, and LongCall, which lets Ctrl-C stop a long call.

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>
#include <utility>

#include "bindings.h"

namespace chronomap::python {

// ---- ObjectLock ----

/// One object's lock, alive while some thread holds or waits for it.
struct ObjectLock::Slot {
  std::mutex mutex;
  size_t users = 0;  // holders and waiters, counted under the registry's mutex
};

namespace {

/// The locks of the objects in use, by address. Never destroyed: a thread may still release a
/// lock while the interpreter shuts down.
struct Registry {
  std::mutex mutex;
  std::unordered_map<const void*, std::unique_ptr<ObjectLock::Slot>> slots;
};

Registry& registry() {
  static auto* r = new Registry;
  return *r;
}

}  // namespace

ObjectLock::Slot* ObjectLock::acquire(const void* object) {
  Slot* slot = nullptr;
  {
    Registry& r = registry();
    const std::lock_guard<std::mutex> lock(r.mutex);
    auto& s = r.slots[object];
    if (!s) s = std::make_unique<Slot>();
    ++s->users;
    slot = s.get();
  }
  if (!slot->mutex.try_lock()) {
    // Wait without the GIL: the holder may need it to finish (to convert its result).
    const py::gil_scoped_release release;
    slot->mutex.lock();
  }
  return slot;
}

void ObjectLock::release(const void* object, Slot* slot) {
  slot->mutex.unlock();
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (--slot->users == 0) r.slots.erase(object);
}

ObjectLock::ObjectLock(const void* object) { held_[0] = {object, acquire(object)}; }

ObjectLock::ObjectLock(const void* a, const void* b) {
  // In address order, so that two threads locking the same pair cannot wait for each other.
  if (std::less<const void*>()(b, a)) std::swap(a, b);
  held_[0] = {a, acquire(a)};
  if (b != a) held_[1] = {b, acquire(b)};
}

ObjectLock::~ObjectLock() {
  for (auto it = held_.rbegin(); it != held_.rend(); ++it) {
    if (it->second) release(it->first, it->second);
  }
}

// ---- LongCall ----

namespace {

/// Thrown from a progress report to stop the library call (not a std::exception, so that no
/// handler in the library takes it for an error of its own).
struct Stopped {};

/// How often the waiting thread runs Python's signal handlers.
constexpr auto kSignalPoll = std::chrono::milliseconds(20);

}  // namespace

LongCall::LongCall(py::object callback) : callback_(std::move(callback)), has_callback_(!callback_.is_none()) {}

Progress LongCall::progress() {
  Progress p;
  p.step = [this](const std::string&) {
    if (stop_) throw Stopped{};
  };
  p.work = [this](const std::string& label, size_t done, size_t total) {
    if (stop_) throw Stopped{};
    if (!has_callback_) return;
    const py::gil_scoped_acquire acquire;
    try {
      callback_(label, done, total);
    } catch (py::error_already_set& e) {
      raised_ = std::make_shared<py::error_already_set>(std::move(e));
      stop_ = true;
      throw Stopped{};
    }
  };
  return p;
}

void LongCall::runErased(const std::function<void()>& work) {
  std::mutex mutex;
  std::condition_variable finished;
  bool done = false;
  std::exception_ptr error;
  std::thread worker([&] {
    try {
      work();
    } catch (...) {
      error = std::current_exception();
    }
    const std::lock_guard<std::mutex> lock(mutex);
    done = true;
    finished.notify_one();
  });
  std::optional<py::error_already_set> interrupt;
  for (;;) {
    {
      const py::gil_scoped_release release;
      std::unique_lock<std::mutex> lock(mutex);
      if (finished.wait_for(lock, kSignalPoll, [&] { return done; })) break;
    }
    // Only the main thread runs signal handlers; elsewhere this returns 0 at once.
    if (!interrupt && PyErr_CheckSignals() != 0) {
      interrupt.emplace();  // takes the handler's exception (KeyboardInterrupt)
      stop_ = true;         // the work stops at its next report
    }
  }
  {
    const py::gil_scoped_release release;
    worker.join();
  }
  if (interrupt) throw std::move(*interrupt);
  if (raised_) throw *raised_;
  if (error) std::rethrow_exception(error);
}

}  // namespace chronomap::python
