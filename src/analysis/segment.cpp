#include "chronomap/analysis/segment.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>

#include "chronomap/core/error.h"
#include "union_find.h"

namespace chronomap {

const char* toString(Connectivity c) {
  switch (c) {
    case Connectivity::Face: return "face";
    case Connectivity::Edge: return "edge";
    case Connectivity::Vertex: return "vertex";
  }
  return "?";
}

Connectivity parseConnectivity(const std::string& name) {
  for (Connectivity c : {Connectivity::Face, Connectivity::Edge, Connectivity::Vertex}) {
    if (name == toString(c)) return c;
  }
  throw UsageError("unknown connectivity '" + name + "' (use face, edge or vertex)");
}

void SegmentSettings::validate() const {
  if (std::isnan(colour_tolerance) || std::isinf(colour_tolerance)) {
    throw UsageError("colour tolerance must be a finite number");
  }
  if (!std::isfinite(min_value) || min_value < 0.0 || min_value >= 1.0) {
    throw UsageError("minimum value must lie in [0, 1), got " + std::to_string(min_value));
  }
  if (connectivity != Connectivity::Face && connectivity != Connectivity::Edge &&
      connectivity != Connectivity::Vertex) {
    throw UsageError("invalid connectivity");
  }
}

namespace {

// The cells that take part, as indices into the diff's cells (still in Morton order).
std::vector<uint32_t> selectCells(const DiffMap& diff, const SegmentSettings& settings) {
  std::vector<uint32_t> sel;
  const bool continuous = diff.settings().mode == DiffMode::Continuous;
  const auto cells = diff.cells();
  for (size_t i = 0; i < cells.size(); ++i) {
    if (cells[i].kind == ChangeKind::Unchanged) continue;
    if (continuous && !(cells[i].value > settings.min_value)) continue;
    sel.push_back(static_cast<uint32_t>(i));
  }
  return sel;
}

// Whether two selected cells may join: same kind, and colours within the tolerance.
struct JoinRule {
  const DiffMap& diff;
  const std::vector<uint32_t>& sel;
  double tolerance;
  bool operator()(uint32_t i, uint32_t j) const {
    const ChangeCell& a = diff.cells()[sel[i]];
    const ChangeCell& b = diff.cells()[sel[j]];
    if (a.kind != b.kind) return false;
    if (tolerance < 0.0) return true;
    const double dr = a.colour.r - b.colour.r, dg = a.colour.g - b.colour.g, db = a.colour.b - b.colour.b;
    return dr * dr + dg * dg + db * db <= tolerance * tolerance;
  }
};

// Builds the component records from a union-find over the selected cells.
Segmentation collect(const DiffMap& diff, const std::vector<uint32_t>& sel, UnionFind& uf,
                     const SegmentSettings& settings) {
  std::unordered_map<uint32_t, size_t> slot_of_root;
  std::vector<Component> all;
  for (uint32_t i = 0; i < sel.size(); ++i) {
    const uint32_t root = uf.find(i);
    auto [it, fresh] = slot_of_root.try_emplace(root, all.size());
    if (fresh) all.emplace_back();
    all[it->second].cells.push_back(sel[i]);
  }
  const double res = diff.resolution_m();
  Segmentation out;
  for (Component& c : all) {
    double sum_r = 0, sum_g = 0, sum_b = 0;
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
    c.bbox_min_m = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    c.bbox_max_m = -c.bbox_min_m;
    for (uint32_t idx : c.cells) {
      const ChangeCell& cell = diff.cells()[idx];
      c.kind = cell.kind;
      const uint64_t n = uint64_t{1} << (3 * cell.level);
      c.voxels += n;
      const Eigen::Vector3d lo = diff.grid().cornerOf(cell.key);
      const Eigen::Vector3d hi = lo + Eigen::Vector3d::Constant(res * static_cast<double>(1u << cell.level));
      c.bbox_min_m = c.bbox_min_m.cwiseMin(lo);
      c.bbox_max_m = c.bbox_max_m.cwiseMax(hi);
      weighted += 0.5 * (lo + hi) * static_cast<double>(n);
      sum_r += cell.colour.r * static_cast<double>(n);
      sum_g += cell.colour.g * static_cast<double>(n);
      sum_b += cell.colour.b * static_cast<double>(n);
    }
    const auto v = static_cast<double>(c.voxels);
    c.volume_m3 = v * res * res * res;
    c.centroid_m = weighted / v;
    auto channel = [v](double s) { return static_cast<uint8_t>(std::lround(s / v)); };
    c.mean_colour = Rgb{channel(sum_r), channel(sum_g), channel(sum_b)};
    if (c.voxels < settings.min_voxels) {
      ++out.dropped;
      continue;
    }
    out.components.push_back(std::move(c));
  }
  std::sort(out.components.begin(), out.components.end(), [](const Component& a, const Component& b) {
    if (a.voxels != b.voxels) return a.voxels > b.voxels;
    return a.cells.front() < b.cells.front();
  });
  for (size_t i = 0; i < out.components.size(); ++i) out.components[i].id = static_cast<uint32_t>(i + 1);
  return out;
}

// --- The bottom-up bounding-box segmentation -------------------------------------------------
//
// A box (one per octree node) holds six faces. A face is a quadtree of the cells that touch one
// side of the node, with its square and plane given explicitly, so that a node with a single
// non-empty child can hand its child's faces up unchanged (no allocation per level): a face
// whose plane is not the side of the parent's cube simply holds nothing there.

constexpr uint32_t kNone = 0xffffffffu;
constexpr uint32_t kLeafBit = 0x80000000u;

// A square of a face in the face's two in-plane coordinates (u, v), with its content: a leaf
// (kLeafBit | selected cell), a quad node, or nothing.
struct Square {
  uint32_t ref = kNone;
  int32_t u0 = 0, v0 = 0, size = 0;
};

struct Face {
  Square square;
  int32_t plane = 0;
};
using Box = std::array<Face, 6>;  // face 2a + s: axis a, s = 0 the low side, 1 the high side

// In-plane axes of a face normal to axis a.
constexpr int uAxis(int a) { return (a + 1) % 3; }
constexpr int vAxis(int a) { return (a + 2) % 3; }
int32_t coord(const VoxelKey& k, int axis) { return axis == 0 ? k.x : axis == 1 ? k.y : k.z; }
int bit(int child, int axis) { return (child >> axis) & 1; }

class BoxSegmenter {
 public:
  BoxSegmenter(const DiffMap& diff, const std::vector<uint32_t>& sel, const SegmentSettings& settings, UnionFind& uf)
      : diff_(diff), sel_(sel), conn_(settings.connectivity), uf_(uf),
        rule_{diff, sel, settings.colour_tolerance} {
    codes_.reserve(sel.size());
    for (uint32_t i : sel) codes_.push_back(mortonEncode(diff.cells()[i].key));
  }

