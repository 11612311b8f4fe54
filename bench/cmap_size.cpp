// Where the bytes of a .cmap go: for each map, every block of the file in format version 1 (the
// previous layout: pools and records as they lie in memory), version 2 (field by field, lengths
// exact) and the current version (lengths and colour sums quantised), raw and as stored (zstd),
// the CPU time to encode and to decode each, and the largest error of the hit positions read back.
//
// Usage: cmap_size [--synthetic] [--level N] [FILE.cmap ...]
//   --synthetic: the session maps of integrate_vs_peers' synthetic sequence (30 frames of
//                640x480 within 3 m, fast mode, hit positions on) at 0.05 m and 0.02 m
//   FILE.cmap:   a session or 4D map file of any version (appended sessions folded in)
// The last line is one JSON object with each map's bytes in both versions. With the environment
// variable CMAP_SIZE_DUMP=DIR, each session map's current-version blocks are also written raw to DIR
// (NAME.TAG), for trying other encodings on them.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "chronomap/integrate/integrator.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/sim/box_room.h"

using namespace chronomap;

namespace {

double cpuNow() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// Best CPU seconds of `rounds` calls of fn.
double bestOf(int rounds, const std::function<void()>& fn) {
  double best = 1e300;
  for (int i = 0; i < rounds; ++i) {
    const double t0 = cpuNow();
    fn();
    best = std::min(best, cpuNow() - t0);
  }
  return best;
}

/// Tag, raw and stored bytes of each block of an encoded file (docs/file-format.md).
struct BlockSize {
  std::string tag;
  uint64_t raw = 0, stored = 0;
};
std::vector<BlockSize> blockSizes(const std::vector<uint8_t>& bytes) {
  std::vector<BlockSize> out;
  uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 76, 4);
  size_t pos = 84;
  for (uint32_t i = 0; i < n; ++i) {
    BlockSize b;
    b.tag.assign(reinterpret_cast<const char*>(bytes.data() + pos), 4);
    std::memcpy(&b.raw, bytes.data() + pos + 8, 8);
    std::memcpy(&b.stored, bytes.data() + pos + 16, 8);
    pos += 32 + b.stored;
    out.push_back(b);
  }
  return out;
}

void printBlocks(const char* title, const std::vector<uint8_t>& bytes, size_t records) {
  std::printf("%s: %zu bytes (%.2f MiB), %.2f bytes per record\n", title, bytes.size(),
              static_cast<double>(bytes.size()) / (1 << 20), static_cast<double>(bytes.size()) / std::max<size_t>(1, records));
  std::printf("| block | raw bytes | stored bytes | share | stored bytes per record |\n|---|---:|---:|---:|---:|\n");
  for (const BlockSize& b : blockSizes(bytes)) {
    std::printf("| %s | %llu | %llu | %.1f%% | %.3f |\n", b.tag.c_str(), static_cast<unsigned long long>(b.raw),
                static_cast<unsigned long long>(b.stored), 100.0 * static_cast<double>(b.stored) / static_cast<double>(bytes.size()),
                static_cast<double>(b.stored) / static_cast<double>(std::max<size_t>(1, records)));
  }
}

/// Largest |mean offset written - mean offset read| over the counters, in voxels.
double positionError(const std::vector<VoxelCounters>& a, const std::vector<VoxelCounters>& b) {
  double worst = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    for (int axis = 0; axis < 3; ++axis) worst = std::max(worst, std::abs(a[i].meanOffset(axis) - b[i].meanOffset(axis)));
  }
  return worst;
}

/// Largest relative error of the lengths read back, largest change of P, and how many states changed.
struct LengthError {
  double relative = 0, probability = 0;
  size_t states_changed = 0;
};
LengthError lengthError(const std::vector<VoxelCounters>& a, const std::vector<VoxelCounters>& b) {
  LengthError e;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    if (a[i].length_m > 0.0f) {
      e.relative = std::max(e.relative, std::abs(double{b[i].length_m} / double{a[i].length_m} - 1.0));
    }
    e.probability = std::max(e.probability, std::abs(a[i].probability() - b[i].probability()));
    e.states_changed += a[i].state() != b[i].state();
  }
  return e;
}

