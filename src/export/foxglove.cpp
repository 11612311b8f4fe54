#include "chronomap/export/foxglove.h"

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "chronomap/analysis/changes.h"
#include "chronomap/core/base64.h"
#include "chronomap/core/error.h"
#include "chronomap/core/time.h"
#include "chronomap/octree/voxel_queries.h"
#include "foxglove_schemas.h"

namespace chronomap {

namespace {

using nlohmann::json;

// foxglove.NumericType and foxglove.SceneEntityDeletionType / LineType values.
constexpr int kUint8 = 1, kInt8 = 2, kFloat32 = 7;
constexpr int kDeleteAll = 1;
constexpr int kLineList = 2;
constexpr uint32_t kPointStride = 16;  // x, y, z float32; red, green, blue, alpha uint8
constexpr double kNsPerS = 1e9;

uint64_t timeNs(double time_s, const std::string& session) {
  if (!(time_s >= 0.0)) {
    throw UsageError("session '" + session + "' at " + formatTime(time_s) +
                     " lies before 1970, which an MCAP file cannot hold (its times are unsigned nanoseconds)");
  }
  // Whole seconds and the nanoseconds after them: time_s * 1e9 as one double would lose the
  // last digits (a double holds 53 bits; 2012 in nanoseconds needs 61).
  const double whole_s = std::floor(time_s);
  return static_cast<uint64_t>(whole_s) * 1'000'000'000u + static_cast<uint64_t>(std::llround((time_s - whole_s) * kNsPerS));
}

json stamp(uint64_t ns) { return {{"sec", ns / 1'000'000'000u}, {"nsec", ns % 1'000'000'000u}}; }
json vec3(const Eigen::Vector3d& v) { return {{"x", v.x()}, {"y", v.y()}, {"z", v.z()}}; }
json pose(const Eigen::Vector3d& position) {
  return {{"position", vec3(position)}, {"orientation", {{"x", 0.0}, {"y", 0.0}, {"z", 0.0}, {"w", 1.0}}}};
}
json colour(const Rgb& c, double alpha) {
  return {{"r", c.r / 255.0}, {"g", c.g / 255.0}, {"b", c.b / 255.0}, {"a", alpha}};
}
json field(const char* name, uint32_t offset, int type) { return {{"name", name}, {"offset", offset}, {"type", type}}; }

std::string transformMessage(uint64_t ns, const FoxgloveSettings& s) {
  return json{{"timestamp", stamp(ns)},
              {"parent_frame_id", s.world_frame},
              {"child_frame_id", s.map_frame},
              {"translation", vec3(Eigen::Vector3d::Zero())},
              {"rotation", {{"x", 0.0}, {"y", 0.0}, {"z", 0.0}, {"w", 1.0}}}}
      .dump();
}

std::string pointCloudMessage(const VoxelCentres& occupied, uint64_t ns, const FoxgloveSettings& s) {
  std::string data(occupied.centers_m.size() * kPointStride, '\0');
  for (size_t i = 0; i < occupied.centers_m.size(); ++i) {
    const Eigen::Vector3f p = occupied.centers_m[i].cast<float>();
    const Rgb& c = occupied.colours[i];
    const uint8_t rgba[4] = {c.r, c.g, c.b, 255};
    std::memcpy(&data[i * kPointStride], p.data(), 12);
    std::memcpy(&data[i * kPointStride + 12], rgba, 4);
  }
  return json{{"timestamp", stamp(ns)},
              {"frame_id", s.map_frame},
              {"pose", pose(Eigen::Vector3d::Zero())},
              {"point_stride", kPointStride},
              {"fields",
               {field("x", 0, kFloat32), field("y", 4, kFloat32), field("z", 8, kFloat32), field("red", 12, kUint8),
                field("green", 13, kUint8), field("blue", 14, kUint8), field("alpha", 15, kUint8)}},
              {"data", base64(data)}}
      .dump();
}

std::string gridMessage(const Costmap& c, uint64_t ns, const FoxgloveSettings& s) {
  const std::string data(reinterpret_cast<const char*>(c.cost.data()), c.cost.size());
  return json{{"timestamp", stamp(ns)},
              {"frame_id", s.map_frame},
              {"pose", pose(Eigen::Vector3d(c.origin_m.x(), c.origin_m.y(), s.costmap.z_min_m))},
              {"column_count", c.width},
              {"cell_size", {{"x", c.resolution_m}, {"y", c.resolution_m}}},
              {"row_stride", c.width},
              {"cell_stride", 1},
              {"fields", {field("cost", 0, kInt8)}},
              {"data", base64(data)}}
      .dump();
}

json cube(const Eigen::Vector3d& centre, const Eigen::Vector3d& size, const Rgb& c, double alpha) {
  return {{"pose", pose(centre)}, {"size", vec3(size)}, {"color", colour(c, alpha)}};
}

/// One changed object: its box (a move's new place, and its old one fainter, joined by a line)
/// and a label above it.
json objectEntity(const ChangedObject& o, uint64_t ns, const FoxgloveSettings& s) {
  const Rgb& c = o.kind == ObjectChange::Appeared ? s.appeared : o.kind == ObjectChange::Vanished ? s.vanished : s.moved;
  const Eigen::Vector3d centre = 0.5 * (o.bbox_min_m + o.bbox_max_m);
  json cubes = json::array({cube(centre, o.size_m(), c, s.box_alpha)});
  json lines = json::array();
  char text[96];
  std::snprintf(text, sizeof text, "%u %s", o.id, toString(o.kind));
  json metadata = json::array({{{"key", "kind"}, {"value", toString(o.kind)}},
                               {{"key", "voxels"}, {"value", std::to_string(o.voxels)}}});
  if (o.kind == ObjectChange::Moved) {
    cubes.push_back(cube(o.from.centroid_m, o.from.size_m, c, 0.5 * s.box_alpha));
    lines.push_back({{"type", kLineList},
                     {"pose", pose(Eigen::Vector3d::Zero())},
                     {"thickness", 2.0},
                     {"scale_invariant", true},
                     {"points", {vec3(o.from.centroid_m), vec3(o.to.centroid_m)}},
                     {"color", colour(c, 1.0)},
                     {"colors", json::array()},
                     {"indices", json::array()}});
    std::snprintf(text, sizeof text, "%u moved %.2f m", o.id, o.distance_m);
    metadata.push_back({{"key", "distance_m"}, {"value", std::to_string(o.distance_m)}});
  }
  const Eigen::Vector3d above(centre.x(), centre.y(), o.bbox_max_m.z() + 0.1);
  return {{"timestamp", stamp(ns)},
          {"frame_id", s.map_frame},
          {"id", "object " + std::to_string(o.id)},
          {"lifetime", {{"sec", 0}, {"nsec", 0}}},
          {"frame_locked", false},
          {"metadata", metadata},
          {"arrows", json::array()},
          {"cubes", cubes},
          {"spheres", json::array()},
          {"cylinders", json::array()},
          {"lines", lines},
          {"triangles", json::array()},
          {"texts",
           {{{"pose", pose(above)},
             {"billboard", true},
             {"font_size", s.label_font_size},
             {"scale_invariant", true},
             {"color", colour(Rgb{255, 255, 255}, 1.0)},
             {"text", text}}}},
          {"models", json::array()}};
}

std::string sceneUpdateMessage(const std::vector<ChangedObject>& objects, uint64_t ns, const FoxgloveSettings& s) {
  json entities = json::array();
  for (const ChangedObject& o : objects) entities.push_back(objectEntity(o, ns, s));
  // The pair before's boxes go first: Foxglove keeps entities until they are deleted.
  return json{{"deletions", {{{"timestamp", stamp(ns)}, {"type", kDeleteAll}, {"id", ""}}}}, {"entities", entities}}
      .dump();
}

}  // namespace

FoxgloveExport exportFoxglove(const std::filesystem::path& path, const TemporalMap& map, const FoxgloveSettings& s) {
  if (map.sessionCount() == 0) throw UsageError(path.string() + ": the 4D map holds no session to export");
  McapWriter writer(s.mcap);
  const auto channel = [&](const char* topic, const char* schema, std::string_view text) {
    return writer.addChannel(writer.addSchema(schema, "jsonschema", text), topic, "json");
  };
  const uint16_t tf = channel(kFoxgloveTransformTopic, "foxglove.FrameTransform", foxglove_schemas::frameTransform());
  const uint16_t occupied = channel(kFoxgloveOccupiedTopic, "foxglove.PointCloud", foxglove_schemas::pointCloud());
  const uint16_t changes = channel(kFoxgloveChangesTopic, "foxglove.SceneUpdate", foxglove_schemas::sceneUpdate());
  const uint16_t grid = channel(kFoxgloveCostmapTopic, "foxglove.Grid", foxglove_schemas::grid());
  FoxgloveExport out;
  const std::vector<double> times = map.times();
  for (size_t i = 0; i < times.size(); ++i) {
    const uint64_t ns = timeNs(times[i], map.sessions()[i].name);
    writer.addMessage(tf, ns, transformMessage(ns, s));
    const SessionMap state = map.snapshot(times[i]);
    const VoxelCentres voxels = occupiedCentres(state);
    out.points += voxels.centers_m.size();
    writer.addMessage(occupied, ns, pointCloudMessage(voxels, ns, s));
    writer.addMessage(grid, ns, gridMessage(costmap(state, s.costmap), ns, s));
    if (i > 0) {
      const Changes found = findChanges(map, times[i - 1], times[i], s.changes);
      out.objects += found.objects.size();
      writer.addMessage(changes, ns, sceneUpdateMessage(found.objects, ns, s));
    }
  }
  const auto& counts = writer.messageCounts();
  out.topics = {{kFoxgloveTransformTopic, "foxglove.FrameTransform", counts.at(tf)},
                {kFoxgloveOccupiedTopic, "foxglove.PointCloud", counts.at(occupied)},
                {kFoxgloveChangesTopic, "foxglove.SceneUpdate", counts.at(changes)},
                {kFoxgloveCostmapTopic, "foxglove.Grid", counts.at(grid)}};
  out.sessions = times.size();
  out.bytes = writer.write(path);
  return out;
}

}  // namespace chronomap
