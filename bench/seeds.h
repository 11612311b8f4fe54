#pragma once
// Shared by the evaluation benchmarks: one figure over many simulated buildings. With
// `--seeds A-B` a benchmark simulates its building once per seed (and with `--sensor NAME`,
// through that sensor model), runs itself on each simulation as if given it with its own flag
// (--sim DIR, --office DIR, --weeks DIR), and prints for every number of the runs' last JSON
// line its mean, its spread (min, max) and its value per seed; then one JSON object of them.
// Constants are chosen on training seeds (1-5) and reported on test seeds (6-15): the seeds
// say which is which, never the benchmark.

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "chronomap/sim/building.h"
#include "chronomap/sim/render.h"

namespace chronomap::bench {

/// "A-B" or "A": the seeds from A to B. Exits with status 2 for anything else.
inline std::vector<uint64_t> parseSeeds(const std::string& text) {
  const auto dash = text.find('-');
  char* end = nullptr;
  const unsigned long long a = std::strtoull(text.c_str(), &end, 10);
  unsigned long long b = a;
  bool ok = end != text.c_str() && (dash == std::string::npos ? *end == '\0' : end == text.c_str() + dash);
  if (ok && dash != std::string::npos) {
    const char* rest = text.c_str() + dash + 1;
    b = std::strtoull(rest, &end, 10);
    ok = end != rest && *end == '\0';
  }
  if (!ok || b < a || b - a > 99) {
    std::fprintf(stderr, "--seeds takes A-B (at most 100 seeds), not '%s'\n", text.c_str());
    std::exit(2);
  }
  std::vector<uint64_t> seeds;
  for (unsigned long long s = a; s <= b; ++s) seeds.push_back(s);
  return seeds;
}

/// Mean, min, max and the values of every number (and of every number one object deep, as
/// "key.sub") in `runs`' JSON objects; a key missing from a run is left out of that run.
inline nlohmann::json spreadOf(const std::vector<nlohmann::json>& runs) {
  std::map<std::string, std::vector<double>> values;
  for (const nlohmann::json& run : runs) {
    for (auto it = run.begin(); it != run.end(); ++it) {
      if (it->is_number()) values[it.key()].push_back(it->get<double>());
      if (it->is_object()) {
        for (auto sub = it->begin(); sub != it->end(); ++sub) {
          if (sub->is_number()) values[it.key() + "." + sub.key()].push_back(sub->get<double>());
        }
      }
    }
  }
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [key, v] : values) {
    double sum = 0.0, lo = v.front(), hi = v.front();
    for (double x : v) {
      sum += x;
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
    out[key] = {{"mean", sum / static_cast<double>(v.size())}, {"min", lo}, {"max", hi}, {"values", v}};
  }
  return out;
}

/// The last line of `text` that parses as a JSON object; an empty object when none does.
inline nlohmann::json lastJsonLine(const std::string& text) {
  size_t end = text.size();
  while (end > 0) {
    const size_t start = text.rfind('\n', end - 1);
    const size_t from = start == std::string::npos ? 0 : start + 1;
    const std::string line = text.substr(from, end - from);
    if (!line.empty() && line.front() == '{') {
      const nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
      if (j.is_object()) return j;
    }
    if (start == std::string::npos) break;
    end = start;
  }
  return nlohmann::json::object();
}

/// With --seeds in argv: simulates `base` once per seed (with --sensor's model when given), runs
/// this program on each as `sim_flag DIR` plus the other arguments, prints the spread of the
/// runs' figures and returns the exit status (non-zero when a run failed). Without --seeds:
/// returns -1 and the caller goes on as before.
inline int runOverSeeds(int argc, char** argv, const std::string& sim_flag, SimulationSettings base) {
  std::vector<uint64_t> seeds;
  std::string sensor, args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seeds" && i + 1 < argc) {
      seeds = parseSeeds(argv[++i]);
    } else if (a == "--sensor" && i + 1 < argc) {
      sensor = argv[++i];
    } else {
      args += " '" + a + "'";
    }
  }
  if (seeds.empty()) return -1;
  if (!sensor.empty()) {
    try {
      parseSensorKind(sensor);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 2;
    }
  }
  namespace fs = std::filesystem;
  const std::string program = fs::canonical("/proc/self/exe").string();
  const fs::path tmp = fs::temp_directory_path() / ("seeds_" + std::to_string(::getpid()));
  std::vector<nlohmann::json> runs;
  int status = 0;
  for (uint64_t seed : seeds) {
    SimulationSettings s = base;
    s.seed = seed;
    if (!sensor.empty()) s.sensor = sensor;
    const fs::path dir = tmp / ("seed_" + std::to_string(seed));
    std::fprintf(stderr, "seed %llu: simulating %s%s into %s\n", static_cast<unsigned long long>(seed),
                 s.preset.c_str(), sensor.empty() ? "" : (" with the " + sensor + " sensor").c_str(), dir.c_str());
    chronomap::simulate(s, dir, {});
    const std::string command = "'" + program + "' " + sim_flag + " '" + dir.string() + "'" + args;
    std::string out;
    if (FILE* pipe = ::popen(command.c_str(), "r")) {
      char buffer[4096];
      for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) {
        out.append(buffer, n);
        std::fwrite(buffer, 1, n, stdout);
      }
      const int rc = ::pclose(pipe);
      if (rc != 0) status = 1;
    } else {
      status = 1;
    }
    fs::remove_all(dir);
    nlohmann::json figures = lastJsonLine(out);
    figures["seed"] = seed;
    runs.push_back(std::move(figures));
    std::fflush(stdout);
  }
  fs::remove_all(tmp);
  const nlohmann::json spread = spreadOf(runs);
  std::printf("\n== seeds %llu-%llu%s: mean [min, max] over %zu runs ==\n",
              static_cast<unsigned long long>(seeds.front()), static_cast<unsigned long long>(seeds.back()),
              sensor.empty() ? "" : (", sensor " + sensor).c_str(), runs.size());
  for (auto it = spread.begin(); it != spread.end(); ++it) {
    if (it.key() == "seed") continue;
    std::printf("%-48s %10.4g [%.4g, %.4g]\n", it.key().c_str(), (*it)["mean"].get<double>(),
                (*it)["min"].get<double>(), (*it)["max"].get<double>());
  }
  nlohmann::json summary = {{"seeds", seeds}, {"sensor", sensor.empty() ? "ideal" : sensor}, {"figures", spread}};
  std::printf("%s\n", summary.dump().c_str());
  return status;
}

}  // namespace chronomap::bench
