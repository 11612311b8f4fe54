// chronomap clean: a recording's static map as points (the dynamic-map benchmark's output).

#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "chronomap/core/file.h"
#include "chronomap/pipeline/clean.h"
#include "commands.h"
#include "progress.h"

namespace chronomap::cli {

namespace {

struct CleanOptions {
  std::string input;
  std::string output;
  std::string format = "auto";
  CleanSettings settings;
  bool exact = false;
  bool json = false;
};

void printClean(const CleanOptions& o, const CleanResult& r) {
  const StaticPointResult& p = r.points;
  const uint64_t kept = p.points_in - p.points_invalid - p.points_dynamic;
  if (o.json) {
    std::cout << nlohmann::json{{"input", o.input},
                                {"output", o.output},
                                {"format", r.format},
                                {"frames", p.frames},
                                {"points_in", p.points_in},
                                {"points_kept", kept},
                                {"points_dynamic", p.points_dynamic},
                                {"points_invalid", p.points_invalid},
                                {"points_unjudged", p.points_unjudged},
                                {"voxels_occupied", p.voxels_occupied},
                                {"voxels_dynamic", p.voxels_dynamic},
                                {"seconds", p.seconds}}
                     .dump()
              << "\n";
    return;
  }
  std::cout << "cleaned " << p.frames << " frame(s) of " << o.input << " (" << r.format << ") in " << std::fixed
            << std::setprecision(1) << p.seconds << " s\n"
            << "  kept " << kept << " of " << p.points_in << " points (" << p.points_dynamic << " dynamic, "
            << p.points_invalid << " invalid dropped; " << p.points_unjudged << " beyond --max-range kept unjudged)\n"
            << "  " << p.voxels_dynamic << " of " << p.voxels_occupied << " occupied voxels judged dynamic\n"
            << "  static map: " << o.output << "\n";
}

int runClean(CleanOptions& o) {
  requireExtension(o.output, ".pcd", "static map (-o)");
  checkOutputs({{o.output, "-o"}}, {o.input});
  o.settings.dataset.format = parseRecordingFormat(o.format);
  o.settings.points.fast = !o.exact;
  const CleanResult r = cleanRecording(o.input, o.output, o.settings, terminalProgress(o.json));
  printClean(o, r);
  return 0;
}

}  // namespace

Command addClean(CLI::App& root) {
  auto o = std::make_shared<CleanOptions>();
  CLI::App* app = root.add_subcommand(
      "clean",
      "Write a recording's static map as points: every frame's points (world frame) kept where the voxel's "
      "history says something was there whenever it was seen, dropped where rays crossed the voxel in frames "
      "in which nothing was there (a person walking by). Reads any recording (--format), such as the dynamic-map "
      "benchmark's folders (pcd/*.pcd, the sensor pose in each file's VIEWPOINT). Writes a binary PCD (x y z); "
      "bench/dynamic_eval scores it against a labelled gt_cloud.pcd (docs/benchmarks.md).");
  StaticPointSettings& s = o->settings.points;
  app->add_option("recording", o->input, "recording folder or file")->required();
  app->add_option("-o,--output", o->output, "static map to write (.pcd)")->required();
  app->add_option("--format", o->format, "the recording's format (auto detects; integrate --list-formats)")
      ->capture_default_str();
  app->add_option("--resolution", s.resolution_m, "voxel edge in metres")->check(numberIn(0.001, 10))->capture_default_str();
  app->add_option("--max-range", s.max_range_m, "points farther from their sensor are kept unjudged (metres)")
      ->check(numberIn(0.01, 1e4))
      ->capture_default_str();
  app->add_option("--free-length", s.free_length_voxels,
                  "a frame sees a voxel free when its rays cross it for this many voxel lengths and none of its points lies in it")
      ->check(numberIn(0, 1e6))
      ->capture_default_str();
  app->add_option("--free-margin", s.free_margin_m, "... counting each ray free only up to this many metres ...")
      ->check(numberIn(0, 1e3))
      ->capture_default_str();
  app->add_option("--free-margin-growth", s.free_margin_per_m2,
                  "... plus this times its range squared before its point (depth noise; 0 for lidar)")
      ->check(numberIn(0, 10))
      ->capture_default_str();
  app->add_option("--min-free-frames", s.min_free_frames, "a voxel is dynamic when this many frames saw it free ...")
      ->check(numberIn(1, 1e9))
      ->capture_default_str();
  app->add_option("--min-free-ratio", s.min_free_ratio, "... and at least this fraction of the frames that saw it occupied")
      ->check(numberIn(0, 1e6))
      ->capture_default_str();
  app->add_option("--spread", s.spread_steps, "steps grown into a frame's voxels whose neighbours in the frame are ...")
      ->check(numberIn(0, 1000))
      ->capture_default_str();
  app->add_option("--spread-fraction", s.spread_fraction, "... at least this fraction dynamic")
      ->check(numberIn(0, 1))
      ->capture_default_str();
  app->add_option("--threads", s.threads, "worker threads, 0 = all cores (output does not depend on it)")
      ->check(numberIn(0, kMaxThreads))
      ->capture_default_str();
  app->add_flag("--exact", o->exact, "cast every point's ray (slower) instead of one per end voxel");
  app->add_flag("--json", o->json, "print the counts as JSON on stdout (no progress)");
  return {app, [o] { return runClean(*o); }};
}

}  // namespace chronomap::cli
