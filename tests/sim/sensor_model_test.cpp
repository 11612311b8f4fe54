// The simulator's depth camera models (SensorModel::kind kinect and realsense) and odometry.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <numbers>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/sim/building.h"
#include "sim/internal.h"
#include "test_support.h"
#include "builders.h"

namespace chronomap {
namespace {

namespace fs = std::filesystem;

// A scene of one wall facing -x at x = `x_m`, all faces `colour`, shiny faces as given.
SceneState wallScene(double x_m, Rgb colour, uint8_t shiny_faces = 0) {
  SceneState s;
  Object wall;
  wall.kind = ObjectKind::Wall;
  Part p;
  p.box = Eigen::AlignedBox3d(Eigen::Vector3d(x_m, -40.0, -40.0), Eigen::Vector3d(x_m + 0.1, 40.0, 40.0));
  p.face_colours.fill(colour);
  p.shiny_faces = shiny_faces;
  wall.parts.push_back(p);
  s.objects.push_back(wall);
  s.bounds.extend(p.box);
  return s;
}

// Incidence of pixel (u, v) on a wall facing the camera square on.
double squareOnIncidence(const Camera& c, uint32_t u, uint32_t v) {
  const Eigen::Vector3d d((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0);
  return std::acos(1.0 / d.norm());
}

constexpr Rgb kLightGrey{200, 200, 200};

TEST(SensorModel, KinectAndRealSenseNoiseOnAFlatWallFollowsTheirFormula) {
  const Camera camera = kinectCamera(0.25);
  for (const SensorKind kind : {SensorKind::Kinect, SensorKind::RealSense}) {
    const SensorModel sensor = sensorModel(kind);
    for (const double z : {1.0, 2.0, 3.0, 4.0}) {
      const Renderer renderer(wallScene(z, kLightGrey));
      double sum = 0.0, sum2 = 0.0;
      size_t n = 0, off_lattice = 0;
      double worst = 0.0;
      for (uint64_t seed = 1; seed <= 2; ++seed) {
        const RenderedFrame f = renderer.render(camera, test::cameraLooking(Eigen::Vector3d::Zero(), 0.0), sensor, 12.0, seed);
        for (uint32_t v = 0; v < camera.height; ++v) {
          for (uint32_t u = 0; u < camera.width; ++u) {
            const uint16_t d = f.depth.pixels[size_t{v} * camera.width + u];
            if (d == 0) continue;
            const double measured = d / sensor.depth_scale;
            const double sigma = axialSigma(sensor.camera, z, squareOnIncidence(camera, u, v));
            const double e = (measured - z) / sigma;
            sum += e;
            sum2 += e * e;
            worst = std::max(worst, std::abs(e));
            ++n;
            // Depths on the disparity lattice: baseline * focal / (k * step), k whole (to the PNG's 0.2 mm).
            const double fb = sensor.camera.baseline_m * sensor.camera.focal_px;
            const double k = std::round(fb / (measured * sensor.camera.disparity_step_px));
            if (std::abs(fb / (k * sensor.camera.disparity_step_px) - measured) > 0.5 / sensor.depth_scale + 1e-9) ++off_lattice;
          }
        }
      }
      const std::string what = std::string(toString(kind)) + " at " + std::to_string(z) + " m";
      ASSERT_GT(n, 30000u) << what;  // of 2 x 19,200 pixels: nothing lost on a light, flat, square-on wall
      const double mean = sum / static_cast<double>(n);
      std::printf("%s: %zu pixels, depth error / sigma_z: spread %.3f, mean %.3f, largest %.2f\n", what.c_str(), n,
                  std::sqrt(sum2 / static_cast<double>(n) - mean * mean), mean, worst);
      EXPECT_NEAR(std::sqrt(sum2 / static_cast<double>(n) - mean * mean), 1.0, 0.06) << what;
      EXPECT_LT(std::abs(mean), 0.1) << what;
      EXPECT_LT(worst, 6.0) << what << ": no flying pixel without a depth edge";
      EXPECT_EQ(off_lattice, 0u) << what;
    }
  }
}

TEST(SensorModel, NoDepthBeyondTheRangeOrAtGrazingIncidence) {
  const Camera camera = kinectCamera(0.25);
  const Eigen::Isometry3d square_on = test::cameraLooking(Eigen::Vector3d::Zero(), 0.0);
  auto measured = [&](double wall_m, SensorKind kind) {
    const RenderedFrame f = Renderer(wallScene(wall_m, kLightGrey)).render(camera, square_on, sensorModel(kind), 12.0, 7);
    return static_cast<size_t>(std::count_if(f.depth.pixels.begin(), f.depth.pixels.end(), [](uint16_t d) { return d > 0; }));
  };
  const size_t all = size_t{camera.width} * camera.height;
  EXPECT_EQ(measured(4.7, SensorKind::Kinect), 0u);  // beyond 4.5 m
  EXPECT_GT(measured(4.3, SensorKind::Kinect), all * 9 / 10);
  EXPECT_GT(measured(4.7, SensorKind::RealSense), all * 9 / 10);  // within 6 m
  EXPECT_EQ(measured(6.3, SensorKind::RealSense), 0u);
  EXPECT_GT(measured(4.7, SensorKind::Ideal), all * 9 / 10);  // the ideal sensor's 5 m, as before

  // A wall seen obliquely: yaw 62 degrees puts the incidence from about 33 to 90 degrees.
  for (const SensorKind kind : {SensorKind::Kinect, SensorKind::RealSense}) {
    const SensorModel sensor = sensorModel(kind);
    const Eigen::Isometry3d T = test::cameraLooking(Eigen::Vector3d::Zero(), 62.0 * std::numbers::pi / 180.0);
    const RenderedFrame f = Renderer(wallScene(1.0, kLightGrey)).render(camera, T, sensor, 12.0, 3);
    size_t grazing = 0, grazing_measured = 0, moderate = 0, moderate_measured = 0;
    for (uint32_t v = 0; v < camera.height; ++v) {
      for (uint32_t u = 0; u < camera.width; ++u) {
        const size_t i = size_t{v} * camera.width + u;
        if (f.true_depth_m[i] == 0.0f) continue;
        const Eigen::Vector3d d = T.linear() * Eigen::Vector3d((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0).normalized();
        const double theta_deg = std::acos(std::abs(d.x())) * 180.0 / std::numbers::pi;
        // A pixel samples up to 2 px away (lateral noise): keep 3 degrees clear of the limit.
        if (theta_deg > sensor.camera.max_incidence_deg + 3.0) {
          ++grazing;
          grazing_measured += f.depth.pixels[i] > 0;
        } else if (theta_deg < 60.0 && f.true_depth_m[i] < sensor.max_range_m - 0.5) {
          ++moderate;
          moderate_measured += f.depth.pixels[i] > 0;
        }
      }
    }
    EXPECT_GT(grazing, 500u) << toString(kind);
    EXPECT_EQ(grazing_measured, 0u) << toString(kind);
    EXPECT_GT(moderate, 1000u) << toString(kind);
    EXPECT_GT(moderate_measured, moderate * 95 / 100) << toString(kind);
  }
}

TEST(SensorModel, DarkAndShinySurfacesAreLostOrMeasuredCentimetresOff) {
  const Camera camera = kinectCamera(0.25);
  const Eigen::Isometry3d T = test::cameraLooking(Eigen::Vector3d::Zero(), 0.0);
  const SensorModel sensor = sensorModel(SensorKind::Kinect);
  struct Case {
    Rgb colour;
    uint8_t shiny;
    double dropout, bias_m;
  };
  const DepthCameraModel& m = sensor.camera;
  for (const Case& c : {Case{Rgb{25, 25, 25}, 0, m.dark_dropout, m.dark_bias_m},
                        Case{kLightGrey, 1u << 0, m.shiny_dropout, m.shiny_bias_m},  // the -x face, facing the camera
                        Case{kLightGrey, 1u << 1, 0.0, 0.0}}) {                      // the far face: not seen
    const RenderedFrame f = Renderer(wallScene(1.5, c.colour, c.shiny)).render(camera, T, sensor, 12.0, 11);
    double sum = 0.0;
    size_t n = 0;
    for (const uint16_t d : f.depth.pixels) {
      if (d == 0) continue;
      sum += d / sensor.depth_scale - 1.5;
      ++n;
    }
    const double lost = 1.0 - static_cast<double>(n) / static_cast<double>(f.depth.pixels.size());
    EXPECT_NEAR(lost, c.dropout, 0.02) << int{c.shiny};
    EXPECT_NEAR(sum / static_cast<double>(n), c.bias_m, 0.001) << int{c.shiny};
  }
}

TEST(SensorModel, FlyingPixelsOnlyAtDepthEdges) {
  // A wall 3 m away with a pillar and a low box 1.2 to 2 m in front of it: depth edges of 1 m
  // and more, where the pixels fly, and flat surfaces, where they must not.
  SceneState scene = wallScene(3.0, kLightGrey);
  Object front;
  for (const auto& [lo, hi] : {std::pair{Eigen::Vector3d(1.5, -0.3, -3.0), Eigen::Vector3d(1.8, 0.3, 3.0)},
                               std::pair{Eigen::Vector3d(2.0, 0.5, -3.0), Eigen::Vector3d(2.4, 1.2, -0.4)},
                               std::pair{Eigen::Vector3d(1.2, -1.5, 0.2), Eigen::Vector3d(1.3, -0.8, 0.9)}}) {
    Part p;
    p.box = Eigen::AlignedBox3d(lo, hi);
    p.face_colours.fill(kLightGrey);
    front.parts.push_back(p);
  }
  scene.objects.push_back(front);
  const Renderer renderer(scene);
  const SensorModel sensor = sensorModel(SensorKind::Kinect);
  const Camera camera = kinectCamera(0.5);
  const auto w = static_cast<int64_t>(camera.width), h = static_cast<int64_t>(camera.height);
  size_t flying = 0, measured = 0;
  for (int view = 0; view < 3; ++view) {
    const RenderedFrame f = renderer.render(camera, test::cameraLooking(Eigen::Vector3d::Zero(), 0.2 * (view - 1)), sensor, 12.0, 40 + view);
    const auto truth = [&](int64_t u, int64_t v) { return double{f.true_depth_m[static_cast<size_t>(v * w + u)]}; };
    for (int64_t v = 0; v < h; ++v) {
      for (int64_t u = 0; u < w; ++u) {
        const uint16_t d = f.depth.pixels[static_cast<size_t>(v * w + u)];
        if (d == 0) continue;
        ++measured;
        const double z = d / sensor.depth_scale;
        // Flying: farther from every true depth the pixel may have sampled (2 px of lateral noise)
        // than noise, quantisation and a dark or shiny bias explain.
        bool explained = false;
        for (int64_t dv = -2; dv <= 2 && !explained; ++dv) {
          for (int64_t du = -2; du <= 2 && !explained; ++du) {
            if (u + du < 0 || v + dv < 0 || u + du >= w || v + dv >= h) continue;
            const double t = truth(u + du, v + dv);
            const double tolerance = 6.0 * axialSigma(sensor.camera, t + 0.05, 1.4) + depthStep(sensor.camera, t + 0.05);
            explained = t > 0.0 && std::abs(z - t - 0.035) <= 0.035 + 0.001 + tolerance;  // biases: 0 to 7 cm
          }
        }
        if (explained) continue;
        ++flying;
        // A depth edge within 3 px: two neighbouring true depths more than 5% apart.
        bool edge = false;
        for (int64_t dv = -3; dv <= 3 && !edge; ++dv) {
          for (int64_t du = -3; du <= 3 && !edge; ++du) {
            const int64_t a = u + du, b = v + dv;
            if (a < 0 || b < 0 || a + 1 >= w || b + 1 >= h) continue;
            for (const auto& [c, e] : {std::pair{a + 1, b}, std::pair{a, b + 1}}) {
              const double z0 = truth(a, b), z1 = truth(c, e);
              edge = edge || std::abs(z0 - z1) > 0.05 * std::min(z0, z1);
            }
          }
        }
        EXPECT_TRUE(edge) << "a flying pixel away from any depth edge at " << u << ", " << v << " of view " << view;
        if (!edge) return;
      }
    }
  }
  std::printf("%zu flying pixels of %zu measured\n", flying, measured);
  EXPECT_GT(measured, 150000u);
  EXPECT_GT(flying, 500u);  // they exist
}

TEST(SensorModel, IdealSensorKeepsItsBytes) {
  // FNV-1a of a frame's colour and depth with the default SensorModel, as the renderer drew it
  // before sensor models existed (the simulator's whole output was compared with diff -r too).
  const SceneState scene = makeScene("office", 4);
  const Renderer renderer(scene);
  const Camera camera = kinectCamera(0.25);
  const Eigen::Isometry3d T = test::cameraLooking({3.0, 1.0, 1.2}, 1.0);
  auto hash = [](const RenderedFrame& f) {
    uint64_t x = 0xcbf29ce484222325ULL;
    auto add = [&x](uint8_t b) { x = (x ^ b) * 0x100000001b3ULL; };
    for (const Rgb& c : f.rgb.pixels) {
      add(c.r);
      add(c.g);
      add(c.b);
    }
    for (const uint16_t d : f.depth.pixels) {
      add(static_cast<uint8_t>(d & 0xff));
      add(static_cast<uint8_t>(d >> 8));
    }
    return x;
  };
  const RenderedFrame before = renderer.render(camera, T, SensorModel{}, 10.0, 5);
  EXPECT_EQ(hash(before), 7996256501885398153ULL);
  EXPECT_EQ(hash(renderer.render(camera, T, sensorModel(SensorKind::Ideal), 10.0, 5)), hash(before));
  EXPECT_NE(hash(renderer.render(camera, T, sensorModel(SensorKind::Kinect), 10.0, 5)), hash(before));
}

TEST(SensorModel, OdometryDriftsWithThePathWhileTheTruePosesStay) {
  const SceneState scene = makeScene("office", 1);
  SimulationSettings ideal, kinect;
  kinect.sensor = "kinect";
  double early = 0.0, late = 0.0;
  size_t n_early = 0, n_late = 0;
  for (int session = 0; session < 4; ++session) {
    const sim_detail::Patrol a = sim_detail::patrolSession(scene, ideal, session);
    const sim_detail::Patrol b = sim_detail::patrolSession(scene, kinect, session);
    ASSERT_EQ(a.true_poses.size(), b.true_poses.size());
    ASSERT_GT(b.true_poses.size(), 30u);
    for (size_t i = 0; i < a.true_poses.size(); ++i) {
      ASSERT_TRUE(a.true_poses[i].matrix() == b.true_poses[i].matrix()) << i;
    }
    // The first estimate is the true pose with the session's localisation offset, as before.
    EXPECT_NEAR(b.estimated[0].translation().x() - b.true_poses[0].translation().x(), a.offset_x_m, 1e-12);
    EXPECT_NEAR(b.estimated[0].translation().y() - b.true_poses[0].translation().y(), a.offset_y_m, 1e-12);
    // Error against the path travelled: the first and the last quarter of the path.
    std::vector<double> path{0.0};
    for (size_t i = 1; i < b.true_poses.size(); ++i) {
      path.push_back(path.back() + (b.true_poses[i].translation() - b.true_poses[i - 1].translation()).norm());
    }
    for (size_t i = 0; i < path.size(); ++i) {
      const double error = (b.estimated[i].translation() - b.true_poses[i].translation()).norm();
      if (path[i] < 0.25 * path.back()) {
        early += error;
        ++n_early;
      } else if (path[i] > 0.75 * path.back()) {
        late += error;
        ++n_late;
      }
    }
  }
  early /= static_cast<double>(n_early);
  late /= static_cast<double>(n_late);
  std::printf("odometry error: %.3f m in the first quarter of the path, %.3f m in the last\n", early, late);
  EXPECT_GT(late, 2.0 * early);
}

TEST(SensorModel, SimulateWithASensorKeepsTheTruthAndTheTruePoses) {
  test::TempDir tmp;
  SimulationSettings settings;
  settings.preset = "tiny";
  settings.sessions = 1;
  settings.resolution_scale = 0.1;
  settings.threads = 1;
  simulate(settings, tmp.path() / "ideal");
  settings.sensor = "kinect";
  simulate(settings, tmp.path() / "kinect");
  const fs::path a = tmp.path() / "ideal", b = tmp.path() / "kinect";
  for (const char* same : {"truth/occupancy_00.cmap", "truth/objects_00.json", "session_00/groundtruth.txt",
                           "session_00/rgb.txt", "session_00/depth.txt"}) {
    EXPECT_EQ(test::bytesOf(a / same), test::bytesOf(b / same)) << same;
  }
  size_t images = 0;
  for (const auto& e : fs::directory_iterator(a / "session_00" / "rgb")) {
    EXPECT_EQ(test::bytesOf(e.path()), test::bytesOf(b / "session_00" / "rgb" / e.path().filename())) << e.path();
    ++images;
  }
  EXPECT_EQ(images, 32u);
  EXPECT_NE(test::bytesOf(a / "session_00/trajectory.txt"), test::bytesOf(b / "session_00/trajectory.txt"));
  const auto scene = nlohmann::json::parse(readTextFile(b / "scene.json"));
  EXPECT_EQ(scene["sensor"]["model"], "kinect");
  EXPECT_EQ(scene["sensor"]["max_range_m"], 4.5);
  settings.sensor = "lidar";
  EXPECT_THROW(simulate(settings, tmp.path() / "lidar"), UsageError);
}

}  // namespace
}  // namespace chronomap
