#include "test_support.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

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

SessionMap randomSessionMap(uint64_t seed, int side, double occupied, double resolution_m) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::mt19937 position(static_cast<uint32_t>(seed * 7 + 1));  // its own stream: the rest stays as it was
  SessionMap m(resolution_m);
  for (int z = 0; z < side; ++z) {
    for (int y = 0; y < side; ++y) {
      for (int x = 0; x < side; ++x) {
        if (u(rng) > 0.9) continue;
        VoxelCounters c;
        c.length_m = 0.125f;
        if (u(rng) < occupied) {
          c.hits = 2;
          c.red = 2 * static_cast<uint32_t>(rng() % 256);
          for (float& o : c.offset) o = 2.0f * (static_cast<float>(position() % 101) / 100.0f - 0.5f);
        }
        m.add(VoxelKey{static_cast<uint16_t>(kKeyOrigin + x), static_cast<uint16_t>(kKeyOrigin + y),
                       static_cast<uint16_t>(kKeyOrigin + z)},
              c);
      }
    }
  }
  m.compressFree();
  return m;
}

PointCloud cloudOf(std::initializer_list<Eigen::Vector3f> points) {
  PointCloud c;
  c.points.assign(points.begin(), points.end());
  c.width = static_cast<uint32_t>(c.points.size());
  return c;
}

}  // namespace chronomap::test
