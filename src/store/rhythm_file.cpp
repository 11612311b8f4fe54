#include "chronomap/store/rhythm_file.h"

#include <cstring>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"

namespace chronomap {

namespace {

constexpr char kMagic[4] = {'C', 'M', 'R', 'H'};
// 2: hits_per_voxel after the hour bins; 3: each voxel's group after it, and the groups' table
// after the voxels.
constexpr uint32_t kVersion = 3;

}  // namespace

std::vector<uint8_t> serialize(const RhythmModels& m) {
  ByteWriter w;
  for (char c : kMagic) w.put(c);
  w.put(kVersion);
  w.put(m.resolution_m);
  w.put(m.from_s);
  w.put(m.to_s);
  w.put(m.sessions);
  w.put(static_cast<uint64_t>(m.voxels.size()));
  for (const VoxelRhythm& v : m.voxels) {
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
    w.put(v.hits_per_voxel);
    w.put(v.group);
  }
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

RhythmModels deserializeRhythm(std::span<const uint8_t> bytes, const std::string& source) {
  ByteReader r{bytes, 0, source, "the model"};
  for (char c : kMagic) {
    if (r.get<char>() != c) throw FormatError(source + ": not a chronomap rhythm model");
  }
  const auto version = r.get<uint32_t>();
  if (version < 1 || version > kVersion) {
    throw FormatError(source + ": rhythm model version " + std::to_string(version) + " (this build reads 1 to 3)");
  }
  RhythmModels m;
  m.resolution_m = r.get<double>();
  m.from_s = r.get<double>();
  m.to_s = r.get<double>();
  m.sessions = r.get<uint32_t>();
  const auto count = r.get<uint64_t>();
  const size_t kRecord = RhythmModels::kVoxelBytes - (version == 1 ? 8 : version == 2 ? 4 : 0);
  if (!std::isfinite(m.resolution_m) || m.resolution_m <= 0.0 || count > (bytes.size() - r.pos) / kRecord) {
    throw FormatError(source + ": bad header (resolution or voxel count)");
  }
  m.voxels.resize(count);
  uint64_t previous = 0;
  for (uint64_t i = 0; i < count; ++i) {
    VoxelRhythm& v = m.voxels[i];
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
    if (v.level >= 16 || v.last_occupied > 1 || v.combined_uses_mean > 1 || !(v.mean >= 0.0f && v.mean <= 1.0f) || !std::isfinite(v.last_time_s) ||
        !(v.rate_in_per_h >= 0.0f) || !(v.rate_out_per_h >= 0.0f) || !std::isfinite(v.rate_in_per_h) ||
        !std::isfinite(v.rate_out_per_h)) {
      throw FormatError(source + ": voxel " + std::to_string(i) + " has values out of range");
    }
    const uint64_t code = mortonEncode(v.corner);
    if (i > 0 && code <= previous) throw FormatError(source + ": voxels out of order");
    previous = code;
  }
  if (version >= 3) {
    const auto groups = r.get<uint64_t>();
    if (groups > (bytes.size() - r.pos) / RhythmModels::kGroupBytes) throw FormatError(source + ": bad group count");
    m.groups.resize(groups);
    for (RhythmGroup& g : m.groups) {
      for (size_t k = 0; k < 2; ++k) {
        for (size_t b = 0; b < 12; ++b) {
          g.observed[k][b] = r.get<uint16_t>();
          g.occupied[k][b] = r.get<uint16_t>();
          if (g.occupied[k][b] > g.observed[k][b]) {
            throw FormatError(source + ": a group has more occupied than observed");
          }
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
