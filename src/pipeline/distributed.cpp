// pipeline/distributed.h with MPI: the only file of chronomap that calls MPI.

#include "chronomap/pipeline/distributed.h"

#include <mpi.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <exception>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "build_steps.h"
#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/core/memory.h"
#include "chronomap/core/time.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/store/cmap.h"

namespace chronomap {

namespace {

using pipeline_detail::Pending;

/// Launched by mpirun (Open MPI, or a PMI launcher such as MPICH's)?
bool launchedByMpirun() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
    if (std::getenv(name)) return true;
  }
  return false;
}

/// The processors this process may run on: mpirun binds each rank to its own by default, and
/// integration's threads should not outnumber them. 0 when unknown.
int processorsAllowed() {
  cpu_set_t set;
  CPU_ZERO(&set);
  return sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : 0;
}

/// Waits for `request` without spinning: Open MPI's blocking calls poll a core at 100% while they
/// wait, which on a shared machine takes processor time from the ranks still integrating. Checks
/// every 250 us instead (each check also moves a large message on by a piece).
void waitGently(MPI_Request& request) {
  int done = 0;
  for (MPI_Test(&request, &done, MPI_STATUS_IGNORE); !done; MPI_Test(&request, &done, MPI_STATUS_IGNORE)) {
    std::this_thread::sleep_for(std::chrono::microseconds(250));
  }
}

/// The failures of one step of the job, agreed on by every rank at the step's end.
class Steps {
 public:
  explicit Steps(const Ranks& ranks) : ranks_(ranks) {}

  /// Runs `fn`, keeping what it throws under `key` (the lowest key wins: the dataset's index, so
  /// that the error is the one the datasets' order gives first). @return false when it threw.
  template <typename Fn>
  bool run(int key, Fn&& fn) {
    try {
      fn();
      return true;
    } catch (...) {
      if (key < key_) {
        key_ = key;
        error_ = std::current_exception();
      }
      return false;
    }
  }

  /// Every rank learns whether any failed. Then rank 0 throws the failure (its own as thrown,
  /// another rank's as its message) and the others throw RankStopped.
  void agree() {
    int in[2] = {key_, ranks_.rank()};
    int out[2] = {INT_MAX, 0};
    MPI_Request request = MPI_REQUEST_NULL;
    MPI_Iallreduce(in, out, 1, MPI_2INT, MPI_MINLOC, MPI_COMM_WORLD, &request);
    waitGently(request);
    if (out[0] == INT_MAX) return;
    const int owner = out[1];
    auto [code, message] = ranks_.rank() == owner ? describeError(error_) : ErrorReport{0, ""};
    int length = static_cast<int>(message.size());
    MPI_Bcast(&code, 1, MPI_INT, owner, MPI_COMM_WORLD);
    MPI_Bcast(&length, 1, MPI_INT, owner, MPI_COMM_WORLD);
    message.resize(static_cast<size_t>(length));
    MPI_Bcast(message.data(), length, MPI_CHAR, owner, MPI_COMM_WORLD);
    if (ranks_.rank() != 0) throw RankStopped(code);
    if (owner == 0) std::rethrow_exception(error_);
    if (code == 2) throw UsageError(message);
    throw Error(message);
  }

 private:
  const Ranks& ranks_;
  int key_ = INT_MAX;
  std::exception_ptr error_;
};

// The messages of the frames shared out (SharedFrames, serveSharedFrames).
constexpr int kControlTag = 1;  // rank 0 to the others: two uint64, what to do and with what
constexpr int kFrameTag = 2;    // the others to rank 0: a frame's answer (FrameAnswer)
enum Control : uint64_t {
  kOpen = 1,   // open recording N (the settings' datasets) as integrateDataset opens it
  kCast = 2,   // cast frame N of it and answer
  kClose = 3,  // the recording is done (every frame handed out was answered)
  kDone = 4,   // every recording is done
};
/// Frames handed to one rank and not yet collected, at most: it casts the next while the answers
/// before are on their way.
constexpr size_t kFramesPerRank = 4;
/// The next recording's first frames handed to each rank while rank 0 adds the last one
/// (SharedFrames::prefetch), and so the most answers a rank keeps on their way.
constexpr size_t kPrefetchPerRank = 16;

