// One question, one answer (issue 43): what changed between two sessions of `chronomap demo`'s
// office, asked at every front door: the demo's report.json, the diff files it keeps, the
// library call, `chronomap diff MAP@T1 MAP@T2 --json` with no other flag, the viewer's
// /api/diff?format=json and `chronomap alerts MAP --at T --top 0 --json`. The Python package asks
// the same call (python/tests/test_changes.py compares it with report.json).
#include <gtest/gtest.h>

#include <cstdio>
#include <nlohmann/json.hpp>

#include "chronomap/analysis/changes.h"
#include "chronomap/core/file.h"
#include "chronomap/core/time.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/store/temporal_file.h"
#include "running_server.h"

namespace chronomap {
namespace {

/// The objects of a ranked alerts list, in the order of their ids, without the scores.
nlohmann::json byIdWithoutScores(nlohmann::json ranked) {
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a["id"] < b["id"]; });
  for (auto& o : ranked) {
    for (const char* key : {"rank", "score_bits", "probability", "reason"}) o.erase(key);
  }
  return ranked;
}

TEST(FrontDoors, EveryFrontDoorGivesTheSameObjectsForEveryPairOfTheDemo) {
  test::TempDir tmp;
  const std::string cli = CHRONOMAP_CLI_PATH;
  const auto demo = test::runCommand(cli + " demo --resolution-scale 0.2 -o " + (tmp / "demo").string() + " --json");
  ASSERT_EQ(demo.exit_code, 0) << demo.err;
  const nlohmann::json report = nlohmann::json::parse(readTextFile(tmp / "demo" / "report.json"));
  const std::string path = (tmp / "demo" / "office.cmap").string();
  const TemporalMap map = readTemporalMap(path);
  ASSERT_EQ(report["pairs"].size(), map.sessionCount() - 1);
  EXPECT_EQ(report["numbering"], "sessions are numbered from 1");
  test::Running server(map);
  httplib::Client client("127.0.0.1", server.port());
  size_t objects = 0;
  for (size_t k = 1; k < map.sessionCount(); ++k) {
    const nlohmann::json& pair = report["pairs"][k - 1];
    SCOPED_TRACE("sessions " + std::to_string(k) + " -> " + std::to_string(k + 1));
    EXPECT_EQ(pair["from"], k);
    EXPECT_EQ(pair["to"], k + 1);
    const double t0 = map.sessions()[k - 1].time_s, t1 = map.sessions()[k].time_s;
    EXPECT_EQ(pair["from_time"], formatTime(t0));
    const nlohmann::json answer = changedObjectsJson(findChanges(map, t0, t1).objects);
    objects += answer.size();
    EXPECT_EQ(pair["objects"], answer) << "report.json";

    char name[64];
    std::snprintf(name, sizeof name, "diff_%02zu_%02zu.cmap", k, k + 1);
    EXPECT_EQ(diffChangesOf(readCmap(tmp / "demo" / "changes" / name), name)["objects"], answer) << name;

    const std::string at0 = path + "@" + formatTime(t0), at1 = path + "@" + formatTime(t1);
    const auto diff = test::runCommand(cli + " diff " + at0 + " " + at1 + " -o " + (tmp / "d.cmap").string() + " --json");
    ASSERT_EQ(diff.exit_code, 0) << diff.err;
    EXPECT_EQ(nlohmann::json::parse(diff.out)["objects"], answer) << "chronomap diff";

    const auto viewer = client.Get("/api/diff?t0=" + formatTime(t0) + "&t1=" + formatTime(t1) + "&format=json");
    ASSERT_TRUE(viewer);
    ASSERT_EQ(viewer->status, 200) << viewer->body;
    EXPECT_EQ(nlohmann::json::parse(viewer->body)["objects"], answer) << "the viewer";

    const auto alerts = test::runCommand(cli + " alerts " + path + " --at " + formatTime(t1) + " --top 0 --json");
    ASSERT_EQ(alerts.exit_code, 0) << alerts.err;
    EXPECT_EQ(byIdWithoutScores(nlohmann::json::parse(alerts.out)["objects"]), answer) << "chronomap alerts";
  }
  EXPECT_GT(objects, 0u) << "the demo's office changes";
}

}  // namespace
}  // namespace chronomap
