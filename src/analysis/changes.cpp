#include "chronomap/analysis/changes.h"

#include <algorithm>

#include <nlohmann/json.hpp>

namespace chronomap {

namespace {

nlohmann::json vec3(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

nlohmann::json placeJson(const ObjectPlace& p) {
  return {{"voxels", p.voxels}, {"centroid", vec3(p.centroid_m)}, {"size", vec3(p.size_m)}};
}

ObjectPlace placeOf(const Component& c) { return {c.voxels, c.centroid_m, c.bbox_max_m - c.bbox_min_m}; }

/// An appeared or vanished object: its component as it is.
ChangedObject objectOf(const Component& c) {
  ChangedObject o;
  o.kind = c.kind == ChangeKind::Vanished ? ObjectChange::Vanished : ObjectChange::Appeared;
  o.voxels = c.voxels;
  o.centroid_m = c.centroid_m;
  o.bbox_min_m = c.bbox_min_m;
  o.bbox_max_m = c.bbox_max_m;
  o.mean_colour = c.mean_colour;
  o.components = {c.id};
  return o;
}

/// A move: where it is now (the appeared half), where it came from, and how far.
ChangedObject moveOf(const Component& gone, const Component& come) {
  ChangedObject o = objectOf(come);
  o.kind = ObjectChange::Moved;
  o.voxels = gone.voxels + come.voxels;
  o.from = placeOf(gone);
  o.to = placeOf(come);
  o.distance_m = (come.centroid_m - gone.centroid_m).norm();
  o.components = {gone.id, come.id};
  return o;
}

}  // namespace

const char* toString(ObjectChange kind) {
  switch (kind) {
    case ObjectChange::Appeared: return "appeared";
    case ObjectChange::Vanished: return "vanished";
    case ObjectChange::Moved: return "moved";
  }
  return "?";
}

std::vector<ChangedObject> changedObjects(const Segmentation& segmentation, const MoveSettings& moves) {
  const std::vector<Component>& components = segmentation.components;
  std::vector<ChangedObject> objects;
  std::vector<bool> in_move(components.size(), false);
  for (const MovePair& m : pairMoves(components, moves)) {
    objects.push_back(moveOf(components[m.vanished], components[m.appeared]));
    in_move[m.vanished] = in_move[m.appeared] = true;
  }
  for (size_t i = 0; i < components.size(); ++i) {
    if (!in_move[i]) objects.push_back(objectOf(components[i]));
  }
  // Largest first; ties by the first component's id, which follows the segmentation's order.
  std::stable_sort(objects.begin(), objects.end(), [](const ChangedObject& a, const ChangedObject& b) {
    if (a.voxels != b.voxels) return a.voxels > b.voxels;
    return a.components.front() < b.components.front();
  });
  for (size_t i = 0; i < objects.size(); ++i) objects[i].id = static_cast<uint32_t>(i + 1);
  return objects;
}

Changes changesOf(DiffMap diff, const ChangeSettings& settings) {
  settings.validate();
  Changes out;
  out.segmentation = segment(diff, settings.segment);
  out.objects = changedObjects(out.segmentation, settings.moves);
  out.appeared_voxels = diff.voxelCount(ChangeKind::Appeared);
  out.vanished_voxels = diff.voxelCount(ChangeKind::Vanished);
  out.diff = std::move(diff);
  return out;
}

Changes findChanges(const SessionMap& before, const SessionMap& after, const ChangeSettings& settings) {
  settings.validate();
  return changesOf(diff(before, after, settings.diff), settings);
}

Changes findChanges(const TemporalMap& map, double t0_s, double t1_s, const ChangeSettings& settings) {
  settings.validate();
  return changesOf(diff(map, t0_s, t1_s, settings.diff), settings);
}

nlohmann::json changedObjectsJson(const std::vector<ChangedObject>& objects) {
  nlohmann::json list = nlohmann::json::array();
  for (const ChangedObject& o : objects) {
    nlohmann::json j{{"id", o.id},
                     {"kind", toString(o.kind)},
                     {"voxels", o.voxels},
                     {"centroid", vec3(o.centroid_m)},
                     {"size", vec3(o.size_m())},
                     {"bbox_min", vec3(o.bbox_min_m)},
                     {"bbox_max", vec3(o.bbox_max_m)},
                     {"colour", {o.mean_colour.r, o.mean_colour.g, o.mean_colour.b}},
                     {"components", o.components}};
    if (o.kind == ObjectChange::Moved) {
      j["from"] = placeJson(o.from);
      j["to"] = placeJson(o.to);
      j["distance_m"] = o.distance_m;
    }
    list.push_back(std::move(j));
  }
  return list;
}

nlohmann::json changeSettingsJson(const ChangeSettings& s) {
  const DiffSettings& d = s.diff;
  return {{"diff",
           {{"mode", toString(d.mode)},
            {"alpha", d.effectiveAlpha()},
            {"neighbourhood_voxels", d.neighbourhood_voxels},
            {"min_shift_voxels", d.min_shift_voxels},
            {"shift_plane_ratio", d.shift_plane_ratio},
            {"kept_surface_radius_voxels", d.kept_surface_radius_voxels},
            {"kept_surface_share", d.kept_surface_share},
            {"dark_surface_radius_voxels", d.dark_surface_radius_voxels},
            {"dark_surface_brightness", d.dark_surface_brightness},
            {"dark_surface_contrast", d.dark_surface_contrast},
            {"dark_surface_share", d.dark_surface_share},
            {"seen_at_both", d.seen_at_both}}},
          {"segment",
           {{"connectivity", toString(s.segment.connectivity)},
            {"min_voxels", s.segment.min_voxels},
            {"colour_tolerance", s.segment.colour_tolerance},
            {"min_value", s.segment.min_value}}},
          {"moves",
           {{"pair", s.moves.pair},
            {"max_size_ratio", s.moves.max_size_ratio},
            {"max_height_difference_m", s.moves.max_height_difference_m},
            {"max_colour_distance", s.moves.max_colour_distance},
            {"alike_footprints", s.moves.alike_footprints}}}};
}

}  // namespace chronomap