nlohmann::json measureSession(const std::string& name, const SessionMap& map, int rounds) {
  std::printf("\n## %s: session map, %zu inner nodes, %zu leaves\n\n", name.c_str(), map.innerCount(), map.leafCount());
  std::vector<uint8_t> v1, v2, exact2;
  const double enc1 = bestOf(rounds, [&] { v1 = encodeSessionMap(map, nlohmann::json::object(), 3, 1); });
  const double enc2 = bestOf(rounds, [&] { v2 = encodeSessionMap(map, nlohmann::json::object()); });
  exact2 = encodeSessionMap(map, nlohmann::json::object(), 3, 2);
  SessionMap back1, back2;
  const double dec1 = bestOf(rounds, [&] { back1 = sessionMapFrom(decodeCmap(v1, "v1"), "v1"); });
  const double dec2 = bestOf(rounds, [&] { back2 = sessionMapFrom(decodeCmap(v2, "v2"), "v2"); });
  printBlocks("version 1", v1, map.leafCount());
  std::printf("\n");
  printBlocks("version 2", exact2, map.leafCount());
  std::printf("\n");
  printBlocks("current version", v2, map.leafCount());
  if (const char* dump = std::getenv("CMAP_SIZE_DUMP")) {
    for (const CmapBlock& b : decodeCmap(v2, "v2").blocks) {
      std::FILE* f = std::fopen((std::string(dump) + "/" + name + "." + b.tag).c_str(), "wb");
      std::fwrite(b.data.data(), 1, b.data.size(), f);
      std::fclose(f);
    }
  }
  const std::vector<VoxelCounters> leaves = map.pools().leaves, leaves_back = back2.pools().leaves;
  const double err = positionError(leaves, leaves_back);
  const LengthError lerr = lengthError(leaves, leaves_back);
  std::printf("\nlargest relative length error %.3g, largest |P change| %.3g, states changed %zu\n", lerr.relative,
              lerr.probability, lerr.states_changed);
  std::printf("\ncurrent / version 1: %.3f; encode %.2f / %.2f ms, decode %.2f / %.2f ms (CPU, best of %d); "
              "round trip equal but positions: %s; largest position error %.5f voxel\n",
              static_cast<double>(v2.size()) / static_cast<double>(v1.size()), 1e3 * enc1, 1e3 * enc2, 1e3 * dec1,
              1e3 * dec2, rounds, back2 == asStored(map) ? "yes" : "NO", err);
  return {{"bytes_v1", v1.size()}, {"bytes_v2", exact2.size()}, {"bytes_now", v2.size()}, {"encode_ms_v1", 1e3 * enc1},
          {"encode_ms_now", 1e3 * enc2}, {"decode_ms_v1", 1e3 * dec1}, {"decode_ms_now", 1e3 * dec2},
          {"position_error_voxels", err}, {"length_relative_error", lerr.relative},
          {"probability_error", lerr.probability}, {"states_changed", lerr.states_changed}};
}

std::vector<VoxelCounters> entryValues(const TemporalMap& map) {
  std::vector<VoxelCounters> v;
  map.forEachList([&](const VoxelKey&, int, std::span<const TemporalMap::Entry> entries) {
    for (const auto& e : entries) v.push_back(e.value);
  });
  return v;
}

