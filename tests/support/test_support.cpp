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

PointCloud cloudOf(std::initializer_list<Eigen::Vector3f> points) {
  PointCloud c;
  c.points.assign(points.begin(), points.end());
  c.width = static_cast<uint32_t>(c.points.size());
  return c;
}

}  // namespace chronomap::test