  void run() {
    if (!sel_.empty()) build(0, sel_.size(), VoxelKey{}, kTreeDepth);
  }

 private:
  const ChangeCell& cell(size_t i) const { return diff_.cells()[sel_[i]]; }

  void join(uint32_t i, uint32_t j) {
    if (rule_(i, j)) uf_.join(i, j);
  }

  // Algorithm 1: the box of the node (corner, level) holding selected cells [lo, hi).
  Box build(size_t lo, size_t hi, VoxelKey corner, int level) {
    // Skip chains of single-child nodes: go straight to the smallest node holding all cells.
    const uint64_t first = codes_[lo];
    const uint64_t last = codes_[hi - 1] + (uint64_t{1} << (3 * cell(hi - 1).level)) - 1;
    while (level > 0 && (first >> (3 * (level - 1))) == (last >> (3 * (level - 1)))) {
      --level;
      corner = mortonDecode((first >> (3 * level)) << (3 * level));
    }
    if (hi - lo == 1 && cell(lo).level == level) return leafBox(lo, corner, level);

    std::array<Box, 8> child{};
    std::array<bool, 8> present{};
    const uint64_t base = mortonEncode(corner);
    const uint64_t span = uint64_t{1} << (3 * (level - 1));
    size_t begin = lo;
    for (int c = 0; c < 8; ++c) {
      const uint64_t end_code = base + span * static_cast<uint64_t>(c + 1);
      const size_t end = static_cast<size_t>(
          std::lower_bound(codes_.begin() + static_cast<std::ptrdiff_t>(begin),
                           codes_.begin() + static_cast<std::ptrdiff_t>(hi), end_code) - codes_.begin());
      if (end > begin) {
        child[c] = build(begin, end, childCorner(corner, c, level - 1), level - 1);
        present[c] = true;
      }
      begin = end;
    }
    const int32_t half = 1 << (level - 1);
    // Faces meeting inside the node: children that differ in one axis.
    for (int a = 0; a < 3; ++a) {
      const int32_t mid = coord(corner, a) + half;
      for (int c = 0; c < 8; ++c) {
        const int d = c | (1 << a);
        if (bit(c, a) || !present[c] || !present[d]) continue;
        const Face& f1 = child[c][2 * a + 1];
        const Face& f2 = child[d][2 * a];
        if (f1.plane == mid && f2.plane == mid) matchSquares(f1.square, f2.square);
      }
    }
    if (conn_ != Connectivity::Face) matchEdges(child, present, corner, half);
    if (conn_ == Connectivity::Vertex) matchVertex(child, present, corner, half);

    Box box;
    for (int a = 0; a < 3; ++a) {
      for (int s = 0; s < 2; ++s) {
        box[2 * a + s] = combineFaces(child, present, corner, level, a, s);
      }
    }
    return box;
  }