void sendControl(int to, Control what, uint64_t value) {
  const uint64_t message[2] = {what, value};
  MPI_Request request = MPI_REQUEST_NULL;
  MPI_Isend(message, 2, MPI_UINT64_T, to, kControlTag, MPI_COMM_WORLD, &request);
  waitGently(request);
}

/// A frame's answer as it travels: the frame, the length of what follows, then its deltas
/// (encodeDeltas) or the error that casting it threw (exit code and message); padded to whole
/// blocks of kAnswerBlock bytes, the unit it is sent in (MPI counts are ints: blocks let an answer
/// pass 2 GiB).
constexpr int kAnswerBlock = 64;

/// The MPI type of one block, committed while it lives.
class BlockType {
 public:
  BlockType() {
    MPI_Type_contiguous(kAnswerBlock, MPI_BYTE, &type_);
    MPI_Type_commit(&type_);
  }
  ~BlockType() { MPI_Type_free(&type_); }
  BlockType(const BlockType&) = delete;
  BlockType& operator=(const BlockType&) = delete;
  MPI_Datatype get() const { return type_; }

 private:
  MPI_Datatype type_ = MPI_DATATYPE_NULL;
};

struct FrameAnswer {
  static std::vector<uint8_t> deltas(uint64_t frame, const VoxelDeltas& d) {
    std::vector<uint8_t> body = encodeDeltas(d);
    return framed(frame, 1, body);
  }
  static std::vector<uint8_t> error(uint64_t frame, const std::exception_ptr& e) {
    const ErrorReport report = describeError(e);
    ByteWriter w;
    w.put(static_cast<int32_t>(report.exit_code));
    w.bytes.insert(w.bytes.end(), report.message.begin(), report.message.end());
    return framed(frame, 0, w.bytes);
  }
  /// The deltas of `frame` into `out`. @throw the error the answer carries (UsageError for exit
  /// code 2, else Error, with its message), or Error when it is not `frame`'s.
  static void read(const std::vector<uint8_t>& bytes, uint64_t frame, int from, VoxelDeltas& out) {
    const std::string source = "frame " + std::to_string(frame + 1) + " from rank " + std::to_string(from);
    ByteReader r{bytes, 0, source, "the answer"};
    if (r.get<uint64_t>() != frame) throw Error(source + ": another frame's answer arrived");
    const auto length = r.get<uint64_t>();
    const auto kind = r.get<uint8_t>();
    if (length > bytes.size() - r.pos) throw Error(source + ": the answer ends early");
    const auto body = std::span<const uint8_t>(bytes).subspan(r.pos, static_cast<size_t>(length));
    if (kind == 1) {
      decodeDeltas(body, out, source);
      return;
    }
    ByteReader e{body, 0, source, "the answer"};
    const auto code = e.get<int32_t>();
    const std::string message(body.begin() + static_cast<std::ptrdiff_t>(e.pos), body.end());
    if (code == 2) throw UsageError(message);
    throw Error(message);
  }

 private:
  static std::vector<uint8_t> framed(uint64_t frame, uint8_t kind, const std::vector<uint8_t>& body) {
    ByteWriter w;
    w.bytes.reserve(body.size() + 17 + kAnswerBlock);
    w.put(frame);
    w.put(static_cast<uint64_t>(body.size()));
    w.put(kind);
    w.bytes.insert(w.bytes.end(), body.begin(), body.end());
    w.bytes.resize((w.bytes.size() + kAnswerBlock - 1) / kAnswerBlock * kAnswerBlock, 0);
    return std::move(w.bytes);
  }
};

/// Rank 0's side of the frames shared out: hands frames to the ranks with the fewest waiting,
/// collects their answers in frame order.
class SharedFrames final : public FrameSharing {
 public:
  explicit SharedFrames(int ranks) : waiting_(static_cast<size_t>(ranks), 0) {}

  /// The recording integrated after the open one, if any: its first frames are handed out as soon
  /// as the open one's are merged (framesDone).
  void setNext(std::optional<size_t> dataset) { next_ = dataset; }

