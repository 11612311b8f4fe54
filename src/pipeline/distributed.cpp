// pipeline/distributed.h with MPI: the only file of chronomap that calls MPI.

#include "chronomap/pipeline/distributed.h"

#include <mpi.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "build_steps.h"
#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"

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

constexpr int kTag = 1;
constexpr size_t kChunkBytes = size_t{1} << 30;  // MPI counts are ints

void sendBytes(const std::vector<uint8_t>& bytes, int to) {
  const uint64_t n = bytes.size();
  MPI_Request request = MPI_REQUEST_NULL;
  MPI_Isend(&n, 1, MPI_UINT64_T, to, kTag, MPI_COMM_WORLD, &request);
  waitGently(request);
  for (size_t at = 0; at < bytes.size(); at += kChunkBytes) {
    const int count = static_cast<int>(std::min(kChunkBytes, bytes.size() - at));
    MPI_Isend(bytes.data() + at, count, MPI_BYTE, to, kTag, MPI_COMM_WORLD, &request);
    waitGently(request);
  }
}

std::vector<uint8_t> receiveBytes(int from) {
  uint64_t n = 0;
  MPI_Request request = MPI_REQUEST_NULL;
  MPI_Irecv(&n, 1, MPI_UINT64_T, from, kTag, MPI_COMM_WORLD, &request);
  waitGently(request);
  std::vector<uint8_t> bytes(n);
  for (size_t at = 0; at < bytes.size(); at += kChunkBytes) {
    const int count = static_cast<int>(std::min(kChunkBytes, bytes.size() - at));
    MPI_Irecv(bytes.data() + at, count, MPI_BYTE, from, kTag, MPI_COMM_WORLD, &request);
    waitGently(request);
  }
  return bytes;
}

/// A session integrated on another rank, as it travels: a session map file in format version 1,
/// whose counters are stored as they are in memory (versions 2 and 3 quantise them), with
/// the rest of the session in its metadata (JSON writes doubles so that they read back exactly).
std::vector<uint8_t> encodePending(const Pending& p) {
  const IntegratedSession& s = p.session;
  nlohmann::json positions = nlohmann::json::array();
  for (const auto& q : s.sensor_positions) positions.push_back({q.x(), q.y(), q.z()});
  nlohmann::json poses = nlohmann::json::array();
  for (const auto& T : s.poses) {
    const Eigen::Matrix<double, 3, 4> m = T.matrix().topRows<3>();
    poses.push_back(std::vector<double>(m.data(), m.data() + 12));  // column-major
  }
  const IntegrationStats& st = s.stats;
  const nlohmann::json meta = {
      {"index", p.index},
      {"time_s", p.time_s},
      {"format", s.format},
      {"frames_dropped", s.frames_dropped},
      {"dropped_reasons", s.dropped_reasons},
      {"recorded_at", s.recorded_at ? nlohmann::json(*s.recorded_at) : nlohmann::json()},
      {"stats",
       {st.frames, st.points, st.points_invalid, st.points_out_of_range, st.points_outside_map, st.rays,
        st.voxel_updates, st.seconds, st.points_depth_edges}},
      {"sensor_positions", std::move(positions)},
      {"poses", std::move(poses)},
      {"warnings", s.warnings}};
  return encodeSessionMap(s.map, meta, /*zstd_level=*/1, /*version=*/1);
}

