// The viewer's HTTP server over a real socket: it binds the loopback address by default,
// answers with the same voxels as the library, refuses what is not its API and keeps serving,
// and answers concurrent requests. Also `chronomap view` and `chronomap export -o .html`.

#include <gtest/gtest.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

#include "chronomap/core/error.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/view/packet.h"
#include "chronomap/view/scene.h"
#include "chronomap/view/server.h"
#include "running_server.h"
#include "test_support.h"

namespace chronomap {
namespace {

using test::Running;
using test::threeSessions;

TEST(ViewServer, ListensOnLoopbackByDefault) {
  EXPECT_EQ(ServerSettings{}.host, "127.0.0.1");
  const TemporalMap map = threeSessions();
  Running r(map);
  EXPECT_EQ(r.server().url(), "http://127.0.0.1:" + std::to_string(r.port()) + "/");
  httplib::Client c("127.0.0.1", r.port());
  const auto res = c.Get("/api/map");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(nlohmann::json::parse(res->body)["sessions"].size(), 3u);
}

TEST(ViewServer, SendsTheScriptCompressedOnceWhenTheBrowserAcceptsGzip) {
  const TemporalMap map = threeSessions();
  Running r(map);
  httplib::Client c("127.0.0.1", r.port());
  c.set_decompress(false);
  const auto gz = c.Get("/viewer.js", httplib::Headers{{"Accept-Encoding", "gzip, deflate, br"}});
  ASSERT_TRUE(gz);
  EXPECT_EQ(gz->get_header_value("Content-Encoding"), "gzip");
  ASSERT_GT(gz->body.size(), 2u);
  EXPECT_EQ(static_cast<uint8_t>(gz->body[0]), 0x1f);
  EXPECT_EQ(static_cast<uint8_t>(gz->body[1]), 0x8b);
  const auto plain = c.Get("/viewer.js", httplib::Headers{{"Accept-Encoding", "identity"}});
  ASSERT_TRUE(plain);
  EXPECT_FALSE(plain->has_header("Content-Encoding"));
  EXPECT_GT(plain->body.size(), 3 * gz->body.size());  // minified JavaScript compresses about 4:1
  c.set_decompress(true);
  const auto decoded = c.Get("/viewer.js");
  ASSERT_TRUE(decoded);
  EXPECT_EQ(decoded->body, plain->body);
}

TEST(ViewServer, SnapshotPayloadDecodesToTheLibrarysVoxels) {
  const TemporalMap map = threeSessions();
  Running r(map);
  httplib::Client c("127.0.0.1", r.port());
  for (const std::string budget : {"1000000", "300"}) {
    const auto res = c.Get("/api/snapshot?session=2&budget=" + budget);
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200);
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/octet-stream");
    const Packet p = readPacket(res->body);
    const VoxelSet ref = snapshotVoxels(map, SnapshotRequest{3000, std::stoul(budget), 0, std::nullopt});
    EXPECT_EQ(p.header["level"], ref.level);
    const auto keys = p.values<uint16_t>("keys");
    ASSERT_EQ(keys.size(), 3 * ref.keys.size());
    for (size_t i = 0; i < ref.keys.size(); ++i) {
      ASSERT_EQ((VoxelKey{keys[3 * i], keys[3 * i + 1], keys[3 * i + 2]}), ref.keys[i]);
    }
    const auto colours = p.values<uint8_t>("colors");
    for (size_t i = 0; i < ref.colours.size(); ++i) EXPECT_EQ(colours[3 * i], ref.colours[i].r);
    EXPECT_EQ(p.values<uint8_t>("levels"), ref.levels);
    EXPECT_EQ(p.values<uint32_t>("members"), ref.members);
  }
  if (const auto res = c.Get("/api/snapshot?session=2&budget=300")) {
    EXPECT_GT(readPacket(res->body).header["level"].get<int>(), 0);
  }
}

TEST(ViewServer, RefusesWhatIsNotItsApiAndKeepsServing) {
  const TemporalMap map = threeSessions();
  Running r(map);
  // Raw requests, so that no client cleans the path up first.
  auto raw = [&](const std::string& request) {
    httplib::Client c("127.0.0.1", r.port());
    c.set_read_timeout(5);
    httplib::Request req;
    req.method = "GET";
    req.path = request;
    auto res = c.send(req);
    return res ? res->status : -1;
  };
  for (const char* path : {"/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/etc/passwd", "/three.cmap", "/CMakeCache.txt",
                           "/api/../../../etc/passwd", "/api/snapshot/../../x"}) {
    EXPECT_EQ(raw(path), 404) << path;
  }
  for (const char* path : {"/api/snapshot?session=3", "/api/snapshot?t=5000", "/api/snapshot?session=0&budget=999999999",
                           "/api/snapshot?session=%zz", "/api/diff?from=0", "/api/history?key=a,b,c"}) {
    EXPECT_EQ(raw(path), 400) << path;
  }
  httplib::Client c("127.0.0.1", r.port());
  const auto post = c.Post("/api/snapshot?session=0", "x", "text/plain");
  ASSERT_TRUE(post);
  EXPECT_GE(post->status, 400);
  EXPECT_LT(post->status, 500);
  const auto ok = c.Get("/api/snapshot?session=0");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
}

TEST(ViewServer, ConcurrentRequestsGetTheSameAnswers) {
  const TemporalMap map = threeSessions();
  Running r(map);
  const std::vector<std::string> paths = {"/api/snapshot?session=0", "/api/snapshot?session=2&budget=500",
                                          "/api/diff?from=0&to=2&min_voxels=1", "/api/history?key=32770,32769,32768",
                                          "/api/map"};
  std::vector<std::string> expected;
  {
    httplib::Client c("127.0.0.1", r.port());
    for (const auto& p : paths) expected.push_back(c.Get(p)->body);
  }
  std::atomic<int> wrong{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      httplib::Client c("127.0.0.1", r.port());
      for (int i = 0; i < 10; ++i) {
        const size_t k = static_cast<size_t>(t + i) % paths.size();
        const auto res = c.Get(paths[k]);
        if (!res || res->status != 200 || res->body != expected[k]) ++wrong;
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
}

TEST(ViewServer, AnAddressInUseIsAnError) {
  const TemporalMap map = threeSessions();
  Running r(map);
  ServerSettings s;
  s.port = r.port();
  Server second(map, "three.cmap", s);
  EXPECT_THROW(second.bind(), IoError);
}

/// `chronomap view MAP --port 0` in a child process: its pid, the first line it printed (the
/// address, once it serves) and what it wrote to stderr when it did not.
struct ServedChild {
  pid_t pid = -1;
  std::string line;
  int port = 0;  ///< 0: it printed no address
  std::string err;
  void stop() {
    if (pid <= 0) return;
    kill(pid, SIGTERM);
    waitpid(pid, nullptr, 0);
    pid = -1;
  }
};

ServedChild serveInChild(const std::filesystem::path& map, const std::filesystem::path& dir) {
  const std::string out = (dir / "view.out").string(), err = (dir / "view.err").string();
  ServedChild child;
  child.pid = fork();
  if (child.pid == 0) {
    std::freopen(out.c_str(), "w", stdout);
    std::freopen(err.c_str(), "w", stderr);
    execl(test::cli().c_str(), "chronomap", "view", map.c_str(), "--port", "0", static_cast<char*>(nullptr));
    _exit(127);
  }
  for (int i = 0; i < 500 && child.line.find("http://") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::ifstream f(out);
    std::getline(f, child.line);
  }
  const size_t at = child.line.find("http://127.0.0.1:");
  if (at != std::string::npos) {
    child.port = std::stoi(child.line.substr(at + 17));
  } else {
    std::ifstream e(err);
    child.err.assign(std::istreambuf_iterator<char>(e), std::istreambuf_iterator<char>());
  }
  return child;
}

TEST(ViewCli, ViewPrintsTheAddressAndServesTheMap) {
  test::TempDir dir;
  writeTemporalMap(dir / "three.cmap", threeSessions(), {});
  ServedChild child = serveInChild(dir / "three.cmap", dir.path());
  ASSERT_GT(child.pid, 0);
  if (!child.port) child.stop();
  ASSERT_NE(child.port, 0) << child.line << child.err;
  httplib::Client c("127.0.0.1", child.port);
  const auto page = c.Get("/");
  const auto js = c.Get("/viewer.js");
  child.stop();
  ASSERT_TRUE(page);
  EXPECT_NE(page->body.find("<script src=\"viewer.js\"></script>"), std::string::npos);
  ASSERT_TRUE(js);
  EXPECT_GT(js->body.size(), 100000u);  // three.js and the page's code
}

TEST(ViewCli, ExportHtmlWritesATourAndRefusesAnotherExtension) {
  test::TempDir dir;
  writeTemporalMap(dir / "three.cmap", threeSessions(), {});
  const auto r = test::runCommand(test::cli() + " export " + (dir / "three.cmap").string() + " -o " +
                                  (dir / "tour.html").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["format"], "html");
  EXPECT_EQ(summary["diffs"], 3);
  const auto bytes = test::bytesOf(dir / "tour.html");
  const std::string html(bytes.begin(), bytes.end());
  EXPECT_EQ(summary["bytes"], html.size());
  EXPECT_NE(html.find("id=\"chronomap-data\">CMV1") == std::string::npos ? html.find("id=\"chronomap-data\">Q01WM") : 0,
            std::string::npos);  // base64 of "CMV1"
  EXPECT_NE(html.find("chronomap 4D viewer"), std::string::npos);
  const auto bad = test::runCommand(test::cli() + " export " + (dir / "three.cmap").string() + " -o " +
                                    (dir / "tour.htm").string());
  EXPECT_EQ(bad.exit_code, 2);
}

// A session map opens where a 4D map does: as a 4D map of its one time (the time its file
// records), in chronomap view and in export -o tour.html.
TEST(ViewCli, ASessionMapOpensAsA4DMapOfItsOneTime) {
  test::TempDir dir;
  const SessionMap session = threeSessions().snapshot(3000.0);
  writeSessionMap(dir / "one.cmap", session, {{"recorded_at", 1330596000.0}});
  const auto r = test::runCommand(test::cli() + " export " + (dir / "one.cmap").string() + " -o " +
                                  (dir / "tour.html").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["diffs"], 0);
  EXPECT_GT(summary["elements"].get<size_t>(), 0u);
  EXPECT_GT(std::filesystem::file_size(dir / "tour.html"), 100000u);  // the viewer and the map

  ServedChild child = serveInChild(dir / "one.cmap", dir.path());
  ASSERT_GT(child.pid, 0);
  if (!child.port) child.stop();
  ASSERT_NE(child.port, 0) << child.line << child.err;
  EXPECT_NE(child.line.find("(1 session)"), std::string::npos) << child.line;
  httplib::Client c("127.0.0.1", child.port);
  const auto info = c.Get("/api/map");
  const auto snap = c.Get("/api/snapshot?session=0");
  child.stop();
  ASSERT_TRUE(info && snap);
  const auto map = nlohmann::json::parse(info->body);
  ASSERT_EQ(map["sessions"].size(), 1u);
  EXPECT_EQ(map["sessions"][0]["time"], "2012-03-01T10:00:00Z");
  EXPECT_EQ(map["sessions"][0]["name"], "one.cmap");
  EXPECT_EQ(snap->status, 200);
  EXPECT_GT(snap->body.size(), 100u);
}

}  // namespace
}  // namespace chronomap