  Box leafBox(size_t i, const VoxelKey& corner, int level) const {
    Box box;
    const int32_t size = 1 << level;
    for (int a = 0; a < 3; ++a) {
      for (int s = 0; s < 2; ++s) {
        Face& f = box[2 * a + s];
        f.square = Square{static_cast<uint32_t>(i) | kLeafBit, coord(corner, uAxis(a)), coord(corner, vAxis(a)), size};
        f.plane = coord(corner, a) + s * size;
      }
    }
    return box;
  }

  // The parent's face on side s of axis a: the children's faces that lie in that plane.
  Face combineFaces(const std::array<Box, 8>& child, const std::array<bool, 8>& present, const VoxelKey& corner,
                    int level, int a, int s) {
    Face out;
    out.plane = coord(corner, a) + s * (1 << level);
    std::array<Square, 4> quads{};
    int count = 0, only = -1;
    for (int c = 0; c < 8; ++c) {
      if (bit(c, a) != s || !present[c]) continue;
      const Face& f = child[c][2 * a + s];
      if (f.square.ref == kNone || f.plane != out.plane) continue;
      quads[bit(c, uAxis(a)) | (bit(c, vAxis(a)) << 1)] = f.square;
      ++count;
      only = bit(c, uAxis(a)) | (bit(c, vAxis(a)) << 1);
    }
    if (count == 0) return out;
    if (count == 1) {
      out.square = quads[only];
      return out;
    }
    quads_.push_back(quads);
    out.square = Square{static_cast<uint32_t>(quads_.size() - 1), coord(corner, uAxis(a)), coord(corner, vAxis(a)),
                        1 << level};
    return out;
  }

  // Whether cells in squares s and t on either side of a plane can be neighbours under the
  // connectivity: they overlap (share a face), share an edge in the plane, or a corner.
  bool touches(const Square& s, const Square& t) const {
    const bool open_u = s.u0 < t.u0 + t.size && t.u0 < s.u0 + s.size;
    const bool open_v = s.v0 < t.v0 + t.size && t.v0 < s.v0 + s.size;
    const bool closed_u = s.u0 <= t.u0 + t.size && t.u0 <= s.u0 + s.size;
    const bool closed_v = s.v0 <= t.v0 + t.size && t.v0 <= s.v0 + s.size;
    switch (conn_) {
      case Connectivity::Face: return open_u && open_v;
      case Connectivity::Edge: return (open_u && closed_v) || (closed_u && open_v);
      case Connectivity::Vertex: return closed_u && closed_v;
    }
    return false;
  }

  // Algorithm 2 (MatchFaces), generalised to squares of any size and position.
  void matchSquares(const Square& s, const Square& t) {
    if (s.ref == kNone || t.ref == kNone || !touches(s, t)) return;
    const bool s_leaf = (s.ref & kLeafBit) != 0, t_leaf = (t.ref & kLeafBit) != 0;
    if (s_leaf && t_leaf) {
      join(s.ref & ~kLeafBit, t.ref & ~kLeafBit);
      return;
    }
    if (!s_leaf && (t_leaf || s.size >= t.size)) {
      const std::array<Square, 4>& q = quads_[s.ref];  // quads_ does not grow while matching
      for (const Square& part : q) matchSquares(part, t);
    } else {
      const std::array<Square, 4>& q = quads_[t.ref];
      for (const Square& part : q) matchSquares(s, part);
    }
  }