  /// Every other rank opens recording `dataset` (unless prefetch() had them open it). The answers
  /// of the recording open before that were not collected (frames prefetched past its end) are
  /// received and dropped first: they come before the new recording's on each rank.
  void open(size_t dataset) {
    if (open_ == dataset) return;
    drop();
    open_ = dataset;
    cast_.assign(waiting_.size(), 0);
    tellOthers(kOpen, dataset);
  }

  /// Every other rank opens recording `dataset` and gets its first kPrefetchPerRank frames each,
  /// to cast while rank 0 finishes the one before (compresses its map, adds its session) or opens
  /// this one. Frames past the recording's end are answered with an error, dropped when the next
  /// recording opens or at close().
  void prefetch(size_t dataset) {
    open(dataset);
    const size_t others = waiting_.size() - 1;
    for (size_t frame = 0; frame < kPrefetchPerRank * others; ++frame) {
      const size_t r = 1 + frame % others;
      sendControl(static_cast<int>(r), kCast, frame);
      ++waiting_[r];
      owner_[frame] = static_cast<int>(r);
    }
  }

  size_t handOut(size_t first, size_t end) override {
    size_t given = 0;
    for (; first + given < end; ++given) {
      size_t least = 0;  // no rank
      for (size_t r = 1; r < waiting_.size(); ++r) {
        if (waiting_[r] < kFramesPerRank && (least == 0 || waiting_[r] < waiting_[least])) least = r;
      }
      if (least == 0) break;
      sendControl(static_cast<int>(least), kCast, first + given);
      ++waiting_[least];
      owner_[first + given] = static_cast<int>(least);
    }
    return given;
  }

  bool handedOut(size_t i) const override { return owner_.count(i) != 0; }

  void framesDone() override {
    done_cast_ = cast_;
    if (next_) prefetch(*next_);
  }

  bool collect(size_t i, VoxelDeltas& out, bool wait) override {
    const int from = owner_.at(i);
    if (!receive(from, wait)) return false;
    --waiting_[static_cast<size_t>(from)];
    ++cast_[static_cast<size_t>(from)];
    owner_.erase(i);
    // Each rank answers its frames in the order it got them, and frames are collected in frame
    // order: this answer is frame i's.
    FrameAnswer::read(answer_, i, from, out);
    return true;
  }

  /// Receives (and drops) the answers still on their way, then the other ranks close the recording.
  void close() {
    drop();
    open_ = kNone;
    tellOthers(kClose, 0);
  }

  /// How many frames of the recording whose frames were last all merged each rank cast (those not
  /// collected from another: rank 0's), for `frames` in all: "rank 0 cast 12 frames, rank 1 10, rank 2 9".
  std::string castBy(size_t frames) const {
    size_t elsewhere = 0;
    std::string others;
    for (size_t r = 1; r < done_cast_.size(); ++r) {
      elsewhere += done_cast_[r];
      others += ", rank " + std::to_string(r) + " " + std::to_string(done_cast_[r]);
    }
    return "rank 0 cast " + std::to_string(frames - std::min(frames, elsewhere)) + " frame(s)" + others;
  }

  /// The other ranks stop serving frames.
  void done() {
    tellOthers(kDone, 0);
  }

 private:
  void tellOthers(Control what, uint64_t value) {
    for (int r = 1; r < static_cast<int>(waiting_.size()); ++r) sendControl(r, what, value);
  }

  /// Receives and drops every answer not collected, in the order each rank was given its frames.
  void drop() {
    for (const auto& [frame, from] : owner_) receive(from, /*wait=*/true);
    owner_.clear();
    std::fill(waiting_.begin(), waiting_.end(), 0);
  }

