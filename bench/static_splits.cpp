// Static real recordings split into two sessions: a control for the change rules. Nothing
// changed in these recordings, so every object `findChanges` reports is false (issue 44, point 3).
//
// Recordings (../shared/data):
//   3dmatch   the five frames of a study room (0, 1, 2, 116, 422) with their poses: every split
//             into 3 + 2 and 2 + 3 frames, either half the earlier session (20 splits);
//   grabber   the PCL grabber sequence, three Kinect clouds from an unmoved camera: every split
//             into 1 + 2 and 2 + 1 clouds (6 splits).
// (nyu-rgbd is left out: its poses are approximate, 10-20 cm, so it is no control for the rules;
// mosd-a and human_dataset are not static.)
//
// Every split is built as `chronomap build` does by default (exact rays at 0.05 m, no
// registration) and, with --registered, also as the README's recommended pipeline does (`build
// --fast --register --register-drift 20 --register-planar --register-points`, or the
// registration CHRONOMAP_BENCH_REGISTER names, as bench_sim.h reads it), and diffed with
// the recommended settings (findChanges' defaults), then with each rule's radius one voxel
// smaller and one larger: the neighbourhood rule, the kept-surface rule, the dark-surface rule.
//
// Usage: static_splits [--data DIR] [--registered] [--only 3dmatch|grabber] [--shift-plane R] [--json]
// (--shift-plane R: the shift test's plane ratio, DiffSettings::shift_plane_ratio, in every
// setting instead of the recommended one.)
// Prints a table per recording and pipeline, and the worst split under each setting; with
// --json one JSON line at the end. The target: at most one false object in every split, under
// every setting.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "chronomap/align/register.h"
#include "chronomap/analysis/change_preset.h"
#include "chronomap/analysis/changes.h"
#include "chronomap/core/frame.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/integrate/integrator.h"
#include "chronomap/pipeline/session.h"
#include "chronomap/temporal/temporal_map.h"

#include "bench_sim.h"

using namespace chronomap;
namespace fs = std::filesystem;

