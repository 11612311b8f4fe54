#include "chronomap/sim/change_truth.h"

#include <nlohmann/json.hpp>
#include <unordered_map>
#include <unordered_set>

#include "chronomap/core/error.h"
#include "chronomap/core/file.h"

namespace chronomap {

std::vector<ChangeEvent> readTruthEvents(const std::filesystem::path& scene_json) {
  const std::string source = scene_json.string();
  std::vector<ChangeEvent> out;
  try {
    const nlohmann::json j = nlohmann::json::parse(readTextFile(scene_json));
    for (const auto& e : j.at("events")) {
      ChangeEvent t;
      t.from_session = e.at("from_session").get<uint32_t>();
      t.object = e.at("object").get<uint32_t>();
      t.object_kind = parseObjectKind(e.at("object_kind").get<std::string>());
      t.kind = parseEventKind(e.at("kind").get<std::string>());
      t.cause = e.value("cause", std::string());
      t.routine = e.value("routine", std::string());
      for (const auto& v : e.at("voxels")) {
        t.voxels.push_back(VoxelKey{v.at(0).get<uint16_t>(), v.at(1).get<uint16_t>(), v.at(2).get<uint16_t>()});
      }
      out.push_back(std::move(t));
    }
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(source + ": not a simulator scene (" + e.what() + ")");
  } catch (const FormatError& e) {
    throw FormatError(source + ": " + e.what());
  }
  return out;
}

std::vector<ChangeEvent> eventsFrom(const std::vector<ChangeEvent>& events, uint32_t from_session) {
  std::vector<ChangeEvent> out;
  for (const ChangeEvent& e : events) {
    if (e.from_session == from_session) out.push_back(e);
  }
  return out;
}

ChangeScore& ChangeScore::operator+=(const ChangeScore& o) {
  events += o.events;
  events_observable += o.events_observable;
  events_found += o.events_found;
  components += o.components;
  false_components += o.false_components;
  changed_voxels += o.changed_voxels;
  true_changed_voxels += o.true_changed_voxels;
  truth_voxels += o.truth_voxels;
  truth_voxels_found += o.truth_voxels_found;
  missed_events.insert(missed_events.end(), o.missed_events.begin(), o.missed_events.end());
  return *this;
}

ChangeScore scoreChanges(const DiffMap& diff, const Segmentation& segmentation, const std::vector<ChangeEvent>& events,
                         const SessionMap& before, const SessionMap& after, const ChangeScoreSettings& settings) {
  ChangeScore s;
  s.events = events.size();
  const int r = settings.match_tolerance_voxels;
  // Event voxels, dilated by the tolerance: code -> event index (the first event wins); and the
  // event voxels known in both sessions, per event.
  auto dilate = [r](const VoxelKey& k, auto&& add) {
    anyKeyWithin(k, r, [&](const VoxelKey& n) {
      add(mortonEncode(n));
      return false;
    });
  };
  std::unordered_map<uint64_t, int> near_event;
  std::vector<std::vector<VoxelKey>> known(events.size());
  for (size_t e = 0; e < events.size(); ++e) {
    for (const VoxelKey& k : events[e].voxels) {
      dilate(k, [&](uint64_t code) { near_event.emplace(code, static_cast<int>(e)); });
      if (before.stateOf(k) != VoxelState::Unknown && after.stateOf(k) != VoxelState::Unknown) known[e].push_back(k);
    }
    s.events_observable += known[e].size() >= settings.min_observed_voxels;
  }
  // Changed voxels, dilated likewise.
  std::unordered_set<uint64_t> near_change;
  for (const ChangeCell& c : diff.cells()) {
    if (c.kind == ChangeKind::Unchanged || c.level != 0) continue;
    ++s.changed_voxels;
    if (near_event.count(mortonEncode(c.key))) ++s.true_changed_voxels;
    dilate(c.key, [&](uint64_t code) { near_change.insert(code); });
  }
  for (const auto& keys : known) {
    s.truth_voxels += keys.size();
    for (const VoxelKey& k : keys) s.truth_voxels_found += near_change.count(mortonEncode(k));
  }
  // Components: which event each overlaps most.
  std::vector<uint8_t> found(events.size(), 0);
  for (const Component& comp : segmentation.components) {
    ++s.components;
    std::unordered_map<int, size_t> votes;
    for (uint32_t idx : comp.cells) {
      const auto it = near_event.find(mortonEncode(diff.cells()[idx].key));
      if (it != near_event.end()) ++votes[it->second];
    }
    int best = -1;
    size_t best_votes = 0;
    for (const auto& [e, n] : votes) {
      if (n > best_votes || (n == best_votes && e < best)) {
        best = e;
        best_votes = n;
      }
      found[static_cast<size_t>(e)] = 1;
    }
    s.component_event.push_back(best);
    if (best < 0) ++s.false_components;
  }
  for (size_t e = 0; e < events.size(); ++e) {
    if (known[e].size() < settings.min_observed_voxels) continue;
    if (found[e]) {
      ++s.events_found;
    } else {
      const ChangeEvent& ev = events[e];
      s.missed_events.push_back(std::string(toString(ev.object_kind)) + " " + std::to_string(ev.object) + " " +
                                toString(ev.kind) + " (session " + std::to_string(ev.from_session) + " -> " +
                                std::to_string(ev.from_session + 1) + ", " + std::to_string(known[e].size()) +
                                " voxels observed)");
    }
  }
  return s;
}

}  // namespace chronomap