  /// The next answer from rank `from` into answer_. @return false when it has not all arrived
  /// and `wait` is false (a large answer moves in pieces, each when the sending rank calls MPI:
  /// the receive stays posted meanwhile, and this process goes on casting); waits for it without
  /// spinning otherwise (waitGently).
  bool receive(int from, bool wait) {
    if (receiving_ == MPI_REQUEST_NULL) {
      MPI_Status status;
      int there = 0;
      for (MPI_Iprobe(from, kFrameTag, MPI_COMM_WORLD, &there, &status); !there && wait;
           MPI_Iprobe(from, kFrameTag, MPI_COMM_WORLD, &there, &status)) {
        std::this_thread::sleep_for(std::chrono::microseconds(250));
      }
      if (!there) return false;
      int blocks = 0;
      MPI_Get_count(&status, block_.get(), &blocks);
      answer_.resize(static_cast<size_t>(std::max(blocks, 0)) * kAnswerBlock);
      MPI_Irecv(answer_.data(), blocks, block_.get(), from, kFrameTag, MPI_COMM_WORLD, &receiving_);
      receiving_from_ = from;
    }
    if (receiving_from_ != from) throw Error("an answer from rank " + std::to_string(receiving_from_) + " is pending");
    if (wait) {
      waitGently(receiving_);
    } else {
      int done = 0;
      MPI_Test(&receiving_, &done, MPI_STATUS_IGNORE);
      if (!done) return false;
    }
    receiving_ = MPI_REQUEST_NULL;
    return true;
  }

  BlockType block_;
  MPI_Request receiving_ = MPI_REQUEST_NULL;  // the answer being received into answer_
  int receiving_from_ = 0;
  static constexpr size_t kNone = ~size_t{0};
  size_t open_ = kNone;          // the recording the other ranks have open
  std::vector<size_t> waiting_;  // per rank: frames handed to it and not collected
  std::vector<size_t> cast_;     // per rank: frames of the recording open it answered
  std::vector<size_t> done_cast_;  // the same, of the recording whose frames were last all merged
  std::optional<size_t> next_;
  std::map<size_t, int> owner_;  // frames handed out and not collected: the rank casting each
  std::vector<uint8_t> answer_;
};

/// What the ranks other than 0 do while rank 0 integrates: cast the frames rank 0 hands them, of
/// the recording it opened (as integrateDataset opens it), and answer with their deltas, until
/// rank 0 is done. A frame that cannot be cast here (or a recording that does not open) is
/// answered with the error, which rank 0 throws at that frame's turn: the error the process alone
/// gives. Casting the next frame goes on while answers are on their way (kFramesPerRank).
void serveSharedFrames(const BuildSettings& s) {
  const BlockType block;
  std::unique_ptr<MemoryActivity> activity;  // out of memory is said as integrate() says it
  std::unique_ptr<Dataset> recording;
  std::exception_ptr open_error;
  std::optional<RayAccumulator> accumulator;
  VoxelDeltas deltas;
  std::deque<std::pair<std::vector<uint8_t>, MPI_Request>> answers;  // on their way, oldest first
  // Frees the answers sent, then waits for the oldest until at most `at_most` are on their way.
  const auto finishAnswers = [&](size_t at_most) {
    for (int sent = 1; sent && !answers.empty(); ) {
      MPI_Test(&answers.front().second, &sent, MPI_STATUS_IGNORE);
      if (sent) answers.pop_front();
    }
    for (; answers.size() > at_most; answers.pop_front()) waitGently(answers.front().second);
  };
  for (;;) {
    uint64_t control[2] = {0, 0};
    MPI_Request request = MPI_REQUEST_NULL;
    MPI_Irecv(control, 2, MPI_UINT64_T, 0, kControlTag, MPI_COMM_WORLD, &request);
    waitGently(request);
    if (control[0] == kOpen) {
      recording.reset();
      activity.reset();
      open_error = nullptr;
      try {
        const size_t i = static_cast<size_t>(control[1]);
        if (i >= s.datasets.size()) throw Error("rank 0 asked for recording " + std::to_string(i + 1));
        recording = openForIntegration(s.datasets[i], s.session);
        activity = integrationMemoryActivity(recording->size(), s.session.resolution_m);
        if (!accumulator) accumulator.emplace(KeyGrid(s.session.resolution_m), s.session.integrator);
      } catch (...) {
        open_error = std::current_exception();
      }
    } else if (control[0] == kCast) {
      const uint64_t frame = control[1];
      std::vector<uint8_t> answer;
      try {
        if (open_error) std::rethrow_exception(open_error);
        if (!recording || frame >= recording->size()) throw Error("rank 0 asked for a frame the recording lacks");
        accumulator->accumulate(*recording, static_cast<size_t>(frame), deltas);
        answer = FrameAnswer::deltas(frame, deltas);
      } catch (...) {
        answer = FrameAnswer::error(frame, std::current_exception());
      }
      if (answer.size() / kAnswerBlock > static_cast<size_t>(INT_MAX)) {
        answer = FrameAnswer::error(frame, std::make_exception_ptr(Error("a frame's deltas over 128 GiB")));
      }
      finishAnswers(kPrefetchPerRank - 1);
      answers.emplace_back(std::move(answer), MPI_REQUEST_NULL);
      std::vector<uint8_t>& bytes = answers.back().first;
      MPI_Isend(bytes.data(), static_cast<int>(bytes.size() / kAnswerBlock), block.get(), 0, kFrameTag,
                MPI_COMM_WORLD, &answers.back().second);
    } else {
      finishAnswers(0);
      recording.reset();
      activity.reset();
      if (control[0] == kDone) return;
    }
  }
}

