#include "chronomap/store/rhythm_file.h"

#include <cmath>
#include <cstring>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/core/key.h"
#include "fitted_on_record.h"

namespace chronomap {

namespace {

constexpr char kRhythmMagic[4] = {'C', 'M', 'R', 'H'};

void putVoxel(ByteWriter& w, const VoxelRhythm& v, uint32_t version) {
  w.put(v.corner.x);
  w.put(v.corner.y);
  w.put(v.corner.z);
  w.put(v.level);
  w.put(v.last_occupied);
  w.put(v.observations);
  w.put(v.combined_uses_mean);
  w.put(v.mean);
  w.put(v.last_time_s);
  w.put(v.rate_in_per_h);
  w.put(v.rate_out_per_h);
  for (size_t k = 0; k < 2; ++k) {
    w.put(v.period[k]);
    w.put(v.amplitude[k][0]);
    w.put(v.amplitude[k][1]);
  }
  for (size_t k = 0; k < 2; ++k) {
    for (size_t b = 0; b < 12; ++b) {
      w.put(v.hour_observed[k][b]);
      w.put(v.hour_occupied[k][b]);
    }
  }
  if (version >= 2) w.put(v.hits_per_voxel);
  if (version >= 3) w.put(v.group);
}

}  // namespace

std::vector<uint8_t> serialize(const RhythmModels& m, uint32_t version) {
  if (version < 1 || version > kRhythmVersion) {
    throw UsageError("rhythm models are written in versions 1 to " + std::to_string(kRhythmVersion) + ", not " +
                     std::to_string(version));
  }
  ByteWriter w;
  for (char c : kRhythmMagic) w.put(c);
  w.put(version);
  w.put(m.resolution_m);
  w.put(m.from_s);
  w.put(m.to_s);
  w.put(m.sessions);
  if (version >= 4) putFittedOn(w, m.fitted_on);
  w.put(static_cast<uint64_t>(m.voxels.size()));
  for (const VoxelRhythm& v : m.voxels) putVoxel(w, v, version);
  if (version < 3) return std::move(w.bytes);
  w.put(static_cast<uint64_t>(m.groups.size()));
  for (const RhythmGroup& g : m.groups) {
    for (size_t k = 0; k < 2; ++k) {
      for (size_t b = 0; b < 12; ++b) {
        w.put(g.observed[k][b]);
        w.put(g.occupied[k][b]);
      }
    }
  }
  return std::move(w.bytes);
}

namespace {

/// One voxel's record of a file of `version`. @throw FormatError for values out of range.
VoxelRhythm getVoxel(ByteReader& r, uint32_t version, uint64_t i) {
  const std::string& source = r.source;
  VoxelRhythm v;
  v.corner.x = r.get<uint16_t>();
  v.corner.y = r.get<uint16_t>();
  v.corner.z = r.get<uint16_t>();
  v.level = r.get<uint8_t>();
  v.last_occupied = r.get<uint8_t>();
  v.observations = r.get<uint16_t>();
  v.combined_uses_mean = r.get<uint8_t>();
  v.mean = r.get<float>();
  v.last_time_s = r.get<double>();
  v.rate_in_per_h = r.get<float>();
  v.rate_out_per_h = r.get<float>();
  for (size_t k = 0; k < 2; ++k) {
    v.period[k] = r.get<uint8_t>();
    v.amplitude[k][0] = r.get<float>();
    v.amplitude[k][1] = r.get<float>();
    if (v.period[k] != 255 && v.period[k] >= kRhythmPeriods_h.size()) throw FormatError(source + ": bad period");
    if (!std::isfinite(v.amplitude[k][0]) || !std::isfinite(v.amplitude[k][1])) {
      throw FormatError(source + ": an amplitude is not a finite number");
    }
  }
  for (size_t k = 0; k < 2; ++k) {
    for (size_t b = 0; b < 12; ++b) {
      v.hour_observed[k][b] = r.get<uint8_t>();
      v.hour_occupied[k][b] = r.get<uint8_t>();
      if (v.hour_occupied[k][b] > v.hour_observed[k][b]) throw FormatError(source + ": more occupied than observed");
    }
  }
  if (version >= 2) {
    v.hits_per_voxel = r.get<float>();
    if (!(v.hits_per_voxel == -1.0f || (v.hits_per_voxel >= 0.0f && v.hits_per_voxel <= 1e6f))) {
      throw FormatError(source + ": bad hit density");
    }
  }
  if (version >= 3) v.group = r.get<uint32_t>();
  if (v.level >= 16 || v.last_occupied > 1 || v.combined_uses_mean > 1 || !(v.mean >= 0.0f && v.mean <= 1.0f) ||
      !std::isfinite(v.last_time_s) || !(v.rate_in_per_h >= 0.0f) || !(v.rate_out_per_h >= 0.0f) ||
      !std::isfinite(v.rate_in_per_h) || !std::isfinite(v.rate_out_per_h)) {
    throw FormatError(source + ": voxel " + std::to_string(i) + " has values out of range");
  }
  return v;
}

/// The groups' table (version 3 on), and each voxel's copy of its group's bins.
void getGroups(ByteReader& r, RhythmModels& m) {
  const std::string& source = r.source;
  const auto groups = r.get<uint64_t>();
  if (groups > (r.bytes.size() - r.pos) / RhythmModels::kGroupBytes) {
    throw FormatError(source + ": the file announces " + std::to_string(groups) + " groups, more than its " +
                      std::to_string(r.bytes.size() - r.pos) + " bytes left hold (bad group count)");
  }
  m.groups.resize(groups);
  for (RhythmGroup& g : m.groups) {
    for (size_t k = 0; k < 2; ++k) {
      for (size_t b = 0; b < 12; ++b) {
        g.observed[k][b] = r.get<uint16_t>();
        g.occupied[k][b] = r.get<uint16_t>();
        if (g.occupied[k][b] > g.observed[k][b]) throw FormatError(source + ": a group has more occupied than observed");
      }
    }
  }
  for (size_t i = 0; i < m.voxels.size(); ++i) {
    VoxelRhythm& v = m.voxels[i];
    if (v.group == VoxelRhythm::kNoGroup) continue;
    if (v.group >= m.groups.size()) throw FormatError(source + ": voxel " + std::to_string(i) + " names no group");
    v.group_observed = m.groups[v.group].observed;
    v.group_occupied = m.groups[v.group].occupied;
  }
}

}  // namespace

RhythmModels deserializeRhythm(std::span<const uint8_t> bytes, const std::string& source) {
  ByteReader r{bytes, 0, source, "the model"};
  for (char c : kRhythmMagic) {
    if (r.get<char>() != c) throw FormatError(source + ": not a chronomap rhythm model");
  }
  const auto version = r.get<uint32_t>();
  if (version < 1 || version > kRhythmVersion) {
    throw FormatError(source + ": rhythm model version " + std::to_string(version) + " (this build reads 1 to " +
                      std::to_string(kRhythmVersion) + ")");
  }
  RhythmModels m;
  m.resolution_m = r.get<double>();
  m.from_s = r.get<double>();
  m.to_s = r.get<double>();
  m.sessions = r.get<uint32_t>();
  if (!(m.resolution_m >= kMinResolution_m && m.resolution_m <= kMaxResolution_m)) {
    throw FormatError(source + ": bad header (resolution " + std::to_string(m.resolution_m) + " m)");
  }
  checkLearnedRange({m.sessions, m.from_s, m.to_s}, source);
  if (version >= 4) m.fitted_on = getFittedOn(r, {m.sessions, m.from_s, m.to_s});
  const auto count = r.get<uint64_t>();
  const size_t record = RhythmModels::kVoxelBytes - (version == 1 ? 8 : version == 2 ? 4 : 0);
  if (count > (bytes.size() - r.pos) / record) {
    throw FormatError(source + ": the header announces " + std::to_string(count) + " voxels, more than the " +
                      std::to_string(bytes.size() - r.pos) + " bytes left hold (bad voxel count)");
  }
  m.voxels.reserve(count);
  uint64_t previous = 0;
  for (uint64_t i = 0; i < count; ++i) {
    m.voxels.push_back(getVoxel(r, version, i));
    const uint64_t code = mortonEncode(m.voxels.back().corner);
    if (i > 0 && code <= previous) throw FormatError(source + ": voxels out of order");
    previous = code;
  }
  if (version >= 3) getGroups(r, m);
  if (r.pos != bytes.size()) throw FormatError(source + ": bytes after the last voxel");
  return m;
}

void writeRhythmModels(const std::filesystem::path& path, const RhythmModels& models) {
  writeFileAtomic(path, serialize(models));
}

RhythmModels readRhythmModels(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return deserializeRhythm(readFileBytes(path), path.string()); });
}

}  // namespace chronomap
