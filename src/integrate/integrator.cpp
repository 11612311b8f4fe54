#include "chronomap/integrate/integrator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include "chronomap/core/error.h"
#include "chronomap/integrate/ray.h"

namespace chronomap {

IntegrationStats& IntegrationStats::operator+=(const IntegrationStats& o) {
  frames += o.frames;
  points += o.points;
  points_invalid += o.points_invalid;
  points_out_of_range += o.points_out_of_range;
  points_outside_map += o.points_outside_map;
  rays += o.rays;
  voxel_updates += o.voxel_updates;
  seconds += o.seconds;
  return *this;
}

namespace {

/// A valid end point in key space with its colour.
struct EndPoint {
  double u[3];
  Rgb color;
};

/// Hits and colour of one end voxel; in fast mode also the sum of its points.
struct EndEntry {
  uint32_t hits = 0;
  uint32_t red = 0, green = 0, blue = 0;
  double sum[3] = {0, 0, 0};
  int64_t cell[3] = {0, 0, 0};
};

/// Dense scratch over the frame's bounding box: ray length (voxel units) and end-entry index
/// (0 = none) per cell.
struct DenseStore {
  int64_t x0 = 0, y0 = 0, z0 = 0, nx = 0, ny = 0, nz = 0;
  std::vector<float> length;
  std::vector<uint32_t> end;

  void reset(int64_t ax, int64_t ay, int64_t az, int64_t bx, int64_t by, int64_t bz) {
    x0 = ax, y0 = ay, z0 = az;
    nx = bx - ax + 1, ny = by - ay + 1, nz = bz - az + 1;
    const size_t cells = static_cast<size_t>(nx * ny * nz);
    length.assign(cells, 0.0f);
    end.assign(cells, 0u);
  }
  size_t cell(int64_t x, int64_t y, int64_t z) const {
    return static_cast<size_t>((x - x0) + nx * ((y - y0) + ny * (z - z0)));
  }
  float& lengthAt(int64_t x, int64_t y, int64_t z) { return length[cell(x, y, z)]; }
  uint32_t& endAt(int64_t x, int64_t y, int64_t z) { return end[cell(x, y, z)]; }
};

/// Open-addressing hash scratch for frames whose bounding box is too large for a dense grid.
struct HashStore {
  struct Slot {
    uint64_t code = 0;  // Morton code + 1; 0 = empty
    float length = 0.0f;
    uint32_t end = 0;
  };
  std::vector<Slot> slots;
  size_t used = 0;

  void reset() {
    slots.assign(1 << 16, Slot{});
    used = 0;
  }
  static uint64_t codeOf(int64_t x, int64_t y, int64_t z) {
    return mortonEncode(VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)}) + 1;
  }
  Slot& slot(int64_t x, int64_t y, int64_t z) {
    if (2 * (used + 1) > slots.size()) grow();
    const uint64_t code = codeOf(x, y, z);
    const size_t mask = slots.size() - 1;
    size_t i = static_cast<size_t>((code * 0x9E3779B97F4A7C15ULL) >> 20) & mask;
    while (slots[i].code != 0 && slots[i].code != code) i = (i + 1) & mask;
    if (slots[i].code == 0) {
      slots[i].code = code;
      ++used;
    }
    return slots[i];
  }
  void grow() {
    std::vector<Slot> old = std::move(slots);
    slots.assign(old.size() * 2, Slot{});
    const size_t mask = slots.size() - 1;
    for (const Slot& s : old) {
      if (s.code == 0) continue;
      size_t i = static_cast<size_t>((s.code * 0x9E3779B97F4A7C15ULL) >> 20) & mask;
      while (slots[i].code != 0) i = (i + 1) & mask;
      slots[i] = s;
    }
  }
  float& lengthAt(int64_t x, int64_t y, int64_t z) { return slot(x, y, z).length; }
  uint32_t& endAt(int64_t x, int64_t y, int64_t z) { return slot(x, y, z).end; }
};

}  // namespace

struct RayAccumulator::Impl {
  KeyGrid grid;
  IntegratorSettings settings;
  std::vector<EndPoint> points;
  std::vector<EndEntry> ends;  // ends[0] unused so that index 0 means "none"
  DenseStore dense;
  HashStore hash;