/// Rank 0's sessions added to the map as soon as every earlier one of the build is, while the other
/// ranks cast the next recording's first frames (SharedFrames::prefetch), instead of all after the
/// last frame: only without registration and re-alignment (which need every session), and when
/// every recording's time is known before integrating and no two are the same (else sortByTime
/// and finishBuild decide, as in build()). The sessions are added in time order as finishBuild
/// adds them, so the map is the same; an error of an add is kept for the end, where build() would
/// meet it, so that a recording that fails to integrate is still the error given.
class AddingAsIntegrated {
 public:
  /// Never throws: anything that goes wrong here leaves the sessions to the end, as build() adds them.
  AddingAsIntegrated(const BuildSettings& s, TemporalMap& map) noexcept : s_(s), map_(map) {
    if (s.registration || s.realign) return;
    try {
      std::vector<std::pair<double, size_t>> times;
      for (size_t i = 0; i < s.datasets.size(); ++i) {
        const std::optional<double> t = pipeline_detail::timeBeforeIntegrating(s, i);
        if (!t) return;
        times.emplace_back(*t, i);
      }
      std::stable_sort(times.begin(), times.end());
      for (size_t k = 1; k < times.size(); ++k) {
        if (times[k].first == times[k - 1].first) return;
      }
      times_.resize(s.datasets.size());
      for (const auto& [t, i] : times) {
        order_.push_back(i);
        times_[i] = t;
      }
      on_ = true;
    } catch (...) {
      order_.clear();
    }
  }

  /// Takes dataset p.index's integrated session: adds it, and those waiting for it, when every
  /// earlier one is added.
  void take(Pending p) {
    if (!on_) {
      rest_.push_back(std::move(p));
      return;
    }
    const size_t index = p.index;
    if (p.time_s != times_.at(index) && !error_) {
      error_ = std::make_exception_ptr(Error(s_.datasets[index].string() + " was recorded at " + formatTime(p.time_s) +
                                             ", not at " + formatTime(times_[index]) +
                                             " as it said when opened: did it change during the build?"));
    }
    waiting_.emplace(index, std::move(p));
    while (next_ < order_.size() && waiting_.count(order_[next_]) != 0) {
      auto it = waiting_.find(order_[next_]);
      if (!error_) {
        try {
          added_.push_back(pipeline_detail::addPending(s_, map_, it->second, std::nullopt, std::nullopt));
        } catch (...) {
          error_ = std::current_exception();
        }
      }
      if (error_) rest_.push_back(std::move(it->second));
      waiting_.erase(it);
      ++next_;
    }
  }

  /// After the last recording: throws what an add threw; else the sessions not added (in build()'s
  /// order, for sortByTime and finishBuild) and those added.
  std::pair<std::vector<Pending>, std::vector<BuiltSession>> finish() {
    if (error_) std::rethrow_exception(error_);
    for (auto& [index, p] : waiting_) rest_.push_back(std::move(p));
    return {std::move(rest_), std::move(added_)};
  }

 private:
  const BuildSettings& s_;
  TemporalMap& map_;
  bool on_ = false;
  std::vector<size_t> order_;  // the datasets in time order
  std::vector<double> times_;  // each dataset's time, known before integrating
  size_t next_ = 0;            // in order_: the first not added
  std::map<size_t, Pending> waiting_;
  std::vector<Pending> rest_;
  std::vector<BuiltSession> added_;
  std::exception_ptr error_;
};