namespace {

constexpr double kResolution_m = 0.05;

/// One setting of the rules: a name and how it changes the recommended settings.
struct Variant {
  std::string name;
  std::function<void(ChangeSettings&)> apply;
};

double g_shift_plane = -1.0;  // --shift-plane; < 0: the recommended

std::vector<Variant> variants() {
  const ChangeSettings r = recommendedChangeSettings();
  std::vector<Variant> v = {{"default", [](ChangeSettings&) {}}};
  auto radius = [&](const char* name, int DiffSettings::*field) {
    const int at = r.diff.*field;
    for (int d : {-1, +1}) {
      std::string label(name);
      label.append(" ").append(std::to_string(at + d));
      v.push_back({label, [field, at, d](ChangeSettings& s) {
                     s.diff.*field = at + d;
                   }});
    }
  };
  radius("neighbourhood", &DiffSettings::neighbourhood_voxels);
  radius("kept-surface", &DiffSettings::kept_surface_radius_voxels);
  radius("dark-surface", &DiffSettings::dark_surface_radius_voxels);
  return v;
}

/// A split: the frames of the earlier session and of the later one.
struct Split {
  std::vector<size_t> a, b;
};

/// Every split of `n` frames into two sessions of `small` and n - small frames, for each
/// `small` in `sizes`, either half first.
std::vector<Split> splitsOf(size_t n, std::vector<size_t> sizes) {
  std::vector<Split> out;
  for (uint32_t mask = 1; mask + 1 < (1u << n); ++mask) {
    Split s;
    for (size_t i = 0; i < n; ++i) ((mask >> i) & 1u ? s.a : s.b).push_back(i);
    if (std::find(sizes.begin(), sizes.end(), s.a.size()) != sizes.end()) out.push_back(s);
  }
  return out;
}

/// How one split's two sessions are made: by frame indices.
using SessionMaker = std::function<std::vector<SessionMap>(const Split&, bool registered)>;

/// The 3DMatch room: each session a folder of links to its frames, read as `build` reads it.
SessionMaker threeDMatch(const fs::path& root, const fs::path& tmp, const std::vector<int>& frames) {
  return [root, tmp, frames](const Split& split, bool registered) {
    std::vector<fs::path> paths;
    for (const auto* half : {&split.a, &split.b}) {
      const fs::path dir = tmp / ("s" + std::to_string(paths.size()));
      fs::remove_all(dir);
      fs::create_directories(dir / "seq");
      fs::create_symlink(root / "camera-intrinsics.txt", dir / "camera-intrinsics.txt");
      for (size_t i : *half) {
        char stem[32];
        std::snprintf(stem, sizeof stem, "frame-%06d", frames[i]);
        for (const char* part : {".color.png", ".depth.png", ".pose.txt"}) {
          fs::create_symlink(root / "seq-01" / (stem + std::string(part)), dir / "seq" / (stem + std::string(part)));
        }
      }
      paths.push_back(dir / "seq");
    }
    SessionSettings settings;
    settings.resolution_m = kResolution_m;
    settings.integrator.fast = registered;  // the README's pipeline integrates in fast mode
    std::vector<SessionMap> maps;
    std::vector<std::vector<Eigen::Vector3d>> positions;
    for (const fs::path& p : paths) {
      IntegratedSession s = integrateDataset(p, settings);
      maps.push_back(std::move(s.map));
      positions.push_back(std::move(s.sensor_positions));
    }
    if (registered) {
      // The README's registration, or the one CHRONOMAP_BENCH_REGISTER names (bench_sim.h).
      const char* env = std::getenv("CHRONOMAP_BENCH_REGISTER");
      registerDatasets(maps, paths, positions, settings,
                       env && *env ? bench::benchRegistration() : recommendedRegistration());
    }
    return maps;
  };
}

/// The grabber sequence: clouds from an unmoved camera (identity pose), as `integrate` reads a
/// PCD. Registration has nothing to correct and is not run.
SessionMaker grabber(const std::vector<fs::path>& files) {
  return [files](const Split& split, bool registered) {
    std::vector<SessionMap> maps;
    for (const auto* half : {&split.a, &split.b}) {
      std::vector<Frame> frames;
      for (size_t i : *half) frames.push_back(Frame{readCloud(files[i]), Eigen::Isometry3d::Identity(), 0, files[i]});
      SessionMap map(kResolution_m);
      IntegratorSettings s;
      s.fast = registered;
      integrate(FrameVector(std::move(frames)), map, s);
      maps.push_back(std::move(map));
    }
    return maps;
  };
}

std::string names(const std::vector<size_t>& idx, const std::vector<std::string>& labels) {
  std::string s;
  for (size_t i : idx) {
    if (!s.empty()) s.push_back(',');
    s.append(labels[i]);
  }
  return s;
}

/// Every split under every variant: prints the table, returns {variant: [objects per split]}.
nlohmann::json evaluate(const std::string& title, const std::vector<std::string>& labels,
                        const std::vector<Split>& splits, const SessionMaker& make, bool registered) {
  const std::vector<Variant> vs = variants();
  std::printf("\n== %s, %s: %zu splits; false objects (vertex-connected, >= %llu voxels) ==\n", title.c_str(),
              registered ? "registered (README pipeline)" : "build's defaults", splits.size(),
              static_cast<unsigned long long>(kRecommendedMinObjectVoxels));
  std::printf("%-14s %-14s", "A (earlier)", "B");
  for (const Variant& v : vs) std::printf(" %15s", v.name.c_str());
  std::printf("\n");
  nlohmann::json per_variant = nlohmann::json::object();
  for (const Variant& v : vs) per_variant[v.name] = nlohmann::json::array();
  for (const Split& split : splits) {
    const std::vector<SessionMap> maps = make(split, registered);
    TemporalMap map(kResolution_m);
    map.add(1000, maps[0]);
    map.add(2000, maps[1]);
    std::printf("%-14s %-14s", names(split.a, labels).c_str(), names(split.b, labels).c_str());
    for (const Variant& v : vs) {
      ChangeSettings s = recommendedChangeSettings();
      if (g_shift_plane >= 0.0) s.diff.shift_plane_ratio = g_shift_plane;
      v.apply(s);
      const Changes c = findChanges(map, 1000, 2000, s);
      std::string cell = std::to_string(c.objects.size());
      if (!c.objects.empty()) {
        cell += " (";
        for (size_t k = 0; k < c.objects.size() && k < 2; ++k) {
          if (k) cell.push_back(',');
          cell.append(std::to_string(c.objects[k].voxels));
          cell.push_back(toString(c.objects[k].kind)[0]);
        }
        cell += c.objects.size() > 2 ? ",..)" : ")";
      }
      std::printf(" %15s", cell.c_str());
      per_variant[v.name].push_back(c.objects.size());
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  std::printf("%-29s", "worst split / splits <= 1");
  for (const Variant& v : vs) {
    size_t worst = 0, ok = 0;
    for (const auto& n : per_variant[v.name]) {
      worst = std::max(worst, n.get<size_t>());
      ok += n.get<size_t>() <= 1;
    }
    char cell[32];
    std::snprintf(cell, sizeof cell, "%zu / %zu of %zu", worst, ok, splits.size());
    std::printf(" %15s", cell);
  }
  std::printf("\n");
  return per_variant;
}

}  // namespace

int main(int argc, char** argv) {
  fs::path data = CHRONOMAP_DEFAULT_DATA_DIR;
  bool registered = false, json = false;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--data") && i + 1 < argc) {
      data = argv[++i];
    } else if (!std::strcmp(argv[i], "--registered")) {
      registered = true;
    } else if (!std::strcmp(argv[i], "--only") && i + 1 < argc) {
      only = argv[++i];
    } else if (!std::strcmp(argv[i], "--json")) {
      json = true;
    } else if (!std::strcmp(argv[i], "--shift-plane") && i + 1 < argc) {
      g_shift_plane = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: static_splits [--data DIR] [--registered] [--only 3dmatch|grabber] [--shift-plane R] [--json]\n");
      return 2;
    }
  }
  const auto start = std::chrono::steady_clock::now();
  nlohmann::json out = nlohmann::json::object();
  const fs::path tmp = fs::temp_directory_path() / ("static_splits_" + std::to_string(::getpid()));
  try {
    if (only.empty() || only == "3dmatch") {
      const fs::path root = data / "3dmatch" / "3dmatch";
      const std::vector<int> frames = {0, 1, 2, 116, 422};
      const std::vector<std::string> labels = {"0", "1", "2", "116", "422"};
      const std::vector<Split> splits = splitsOf(frames.size(), {2, 3});
      for (bool reg : registered ? std::vector<bool>{false, true} : std::vector<bool>{false}) {
        out[std::string("3dmatch") + (reg ? "_registered" : "")] =
            evaluate("3dmatch study room", labels, splits, threeDMatch(root, tmp, frames), reg);
      }
    }
    if (only.empty() || only == "grabber") {
      std::vector<fs::path> files;
      for (const auto& e : fs::directory_iterator(data / "pcl-kinect" / "grabber_sequences" / "pcd")) {
        if (e.path().extension() == ".pcd") files.push_back(e.path());
      }
      std::sort(files.begin(), files.end());
      const std::vector<std::string> labels = {"0", "1", "2"};
      out["grabber"] = evaluate("PCL grabber sequence", labels, splitsOf(files.size(), {1, 2}), grabber(files), false);
    }
  } catch (const std::exception& e) {
    fs::remove_all(tmp);
    std::fprintf(stderr, "static_splits: %s\n", e.what());
    return 1;
  }
  fs::remove_all(tmp);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("\n%.1f s\n", s);
  if (json) std::printf("%s\n", out.dump().c_str());
  return 0;
}