  template <class Store>
  void cast(Store& store, const double origin[3]) {
    if (!settings.fast) {
      for (const EndPoint& p : points) {
        traverseRay(origin, p.u, [&](int64_t x, int64_t y, int64_t z, double len, bool last) {
          store.lengthAt(x, y, z) += static_cast<float>(len);
          if (last) {
            uint32_t& e = store.endAt(x, y, z);
            if (e == 0) {
              e = static_cast<uint32_t>(ends.size());
              ends.push_back(EndEntry{0, 0, 0, 0, {0, 0, 0}, {x, y, z}});
            }
            EndEntry& entry = ends[e];
            ++entry.hits;
            entry.red += p.color.r;
            entry.green += p.color.g;
            entry.blue += p.color.b;
          }
        });
      }
      return;
    }
    // Fast mode: bundle the points of each end voxel, then cast one weighted ray per bundle.
    for (const EndPoint& p : points) {
      const int64_t x = static_cast<int64_t>(std::floor(p.u[0]));
      const int64_t y = static_cast<int64_t>(std::floor(p.u[1]));
      const int64_t z = static_cast<int64_t>(std::floor(p.u[2]));
      uint32_t& e = store.endAt(x, y, z);
      if (e == 0) {
        e = static_cast<uint32_t>(ends.size());
        ends.push_back(EndEntry{0, 0, 0, 0, {0, 0, 0}, {x, y, z}});
      }
      EndEntry& entry = ends[e];
      ++entry.hits;
      entry.red += p.color.r;
      entry.green += p.color.g;
      entry.blue += p.color.b;
      entry.sum[0] += p.u[0];
      entry.sum[1] += p.u[1];
      entry.sum[2] += p.u[2];
    }
    for (size_t e = 1; e < ends.size(); ++e) {
      const EndEntry& entry = ends[e];
      const float weight = static_cast<float>(entry.hits);
      double mean[3];
      for (int a = 0; a < 3; ++a) {
        // The mean of points inside a voxel lies inside it; clamp away rounding at its faces.
        const double lo = static_cast<double>(entry.cell[a]);
        mean[a] = std::clamp(entry.sum[a] / entry.hits, lo, std::nextafter(lo + 1.0, lo));
      }
      traverseRay(origin, mean, [&](int64_t x, int64_t y, int64_t z, double len, bool) {
        store.lengthAt(x, y, z) += weight * static_cast<float>(len);
      });
    }
  }

  void emitCell(int64_t x, int64_t y, int64_t z, float length, uint32_t end, VoxelDeltas& out) const {
    VoxelCounters c;
    c.length_m = length * static_cast<float>(grid.resolution_m());
    if (end != 0) {
      const EndEntry& entry = ends[end];
      c.hits = entry.hits;
      c.red = entry.red;
      c.green = entry.green;
      c.blue = entry.blue;
    }
    out.keys.push_back(VoxelKey{static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z)});
    out.deltas.push_back(c);
  }
};

RayAccumulator::RayAccumulator(const KeyGrid& grid, const IntegratorSettings& settings)
    : impl_(std::make_unique<Impl>(Impl{grid, settings, {}, {}, {}, {}})) {}
RayAccumulator::~RayAccumulator() = default;
RayAccumulator::RayAccumulator(RayAccumulator&&) noexcept = default;
RayAccumulator& RayAccumulator::operator=(RayAccumulator&&) noexcept = default;

