#include "chronomap/store/colour_file.h"

#include <cmath>
#include <cstring>

#include "chronomap/core/byte_buffer.h"
#include "chronomap/core/error.h"
#include "chronomap/core/file.h"
#include "chronomap/core/key.h"
#include "fitted_on_record.h"

namespace chronomap {

namespace {

constexpr char kColourMagic[4] = {'C', 'M', 'C', 'O'};
constexpr uint8_t kColourKindLightCurves = 1;  ///< per-voxel weights under shared light curves
constexpr size_t kColourHeaderBytes = 84;      ///< version 2, without the learning times

}  // namespace

std::vector<uint8_t> serialize(const ColourModel& m, uint32_t version) {
  if (version < 1 || version > kColourVersion) {
    throw UsageError("colour models are written in versions 1 to " + std::to_string(kColourVersion) + ", not " +
                     std::to_string(version));
  }
  ByteWriter w;
  w.bytes.reserve(kColourHeaderBytes + 8 * m.fitted_on.times_s.size() + m.bytes());
  for (char c : kColourMagic) w.put(c);
  w.put(version);
  w.put(kColourKindLightCurves);
  w.put(static_cast<uint8_t>(m.components));
  w.put(static_cast<uint16_t>(m.bins));
  w.put(m.resolution_m);
  w.put(m.from_s);
  w.put(m.to_s);
  w.put(static_cast<uint64_t>(m.sessions));
  w.put(static_cast<uint64_t>(m.observations));
  w.put(m.rms_error);
  if (version >= 2) putFittedOn(w, m.fitted_on);
  w.put(static_cast<uint64_t>(m.keys.size()));
  for (double v : m.curves) w.put(v);
  const size_t per_voxel = 3 * static_cast<size_t>(m.components);
  for (size_t v = 0; v < m.keys.size(); ++v) {
    w.put(m.keys[v].x);
    w.put(m.keys[v].y);
    w.put(m.keys[v].z);
    for (size_t k = 0; k < per_voxel; ++k) w.put(m.weights[v * per_voxel + k]);
  }
  return std::move(w.bytes);
}

ColourModel deserializeColour(std::span<const uint8_t> bytes, const std::string& source) {
  ByteReader r{bytes, 0, source, "the colour model"};
  for (char c : kColourMagic) {
    if (r.get<char>() != c) throw FormatError(source + ": not a chronomap colour model");
  }
  const auto version = r.get<uint32_t>();
  if (version < 1 || version > kColourVersion) {
    throw FormatError(source + ": colour model version " + std::to_string(version) + " (this build reads 1 to " +
                      std::to_string(kColourVersion) + ")");
  }
  if (const auto kind = r.get<uint8_t>(); kind != kColourKindLightCurves) {
    throw FormatError(source + ": colour model of unknown kind " + std::to_string(kind));
  }
  ColourModel m;
  m.components = r.get<uint8_t>();
  m.bins = r.get<uint16_t>();
  m.resolution_m = r.get<double>();
  m.from_s = r.get<double>();
  m.to_s = r.get<double>();
  const auto sessions = r.get<uint64_t>();
  const auto observations = r.get<uint64_t>();
  m.rms_error = r.get<double>();
  checkLearnedRange({sessions, m.from_s, m.to_s}, source);
  if (version >= 2) m.fitted_on = getFittedOn(r, {sessions, m.from_s, m.to_s});
  const auto count = r.get<uint64_t>();
  ColourSettings ranges;  // the ranges validate() allows
  ranges.components = m.components;
  ranges.bins = m.bins;
  try {
    ranges.validate();
  } catch (const UsageError&) {
    throw FormatError(source + ": bad header (" + std::to_string(m.components) + " light curves of " +
                      std::to_string(m.bins) + " knots)");
  }
  const size_t per_voxel = 3 * static_cast<size_t>(m.components);
  const size_t curve_values = per_voxel * static_cast<size_t>(m.bins);
  const size_t record = 6 + 4 * per_voxel;
  // Resolution 0: a model fitted without a map (fitColourObservations()).
  if (!(m.resolution_m == 0.0 || (m.resolution_m >= kMinResolution_m && m.resolution_m <= kMaxResolution_m)) ||
      !std::isfinite(m.rms_error) || m.rms_error < 0.0) {
    throw FormatError(source + ": bad header (resolution or fit error)");
  }
  if (bytes.size() - r.pos < 8 * curve_values || count > (bytes.size() - r.pos - 8 * curve_values) / record) {
    throw FormatError(source + ": the colour model ends early (truncated): its header announces " +
                      std::to_string(count) + " voxels");
  }
  m.sessions = static_cast<size_t>(sessions);
  m.observations = static_cast<size_t>(observations);
  m.curves.resize(curve_values);
  for (double& v : m.curves) {
    v = r.get<double>();
    if (!std::isfinite(v)) throw FormatError(source + ": a light curve value is not a finite number");
  }
  m.keys.resize(count);
  m.weights.resize(count * per_voxel);
  uint64_t previous = 0;
  for (uint64_t i = 0; i < count; ++i) {
    VoxelKey& k = m.keys[i];
    k.x = r.get<uint16_t>();
    k.y = r.get<uint16_t>();
    k.z = r.get<uint16_t>();
    const uint64_t code = mortonEncode(k);
    if (i > 0 && code <= previous) throw FormatError(source + ": voxels out of order");
    previous = code;
    for (size_t j = 0; j < per_voxel; ++j) {
      const float w = r.get<float>();
      if (!std::isfinite(w)) throw FormatError(source + ": voxel " + std::to_string(i) + " has a weight that is not finite");
      m.weights[i * per_voxel + j] = w;
    }
  }
  if (r.pos != bytes.size()) throw FormatError(source + ": bytes after the last voxel");
  return m;
}

void writeColourModel(const std::filesystem::path& path, const ColourModel& model) {
  writeFileAtomic(path, serialize(model));
}

ColourModel readColourModel(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return deserializeColour(readFileBytes(path), path.string()); });
}

}  // namespace chronomap