/// serveSharedFrames(), ending the job when anything leaves it (out of memory while an answer is
/// made): rank 0 would otherwise wait for that rank's answers for ever.
void serveSharedFramesOrAbort(const BuildSettings& s) {
  try {
    serveSharedFrames(s);
  } catch (...) {
    std::fprintf(stderr, "chronomap: rank serving frames stopped: %s\n",
                 describeError(std::current_exception()).message.c_str());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
}

}  // namespace

bool mpiBuilt() { return true; }

Ranks::Ranks() {
  if (!launchedByMpirun()) return;
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (initialised) throw Error("MPI was started already: one Ranks per process");
  MPI_Init(nullptr, nullptr);
  started_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Ranks::~Ranks() {
  if (!started_) return;
  // No rank leaves before every rank is done (rank 0 says why a job failed just before this: a rank
  // that exits non-zero earlier may make mpirun end the job before that message is out).
  MPI_Barrier(MPI_COMM_WORLD);
  MPI_Finalize();
}

std::optional<BuildResult> buildOnRanks(const BuildSettings& settings, const Ranks& ranks) {
  BuildSettings s = settings;
  // "All cores" is the cores this rank is bound to (the map does not depend on the thread count).
  if (s.session.integrator.threads == 0) s.session.integrator.threads = processorsAllowed();
  if (ranks.size() == 1) return build(s);
  const bool root = ranks.rank() == 0;
  const size_t n = s.datasets.size();
  if (!root) s.progress = {};  // one rank reports
  Steps steps(ranks);

  // The inputs, checked on every rank (each reads the datasets); rank 0 locks and reads the map.
  std::optional<FileLock> lock;
  std::optional<TemporalMap> map;
  bool created = false;
  nlohmann::json stored;
  ChosenUp up;
  steps.run(0, [&] {
    pipeline_detail::checkInputs(s);
    if (!root) {
      // Every rank reads the recordings with the same up: the map's own (its metadata), or auto's
      // estimate on the first dataset, which every rank finds alike.
      const bool exists = std::filesystem::exists(s.map);
      up = chooseBuildUp(s, !exists, exists ? userMetadataOf(readCmap(s.map)) : nlohmann::json::object());
      return;
    }
    lock.emplace(s.map, FileLock::Missing::LockFolder);  // held to the end, as build() holds it
    map.emplace(openOrCreate(s.map, s.session.resolution_m, s.criterion, created, nullptr, &stored));
    pipeline_detail::refuseClashes(s, *map);
    up = chooseBuildUp(s, created, stored);
  });
  steps.agree();
  s = pipeline_detail::withUp(s, up);

  // Rank 0 integrates the recordings in the given order, the others casting frames with it; the
  // first that fails ends the step, as in build(). Each session is added as soon as it can be
  // (AddingAsIntegrated), while the others cast the next recording's first frames.
  std::optional<AddingAsIntegrated> adding;
  if (root) {
    SharedFrames frames(ranks.size());
    if (n > 0) frames.prefetch(0);
    adding.emplace(s, *map);
    for (size_t i = 0; i < n; ++i) {
      const int key = static_cast<int>(std::min<size_t>(i, INT_MAX - 1));
      const bool integrated = steps.run(key, [&] {
        frames.open(i);
        frames.setNext(i + 1 < n ? std::optional<size_t>(i + 1) : std::nullopt);
        Pending p = pipeline_detail::integrateOne(s, i, &frames);
        s.progress.say("  " + frames.castBy(p.session.stats.frames));
        adding->take(std::move(p));
      });
      if (!integrated) break;
    }
    frames.close();  // the answers still on their way (of frames handed out ahead, or of a failure)
    frames.done();
  } else {
    serveSharedFramesOrAbort(s);
  }
  steps.agree();
  if (!root) {
    steps.agree();  // rank 0's adding and writing
    return std::nullopt;
  }
  BuildResult result;
  steps.run(0, [&] {
    auto [pending, added] = adding->finish();
    pipeline_detail::sortByTime(s, pending);
    result = pipeline_detail::finishBuild(s, *map, created, pending, up, stored, std::move(added));
  });
  steps.agree();
  return result;
}

}  // namespace chronomap