nlohmann::json measureTemporal(const std::string& name, const TemporalMap& map, int rounds) {
  const TemporalCounts counts = map.counts();
  const size_t records = entryValues(map).size();
  std::printf("\n## %s: 4D map, %zu sessions, %zu entries\n\n", name.c_str(), map.sessionCount(), records);
  (void)counts;
  std::vector<uint8_t> v1, v2;
  const double enc1 = bestOf(rounds, [&] { v1 = encodeTemporalMap(map, nlohmann::json::object(), 1); });
  const double enc2 = bestOf(rounds, [&] { v2 = encodeTemporalMap(map, nlohmann::json::object()); });
  const std::vector<uint8_t> exact2 = encodeTemporalMap(map, nlohmann::json::object(), 2);
  TemporalMap back1, back2;
  const double dec1 = bestOf(rounds, [&] { back1 = temporalMapFrom(decodeCmap(v1, "v1"), "v1"); });
  const double dec2 = bestOf(rounds, [&] { back2 = temporalMapFrom(decodeCmap(v2, "v2"), "v2"); });
  printBlocks("version 1", v1, records);
  std::printf("\n");
  printBlocks("version 2", exact2, records);
  std::printf("\n");
  printBlocks("current version", v2, records);
  const double err = positionError(entryValues(back1), entryValues(back2));
  const LengthError lerr = lengthError(entryValues(back1), entryValues(back2));
  std::printf("\nlargest relative length error %.3g, largest |P change| %.3g, states changed %zu\n", lerr.relative,
              lerr.probability, lerr.states_changed);
  std::printf("\ncurrent / version 1: %.3f; encode %.0f / %.0f ms, decode %.0f / %.0f ms (CPU, best of %d); "
              "largest position error %.5f voxel; memory %.1f MiB\n",
              static_cast<double>(v2.size()) / static_cast<double>(v1.size()), 1e3 * enc1, 1e3 * enc2, 1e3 * dec1,
              1e3 * dec2, rounds, err, static_cast<double>(map.memoryBytes()) / (1 << 20));
  return {{"bytes_v1", v1.size()}, {"bytes_v2", exact2.size()}, {"bytes_now", v2.size()}, {"encode_ms_v1", 1e3 * enc1},
          {"encode_ms_now", 1e3 * enc2}, {"decode_ms_v1", 1e3 * dec1}, {"decode_ms_now", 1e3 * dec2},
          {"position_error_voxels", err}, {"length_relative_error", lerr.relative},
          {"probability_error", lerr.probability}, {"states_changed", lerr.states_changed},
          {"memory_bytes", map.memoryBytes()}};
}

}  // namespace

int main(int argc, char** argv) {
  nlohmann::json summary = nlohmann::json::object();
  int rounds = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--rounds" && i + 1 < argc) {
      rounds = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--synthetic") {
      // As integrate_vs_peers prepares them: points within 3 m only.
      std::vector<Frame> frames = benchmarkSequence(30);
      for (Frame& f : frames) {
        PointCloud kept;
        for (size_t k = 0; k < f.cloud.size(); ++k) {
          const Eigen::Vector3f& p = f.cloud.points[k];
          if (!p.allFinite() || p.norm() > 3.0f || p.norm() == 0.0f) continue;
          kept.points.push_back(p);
          if (f.cloud.hasColours()) kept.colours.push_back(f.cloud.colours[k]);
        }
        kept.width = static_cast<uint32_t>(kept.points.size());
        f.cloud = std::move(kept);
      }
      for (double res : {0.05, 0.02}) {
        IntegratorSettings s;
        s.max_range_m = 3.0;
        s.fast = true;
        s.hit_positions = true;
        SessionMap map(res);
        integrate(FrameVector(frames), map, s);
        const std::string name = res == 0.05 ? "synthetic_5cm" : "synthetic_2cm";
        summary[name] = measureSession(name, map, rounds);
      }
    } else if (arg.rfind("--", 0) == 0) {
      std::fprintf(stderr, "usage: cmap_size [--rounds N] [--synthetic] [FILE.cmap ...]\n");
      return 2;
    } else {
      const CmapFile file = readCmap(arg);
      if (file.header.kind == MapKind::Session) {
        summary[arg] = measureSession(arg, sessionMapFrom(file, arg), rounds);
      } else if (file.header.kind == MapKind::Temporal) {
        summary[arg] = measureTemporal(arg, temporalMapFrom(file, arg), rounds);
      }
      summary[arg]["file_bytes"] = file.file_bytes;
      summary[arg]["file_version"] = file.header.version;
    }
  }
  std::printf("%s\n", summary.dump().c_str());
  return 0;
}