Pending decodePending(const std::vector<uint8_t>& bytes, size_t index, int from) {
  const std::string source = "the session map of dataset " + std::to_string(index + 1) + " from rank " +
                             std::to_string(from);
  const CmapFile file = decodeCmap(bytes, source);
  const nlohmann::json meta = metadataOf(file);
  if (meta.value("index", size_t{0}) != index) throw Error(source + ": another dataset's session arrived");
  const nlohmann::json& st = meta.at("stats");
  const IntegrationStats stats{st.at(0), st.at(1), st.at(2), st.at(3), st.at(4),
                               st.at(5), st.at(6), st.at(7), st.size() > 8 ? st.at(8).get<uint64_t>() : uint64_t{0}};
  std::optional<double> recorded_at;
  if (!meta.at("recorded_at").is_null()) recorded_at = meta.at("recorded_at").get<double>();
  std::vector<Eigen::Vector3d> positions;
  for (const auto& q : meta.at("sensor_positions")) {
    positions.emplace_back(q.at(0).get<double>(), q.at(1).get<double>(), q.at(2).get<double>());
  }
  std::vector<Eigen::Isometry3d> poses;
  for (const auto& q : meta.at("poses")) {
    const std::vector<double> v = q.get<std::vector<double>>();
    if (v.size() != 12) throw Error(source + ": a pose of " + std::to_string(v.size()) + " numbers, not 12");
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.matrix().topRows<3>() = Eigen::Map<const Eigen::Matrix<double, 3, 4>>(v.data());
    poses.push_back(T);
  }
  return {index, meta.at("time_s").get<double>(),
          IntegratedSession{sessionMapFrom(file, source), stats, recorded_at, meta.at("format").get<std::string>(),
                            meta.at("frames_dropped").get<size_t>(), std::move(positions),
                            meta.at("dropped_reasons").get<std::string>(), std::move(poses), ChosenUp{},
                            meta.value("warnings", std::vector<std::string>{})}};
}

/// Bytes a recording holds on disk (a folder's files, or the file): a measure of its work.
uintmax_t recordingBytes(const std::filesystem::path& p) {
  std::error_code ec;
  if (!std::filesystem::is_directory(p, ec)) {
    const uintmax_t size = std::filesystem::file_size(p, ec);
    return ec ? 0 : size;
  }
  uintmax_t total = 0;
  std::filesystem::recursive_directory_iterator it(p, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    std::error_code size_ec;
    const uintmax_t size = it->is_regular_file(size_ec) ? it->file_size(size_ec) : 0;
    if (!size_ec) total += size;
  }
  return total;
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

  // The recordings shared out by size (shareOutRecordings), the same on every rank.
  std::vector<uintmax_t> sizes(n);
  for (size_t i = 0; i < n; ++i) sizes[i] = recordingBytes(s.datasets[i]);
  const std::vector<int> owner = shareOutRecordings(sizes, ranks.size());
  std::vector<Pending> mine;
  for (size_t i = 0; i < n; ++i) {
    if (owner[i] != ranks.rank()) continue;
    const int key = static_cast<int>(std::min<size_t>(i, INT_MAX - 1));
    if (!steps.run(key, [&] { mine.push_back(pipeline_detail::integrateOne(s, i)); })) break;
  }
  steps.agree();

  // Encoded before anything is sent, so that a failure here is agreed on too.
  std::vector<std::vector<uint8_t>> encoded;
  if (!root) {
    steps.run(0, [&] {
      for (const Pending& p : mine) encoded.push_back(encodePending(p));
    });
    mine.clear();
  }
  steps.agree();
  if (!root) {
    for (const auto& bytes : encoded) sendBytes(bytes, 0);
    steps.agree();  // rank 0's adding and writing
    return std::nullopt;
  }
  // Every byte received before anything can fail here, so that no rank waits on a send.
  std::vector<std::vector<uint8_t>> received(n);
  for (size_t i = 0; i < n; ++i) {
    if (owner[i] != 0) received[i] = receiveBytes(owner[i]);
  }
  BuildResult result;
  steps.run(0, [&] {
    std::vector<Pending> pending;
    size_t own = 0;
    for (size_t i = 0; i < n; ++i) {
      if (owner[i] == 0) {
        pending.push_back(std::move(mine[own++]));
        continue;
      }
      const int from = owner[i];
      std::ostringstream step;
      step << "[" << i + 1 << "/" << n << "] " << s.datasets[i].string() << " (integrated on rank " << from << ")";
      s.progress.say(step.str());
      pending.push_back(decodePending(received[i], i, from));
      std::vector<uint8_t>().swap(received[i]);
    }
    pipeline_detail::sortByTime(s, pending);
    result = pipeline_detail::finishBuild(s, *map, created, pending, up, stored);
  });
  steps.agree();
  return result;
}

}  // namespace chronomap