void RayAccumulator::accumulate(const Frame& frame, VoxelDeltas& out) {
  Impl& s = *impl_;
  out.keys.clear();
  out.deltas.clear();
  out.stats = IntegrationStats{};
  IntegrationStats& st = out.stats;
  st.frames = 1;

  const Eigen::Isometry3d& T = frame.T_world_sensor;
  if (!T.matrix().allFinite()) throw DataError(frame.source + ": sensor pose is not finite");
  const Eigen::Vector3d origin_m = T.translation();
  const Eigen::Vector3d origin_u = s.grid.toKeySpace(origin_m);
  if (!s.grid.keyOf(origin_m)) {
    std::ostringstream msg;
    msg << frame.source << ": sensor position (" << origin_m.transpose() << ") m lies outside the map (|x| < "
        << s.grid.halfExtent_m() << " m at this resolution)";
    throw DataError(msg.str());
  }
  const double origin[3] = {origin_u.x(), origin_u.y(), origin_u.z()};

  // Transform, validate and range-filter the points.
  const double max_range_sq = s.settings.max_range_m * s.settings.max_range_m;
  const Eigen::Matrix3d R = T.linear();
  const double inv_res = 1.0 / s.grid.resolution_m();
  s.points.clear();
  int64_t lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = static_cast<int64_t>(std::floor(origin[a]));
  const PointCloud& cloud = frame.cloud;
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    if (!p.allFinite()) {
      ++st.points_invalid;
      continue;
    }
    const Eigen::Vector3d offset = R * p.cast<double>();
    const double r2 = offset.squaredNorm();
    if (r2 == 0.0) {
      ++st.points_invalid;
      continue;
    }
    if (r2 > max_range_sq) {
      ++st.points_out_of_range;
      continue;
    }
    EndPoint e;
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      e.u[a] = origin[a] + offset[a] * inv_res;
      inside = inside && e.u[a] >= 0.0 && e.u[a] < kKeysPerAxis;
    }
    if (!inside) {
      ++st.points_outside_map;
      continue;
    }
    e.color = cloud.hasColors() ? cloud.colors[i] : Rgb{};
    for (int a = 0; a < 3; ++a) {
      const int64_t c = static_cast<int64_t>(std::floor(e.u[a]));
      lo[a] = std::min(lo[a], c);
      hi[a] = std::max(hi[a], c);
    }
    s.points.push_back(e);
  }
  st.points = s.points.size();
  st.rays = st.points;
  if (s.points.empty()) return;

  s.ends.assign(1, EndEntry{});
  const double cells = static_cast<double>(hi[0] - lo[0] + 1) * static_cast<double>(hi[1] - lo[1] + 1) *
                       static_cast<double>(hi[2] - lo[2] + 1);
  if (cells <= static_cast<double>(s.settings.dense_grid_max_cells)) {
    DenseStore& d = s.dense;
    d.reset(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    s.cast(d, origin);
    // Raster order: consecutive keys share most of their path in the tree.
    size_t idx = 0;
    for (int64_t z = 0; z < d.nz; ++z) {
      for (int64_t y = 0; y < d.ny; ++y) {
        for (int64_t x = 0; x < d.nx; ++x, ++idx) {
          if (d.length[idx] > 0.0f || d.end[idx] != 0) {
            s.emitCell(d.x0 + x, d.y0 + y, d.z0 + z, d.length[idx], d.end[idx], out);
          }
        }
      }
    }
  } else {
    HashStore& h = s.hash;
    h.reset();
    s.cast(h, origin);
    std::vector<const HashStore::Slot*> filled;
    filled.reserve(h.used);
    for (const auto& slot : h.slots) {
      if (slot.code != 0) filled.push_back(&slot);
    }
    std::sort(filled.begin(), filled.end(), [](auto* a, auto* b) { return a->code < b->code; });
    for (const auto* slot : filled) {
      const VoxelKey k = mortonDecode(slot->code - 1);
      s.emitCell(k.x, k.y, k.z, slot->length, slot->end, out);
    }
  }
  if (s.settings.fast) st.rays = s.ends.size() - 1;
  st.voxel_updates = out.keys.size();
}

namespace {

void checkSettings(const IntegratorSettings& settings) {
  if (!std::isfinite(settings.max_range_m) || settings.max_range_m <= 0.0) {
    throw UsageError("max range must be a positive number of metres");
  }
  if (settings.threads < 0) throw UsageError("thread count must be 0 (all cores) or positive");
}

}  // namespace

IntegrationStats integrate(const FrameSource& source, SessionMap& map, const IntegratorSettings& settings,
                           const ProgressFn& progress) {
  checkSettings(settings);
  const auto start = std::chrono::steady_clock::now();
  IntegrationStats total;
  const size_t n = source.size();
  int threads = settings.threads > 0 ? settings.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::max(1, threads);

  if (threads == 1 || n <= 1) {
    RayAccumulator acc(map.grid(), settings);
    VoxelDeltas deltas;
    for (size_t i = 0; i < n; ++i) {
      acc.accumulate(source.load(i), deltas);
      map.addMany(deltas.keys, deltas.deltas);
      total += deltas.stats;
      if (progress) progress(i + 1, n);
    }
  } else {
    // Frames are loaded and cast in parallel; merging stays serial and in frame order, so the
    // map is the same for every thread count.
    tbb::enumerable_thread_specific<RayAccumulator> accumulators(map.grid(), settings);
    tbb::task_arena arena(threads);
    arena.execute([&] {
      size_t next = 0;
      tbb::parallel_pipeline(
          static_cast<size_t>(threads) * 2,
          tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order,
                                         [&](tbb::flow_control& fc) -> size_t {
                                           if (next >= n) {
                                             fc.stop();
                                             return 0;
                                           }
                                           return next++;
                                         }) &
              tbb::make_filter<size_t, std::shared_ptr<VoxelDeltas>>(
                  tbb::filter_mode::parallel,
                  [&](size_t i) {
                    auto deltas = std::make_shared<VoxelDeltas>();
                    accumulators.local().accumulate(source.load(i), *deltas);
                    return deltas;
                  }) &
              tbb::make_filter<std::shared_ptr<VoxelDeltas>, void>(
                  tbb::filter_mode::serial_in_order, [&](const std::shared_ptr<VoxelDeltas>& deltas) {
                    map.addMany(deltas->keys, deltas->deltas);
                    total += deltas->stats;
                    if (progress) progress(static_cast<size_t>(total.frames), n);
                  }));
    });
  }
  if (settings.compress_free) map.compressFree();
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace chronomap