  // Cells of a face square that touch the line where in-plane coordinate `dim` (0: u, 1: v)
  // equals `line`, from below (high = true: the cell ends there) or above; appended as
  // intervals along the other in-plane coordinate, in increasing order.
  struct Interval {
    int32_t w0, len;
    uint32_t cell;
  };
  void collectLine(const Square& s, int dim, int32_t line, bool high, std::vector<Interval>& out) const {
    if (s.ref == kNone) return;
    const int32_t lo = dim == 0 ? s.u0 : s.v0;
    if (line < lo || line > lo + s.size) return;
    if (s.ref & kLeafBit) {
      if ((high && lo + s.size == line) || (!high && lo == line)) {
        out.push_back(Interval{dim == 0 ? s.v0 : s.u0, s.size, s.ref & ~kLeafBit});
      }
      return;
    }
    // Quadrants in increasing order of the other coordinate (bit 1 - dim of the index).
    const std::array<Square, 4>& q = quads_[s.ref];
    const int step = dim == 0 ? 2 : 1, side = dim == 0 ? 1 : 2;
    for (int w = 0; w < 2; ++w) {
      for (int b = 0; b < 2; ++b) collectLine(q[w * step + b * side], dim, line, high, out);
    }
  }

  void matchIntervals(const std::vector<Interval>& p, const std::vector<Interval>& q) {
    const bool closed = conn_ == Connectivity::Vertex;
    size_t start = 0;
    for (const Interval& a : p) {
      while (start < q.size() && (closed ? q[start].w0 + q[start].len < a.w0 : q[start].w0 + q[start].len <= a.w0)) {
        ++start;
      }
      for (size_t j = start; j < q.size(); ++j) {
        const Interval& b = q[j];
        if (closed ? b.w0 > a.w0 + a.len : b.w0 >= a.w0 + a.len) break;
        join(a.cell, b.cell);
      }
    }
  }

  // Edges meeting inside the node: children that differ in two axes share a line.
  void matchEdges(const std::array<Box, 8>& child, const std::array<bool, 8>& present, const VoxelKey& corner,
                  int32_t half) {
    std::vector<Interval> p, q;
    for (int a = 0; a < 3; ++a) {
      const int b = uAxis(a);  // the pair of axes (a, b); the line runs along the third
      for (int c = 0; c < 8; ++c) {
        const int d = c ^ (1 << a) ^ (1 << b);
        if (bit(c, a) || !present[c] || !present[d]) continue;
        const int32_t mid_a = coord(corner, a) + half, mid_b = coord(corner, b) + half;
        // Cells of c on its high-a face, touching the b line from c's side; same for d.
        const Face& fc = child[c][2 * a + 1];
        const Face& fd = child[d][2 * a];
        if (fc.plane != mid_a || fd.plane != mid_a) continue;
        p.clear();
        q.clear();
        collectLine(fc.square, 0, mid_b, bit(c, b) == 0, p);  // b is the face's u axis
        collectLine(fd.square, 0, mid_b, bit(d, b) == 0, q);
        auto by_start = [](const Interval& x, const Interval& y) { return x.w0 < y.w0; };
        std::sort(p.begin(), p.end(), by_start);
        std::sort(q.begin(), q.end(), by_start);
        matchIntervals(p, q);
      }
    }
  }

  // The cell of a face square whose corner is the point (u, v), approached from the given sides.
  uint32_t cornerCell(const Square& s, int32_t u, int32_t v, bool high_u, bool high_v) const {
    if (s.ref == kNone) return kNone;
    if (u < s.u0 || u > s.u0 + s.size || v < s.v0 || v > s.v0 + s.size) return kNone;
    if (s.ref & kLeafBit) {
      const bool ok_u = high_u ? s.u0 + s.size == u : s.u0 == u;
      const bool ok_v = high_v ? s.v0 + s.size == v : s.v0 == v;
      return ok_u && ok_v ? (s.ref & ~kLeafBit) : kNone;
    }
    for (const Square& part : quads_[s.ref]) {
      const uint32_t found = cornerCell(part, u, v, high_u, high_v);
      if (found != kNone) return found;
    }
    return kNone;
  }

