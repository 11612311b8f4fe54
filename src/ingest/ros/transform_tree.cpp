#include "chronomap/ingest/ros/transform_tree.h"

#include <algorithm>
#include <cmath>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double w) {
  const Eigen::Quaterniond qa(a.linear()), qb(b.linear());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = qa.slerp(w, qb).normalized().toRotationMatrix();
  out.translation() = (1.0 - w) * a.translation() + w * b.translation();
  return out;
}

}  // namespace

std::optional<Eigen::Isometry3d> poseAt(const std::vector<TimedPose>& sorted, double t, double tolerance_s) {
  auto after = std::lower_bound(sorted.begin(), sorted.end(), t, [](const TimedPose& p, double v) { return p.t < v; });
  // An exact time gives the sample's own numbers, so poses copied from a trajectory stay identical.
  if (after != sorted.end() && after->t == t) return after->pose;
  const bool has_after = after != sorted.end() && after->t - t <= tolerance_s;
  const bool has_before = after != sorted.begin() && t - std::prev(after)->t <= tolerance_s;
  if (has_before && has_after) {
    const TimedPose& a = *std::prev(after);
    const double w = (t - a.t) / (after->t - a.t);
    return interpolate(a.pose, after->pose, w);
  }
  // Outside the recorded span (or beside a gap): the nearest sample when it is close enough.
  if (has_before && after == sorted.end()) return std::prev(after)->pose;
  if (has_after && after == sorted.begin()) return after->pose;
  return std::nullopt;
}

void TransformTree::add(const std::string& parent, const std::string& child, double t,
                        const Eigen::Isometry3d& T_parent_child, bool is_static, const std::string& context) {
  if (parent == child) throw DataError(context + ": frame '" + child + "' is given itself as its parent");
  Edge& e = parents_[child];
  if (!e.parent.empty() && e.parent != parent) {
    throw DataError(context + ": frame '" + child + "' has two parents, '" + e.parent + "' and '" + parent +
                    "' (a transform tree gives each frame one parent; record one of them under another name)");
  }
  e.parent = parent;
  if (is_static) {
    e.fixed = T_parent_child;
  } else {
    e.samples.push_back({t, T_parent_child});
  }
}

void TransformTree::finish(const std::string& context) {
  for (const auto& [child, e] : parents_) {
    // Walking up from every frame ends at a root within as many steps as there are edges.
    std::vector<std::string> path{child};
    for (auto it = parents_.find(child); it != parents_.end(); it = parents_.find(path.back())) {
      const std::string& parent = it->second.parent;
      const auto seen = std::find(path.begin(), path.end(), parent);
      if (seen == path.end()) {
        path.push_back(parent);
        continue;
      }
      std::string loop;
      for (auto f = seen; f != path.end(); ++f) loop += *f + " -> ";
      throw DataError(context + ": the transforms form a loop (" + loop + parent +
                      "), so no frame on it has a pose; a transform tree has no loops");
    }
  }
  for (auto& [child, e] : parents_) {
    std::stable_sort(e.samples.begin(), e.samples.end(),
                     [](const TimedPose& a, const TimedPose& b) { return a.t < b.t; });
  }
}

std::set<std::string> TransformTree::frames() const {
  std::set<std::string> out;
  for (const auto& [child, e] : parents_) {
    out.insert(child);
    out.insert(e.parent);
  }
  return out;
}

std::set<std::string> TransformTree::roots() const {
  std::set<std::string> out;
  for (const auto& [child, e] : parents_) {
    if (!parents_.count(e.parent)) out.insert(e.parent);
  }
  return out;
}

std::vector<std::string> TransformTree::ancestors(const std::string& frame) const {
  std::vector<std::string> out{frame};
  // A cycle in a broken recording must not loop forever: a tree has fewer edges than frames.
  for (size_t guard = 0; guard <= parents_.size(); ++guard) {
    auto it = parents_.find(out.back());
    if (it == parents_.end()) break;
    out.push_back(it->second.parent);
  }
  return out;
}

std::optional<Eigen::Isometry3d> TransformTree::along(const std::vector<std::string>& path, size_t to, double t,
                                                      double tolerance_s) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // T_path[i]_path[0]
  for (size_t i = 0; i < to; ++i) {
    const Edge& e = parents_.at(path[i]);
    std::optional<Eigen::Isometry3d> step = !e.samples.empty() ? poseAt(e.samples, t, tolerance_s) : e.fixed;
    if (!step) return std::nullopt;
    T = *step * T;
  }
  return T;
}

std::optional<Eigen::Isometry3d> TransformTree::lookup(const std::string& target, const std::string& source, double t,
                                                       double tolerance_s) const {
  const std::vector<std::string> up_source = ancestors(source), up_target = ancestors(target);
  for (size_t i = 0; i < up_source.size(); ++i) {
    const auto j = std::find(up_target.begin(), up_target.end(), up_source[i]);
    if (j == up_target.end()) continue;
    const auto T_anc_source = along(up_source, i, t, tolerance_s);
    const auto T_anc_target = along(up_target, static_cast<size_t>(j - up_target.begin()), t, tolerance_s);
    if (!T_anc_source || !T_anc_target) return std::nullopt;
    return T_anc_target->inverse() * *T_anc_source;
  }
  return std::nullopt;
}

}  // namespace chronomap
