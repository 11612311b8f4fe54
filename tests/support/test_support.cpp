#include "test_support.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>

#include "chronomap/ingest/cloud_io.h"

namespace chronomap::test {

namespace fs = std::filesystem;

fs::path dataDir() {
  if (const char* env = std::getenv("CHRONOMAP_DATA_DIR"); env && *env) return env;
  return CHRONOMAP_DEFAULT_DATA_DIR;
}

bool underCi() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

TempDir::TempDir() {
  std::random_device rd;
  path_ = fs::temp_directory_path() /
          ("chronomap-test-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

CommandResult runCommand(const std::string& command) {
  TempDir tmp;
  const fs::path out = tmp / "out.txt", err = tmp / "err.txt";
  const std::string full = command + " >" + out.string() + " 2>" + err.string() + " </dev/null";
  const int status = std::system(full.c_str());
  CommandResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  auto slurp = [](const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

std::string cli() { return std::string(CHRONOMAP_CLI_PATH); }

std::vector<uint8_t> bytesOf(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const fs::path& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

void writeBytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kUnderSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kUnderSanitizer = true;
#else
constexpr bool kUnderSanitizer = false;
#endif
#else
constexpr bool kUnderSanitizer = false;
#endif

/// The address space this process holds now (/proc/self/statm), in bytes; 0 when unknown.
uint64_t addressSpaceBytes() {
  std::ifstream in("/proc/self/statm");
  uint64_t pages = 0;
  in >> pages;
  return pages * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
}

/// Forks; the child runs `limit`, then `body`, and exits with its code (99 when it threw).
int exitCodeInChild(const std::function<void()>& limit, const std::function<int()>& body) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    limit();
    int code = 99;
    try {
      code = body();
    } catch (...) {
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

int exitCodeUnderFileSizeLimit(uint64_t max_file_bytes, const std::function<int()>& body) {
  return exitCodeInChild(
      [&] {
        std::signal(SIGXFSZ, SIG_IGN);  // EFBIG from write() instead of a signal
        const rlimit limit{static_cast<rlim_t>(max_file_bytes), static_cast<rlim_t>(max_file_bytes)};
        ::setrlimit(RLIMIT_FSIZE, &limit);
      },
      body);
}

int exitCodeUnderMemoryLimit(uint64_t extra_bytes, const std::function<int()>& body) {
  return exitCodeInChild(
      [&] {
        if (kUnderSanitizer) return;
        const rlim_t bytes = static_cast<rlim_t>(addressSpaceBytes() + extra_bytes);
        const rlimit limit{bytes, bytes};
        ::setrlimit(RLIMIT_AS, &limit);
      },
      body);
}

bool memoryLimitsApply() { return !kUnderSanitizer; }

bool underSanitizer() { return kUnderSanitizer; }

fs::path writeWallDataset(const fs::path& dir, const std::string& name, float wall_x) {
  PointCloud cloud;
  for (float y = -0.5f; y <= 0.5f; y += 0.02f) {
    for (float z = -0.5f; z <= 0.5f; z += 0.02f) cloud.points.push_back({wall_x, y, z});
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  const fs::path list = dir / (name + ".txt");
  writePly(dir / (name + ".ply"), cloud);
  std::ofstream(list) << name << ".ply 0 0 0 0 0 0 1\n";
  return list;
}

}  // namespace chronomap::test