  // The centre point: children that differ in all three axes.
  void matchVertex(const std::array<Box, 8>& child, const std::array<bool, 8>& present, const VoxelKey& corner,
                   int32_t half) {
    const int32_t mx = coord(corner, 0) + half, my = coord(corner, 1) + half, mz = coord(corner, 2) + half;
    auto centreCell = [&](int c) {
      const Face& f = child[c][2 * 0 + (1 - bit(c, 0))];
      if (f.plane != mx) return kNone;
      return cornerCell(f.square, my, mz, bit(c, 1) == 0, bit(c, 2) == 0);
    };
    for (int c = 0; c < 4; ++c) {
      const int d = 7 - c;
      if (!present[c] || !present[d]) continue;
      const uint32_t i = centreCell(c), j = centreCell(d);
      if (i != kNone && j != kNone) join(i, j);
    }
  }

  const DiffMap& diff_;
  const std::vector<uint32_t>& sel_;
  Connectivity conn_;
  UnionFind& uf_;
  JoinRule rule_;
  std::vector<uint64_t> codes_;
  std::vector<std::array<Square, 4>> quads_;
};

}  // namespace

Segmentation segment(const DiffMap& diff, const SegmentSettings& settings) {
  settings.validate();
  const std::vector<uint32_t> sel = selectCells(diff, settings);
  UnionFind uf(sel.size());
  BoxSegmenter(diff, sel, settings, uf).run();
  return collect(diff, sel, uf, settings);
}

Segmentation segmentByFloodFill(const DiffMap& diff, const SegmentSettings& settings) {
  settings.validate();
  const std::vector<uint32_t> sel = selectCells(diff, settings);
  // Every unit voxel of every selected cell, by Morton code.
  std::unordered_map<uint64_t, uint32_t> owner;
  for (uint32_t i = 0; i < sel.size(); ++i) {
    const ChangeCell& c = diff.cells()[sel[i]];
    const uint64_t first = mortonEncode(c.key), n = uint64_t{1} << (3 * c.level);
    for (uint64_t k = 0; k < n; ++k) owner.emplace(first + k, i);
  }
  const int max_nonzero = settings.connectivity == Connectivity::Face ? 1
                          : settings.connectivity == Connectivity::Edge ? 2
                                                                        : 3;
  const JoinRule rule{diff, sel, settings.colour_tolerance};
  UnionFind uf(sel.size());
  std::vector<uint32_t> label(sel.size(), kNone);
  std::vector<uint32_t> queue;
  for (uint32_t seed = 0; seed < sel.size(); ++seed) {
    if (label[seed] != kNone) continue;
    label[seed] = seed;
    queue.assign(1, seed);
    while (!queue.empty()) {
      const uint32_t i = queue.back();
      queue.pop_back();
      const ChangeCell& c = diff.cells()[sel[i]];
      const uint64_t first = mortonEncode(c.key), n = uint64_t{1} << (3 * c.level);
      for (uint64_t k = 0; k < n; ++k) {
        const VoxelKey v = mortonDecode(first + k);
        for (int dz = -1; dz <= 1; ++dz) {
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              const int nonzero = (dx != 0) + (dy != 0) + (dz != 0);
              if (nonzero == 0 || nonzero > max_nonzero) continue;
              const auto neighbour = offsetKey(v, dx, dy, dz);
              if (!neighbour) continue;
              const auto it = owner.find(mortonEncode(*neighbour));
              if (it == owner.end()) continue;
              const uint32_t j = it->second;
              if (label[j] != kNone || !rule(i, j)) continue;
              label[j] = seed;
              uf.join(seed, j);
              queue.push_back(j);
            }
          }
        }
      }
    }
  }
  return collect(diff, sel, uf, settings);
}

DiffMap componentDiff(const DiffMap& diff, const Component& component) {
  std::vector<ChangeCell> cells;
  cells.reserve(component.cells.size());
  for (uint32_t i : component.cells) cells.push_back(diff.cells()[i]);
  return DiffMap::fromCells(diff.resolution_m(), diff.settings(), std::move(cells));
}

}  // namespace chronomap
