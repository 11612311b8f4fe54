#include "chronomap/octree/session_map.h"

#include <algorithm>
#include <bit>
#include <string>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {
constexpr uint32_t kMaxPoolIndex = 0x7ffffffeu;
constexpr uint32_t kMaxLeafIndex = 0x3ffffffeu;  // below the free-leaf bit

/// Makes room for one more node in a full pool by growing it 4x, not 2x: each growth copies the
/// pool into fresh pages (page faults, then freeing the old ones), and integration at 0.02 m
/// grows the pools to 90 MiB before compression. 4x copies a third as much and faults in about
/// 60% as many pages: merging a synthetic 640x480 frame took 6.6-7.2 ms instead of 8.8-12.6 ms
/// (CPU, 30 frames). The capacity beyond the size is address space that no page backs until it
/// is written; the integrator's memory check counts at most 2x the size of it (integrator.cpp).
template <class T>
void roomForOne(std::vector<T>& pool) {
  if (pool.size() == pool.capacity()) pool.reserve(std::max<size_t>(4 * pool.size(), 64));
}

SessionMap::Children emptyChildren() {
  SessionMap::Children c;
  c.fill(SessionMap::kEmpty);
  return c;
}
}  // namespace

SessionMap::SessionMap(double resolution_m) : grid_(resolution_m) { inner_.push_back(emptyChildren()); }

bool SessionMap::freeOnly(const VoxelCounters& c) {
  return (c.hits | c.red | c.green | c.blue | std::bit_cast<uint32_t>(c.offset[0]) |
          std::bit_cast<uint32_t>(c.offset[1]) | std::bit_cast<uint32_t>(c.offset[2])) == 0;
}

SessionMap::Ref SessionMap::newLeaf(const VoxelCounters& c) {
  if (freeOnly(c)) {
    if (free_.size() >= kMaxLeafIndex) throw Error("session map is full: more than 2^30 free leaves");
    roomForOne(free_);
    free_.push_back(c.length_m);
    return static_cast<Ref>(free_.size() - 1) | kLeafBit | kFreeBit;
  }
  if (leaves_.size() >= kMaxLeafIndex) throw Error("session map is full: more than 2^30 leaves");
  roomForOne(leaves_);
  leaves_.push_back(c);
  return static_cast<Ref>(leaves_.size() - 1) | kLeafBit;
}

void SessionMap::addToLeaf(Ref& ref, const VoxelCounters& delta) {
  if (!isFreeLeaf(ref)) {
    leaves_[index(ref)] += delta;
  } else if (freeOnly(delta)) {
    free_[index(ref)] += delta.length_m;
  } else {
    // The same additions as in the full pool: the other counters start at zero.
    VoxelCounters c;
    c.length_m = free_[index(ref)];
    c += delta;
    ref = newLeaf(c);  // the free slot stays behind until compressFree()
    ++moved_;
  }
}

void SessionMap::setLeaf(Ref& ref, const VoxelCounters& c) {
  if (!isFreeLeaf(ref)) {
    leaves_[index(ref)] = c;
  } else if (freeOnly(c)) {
    free_[index(ref)] = c.length_m;
  } else {
    ref = newLeaf(c);
    ++moved_;
  }
}

SessionMap::Ref SessionMap::newInner() {
  if (inner_.size() >= kMaxPoolIndex) throw Error("session map is full: more than 2^31 inner nodes");
  roomForOne(inner_);
  inner_.push_back(emptyChildren());
  return static_cast<Ref>(inner_.size() - 1);
}

uint32_t SessionMap::splitLeaf(uint32_t parent, int slot) {
  Ref first = inner_[parent][slot];
  VoxelCounters part = leaf(first);
  part.length_m /= 8.0f;  // compressed leaves never hold hits or colour
  const Ref node = newInner();
  // The first child reuses the old leaf's slot so that splitting does not grow the pool by 8.
  setLeaf(first, part);
  inner_[node][0] = first;
  for (int i = 1; i < 8; ++i) {
    const Ref child = newLeaf(part);
    inner_[node][i] = child;
  }
  inner_[parent][slot] = node;
  return node;
}

uint32_t SessionMap::descend(uint32_t parent, int slot) {
  const Ref r = inner_[parent][slot];
  if (r == kEmpty) {
    const Ref node = newInner();
    inner_[parent][slot] = node;
    return node;
  }
  if (isLeaf(r)) return splitLeaf(parent, slot);
  return r;
}

void SessionMap::add(const VoxelKey& key, const VoxelCounters& delta) {
  addMany(std::span<const VoxelKey>(&key, 1), std::span<const VoxelCounters>(&delta, 1));
}

namespace {

/// The inner nodes on the way to the previous key walked: keys in raster or Morton order share
/// most of their path, so each walk descends only from their deepest common ancestor.
class KeyPath {
 public:
  /// The inner node of level `level + 1` that holds `key`'s node of `level` (`key` aligned to
  /// it), made on the way by `descend(parent, slot)`.
  template <class Descend>
  uint32_t parentOf(const VoxelKey& key, int level, Descend&& descend) {
    int from = kTreeDepth;  // level of the deepest common ancestor still valid in node_
    if (have_prev_) {
      const uint32_t diff = static_cast<uint32_t>((key.x ^ prev_.x) | (key.y ^ prev_.y) | (key.z ^ prev_.z));
      from = diff == 0 ? level + 1 : std::bit_width(diff);
    }
    for (int l = from; l > level + 1; --l) node_[l - 1] = descend(node_[l], childSlot(key, l - 1));
    prev_ = key;
    have_prev_ = true;
    return node_[level + 1];
  }

 private:
  std::array<uint32_t, kTreeDepth + 1> node_{};  // node_[l]: the inner node at level l; node_[kTreeDepth] = 0, the root
  VoxelKey prev_{};
  bool have_prev_ = false;
};

}  // namespace

void SessionMap::addMany(std::span<const VoxelKey> keys, std::span<const VoxelCounters> deltas) {
  if (keys.size() != deltas.size()) throw UsageError("addMany: keys and deltas differ in length");
  KeyPath path;
  const auto down = [this](uint32_t parent, int slot) { return descend(parent, slot); };
  for (size_t i = 0; i < keys.size(); ++i) {
    const VoxelKey& key = keys[i];
    const uint32_t node = path.parentOf(key, 0, down);
    const int slot = childSlot(key, 0);
    Ref& r = inner_[node][slot];  // newLeaf() grows the leaf pools only: r stays valid
    if (r == kEmpty) {
      r = newLeaf(deltas[i]);
    } else {
      addToLeaf(r, deltas[i]);
    }
  }
}

void SessionMap::spreadInto(uint32_t parent, int slot, int level, const VoxelCounters& sums) {
  const Ref r = inner_[parent][slot];
  if (r == kEmpty) {
    const Ref leaf = newLeaf(sums);
    inner_[parent][slot] = leaf;
  } else if (isLeaf(r)) {
    addToLeaf(inner_[parent][slot], sums);  // a leaf of the cube's own size
  } else {
    VoxelCounters part = sums;  // level > 0: a known-free cube without hits
    part.length_m /= 8.0f;
    for (int i = 0; i < 8; ++i) spreadInto(r, i, level - 1, part);
  }
}

void SessionMap::addCube(const VoxelKey& corner, int level, const VoxelCounters& sums) {
  if (level < 0 || level >= kTreeDepth) throw UsageError("addCube: level " + std::to_string(level) + " out of range");
  const uint32_t low = (1u << level) - 1;
  if (((corner.x | corner.y | corner.z) & low) != 0) throw UsageError("addCube: corner not aligned to the cube");
  if (level > 0 && ((sums.hits | sums.red | sums.green | sums.blue) != 0 || !sums.offsetsValid())) {
    throw UsageError("addCube: a cube above unit level must be known-free without hits");
  }
  if (level > 0 && sums.length_m <= 0.0f) return;  // an unobserved cube adds nothing
  uint32_t node = 0;
  for (int l = kTreeDepth; l > level + 1; --l) node = descend(node, childSlot(corner, l - 1));
  spreadInto(node, childSlot(corner, level), level, sums);
}

void SessionMap::addCubes(std::span<const VoxelKey> corners, int level, std::span<const float> lengths_m) {
  if (corners.size() != lengths_m.size()) throw UsageError("addCubes: corners and lengths differ in length");
  if (level < 1 || level >= kTreeDepth) throw UsageError("addCubes: level " + std::to_string(level) + " out of range");
  const uint32_t low = (1u << level) - 1;
  KeyPath path;
  const auto down = [this](uint32_t parent, int slot) { return descend(parent, slot); };
  for (size_t i = 0; i < corners.size(); ++i) {
    const VoxelKey& key = corners[i];
    if (((key.x | key.y | key.z) & low) != 0) throw UsageError("addCubes: corner not aligned to the cube");
    if (!(lengths_m[i] > 0.0f)) continue;
    VoxelCounters sums;
    sums.length_m = lengths_m[i];
    spreadInto(path.parentOf(key, level, down), childSlot(key, level), level, sums);
  }
}

void SessionMap::mergeInto(uint32_t parent, int slot, int level, const SessionMap& other, Ref src) {
  if (src == kEmpty) return;
  if (isLeaf(src)) {
    spreadInto(parent, slot, level, other.leaf(src));
    return;
  }
  const uint32_t node = descend(parent, slot);
  for (int i = 0; i < 8; ++i) mergeInto(node, i, level - 1, other, other.inner_[src][i]);
}

void SessionMap::merge(const SessionMap& other) {
  if (other.resolution_m() != resolution_m()) throw UsageError("merge: the maps have different resolutions");
  if (&other == this) {
    // Merging a map into itself reads what it writes: merge a snapshot of it instead.
    const SessionMap copy = other;  // NOLINT(performance-unnecessary-copy-initialization)
    merge(copy);
    return;
  }
  for (int i = 0; i < 8; ++i) mergeInto(0, i, kTreeDepth - 1, other, other.inner_[0][i]);
}

void SessionMap::assign(const VoxelKey& key, const std::optional<VoxelCounters>& value) {
  if (!value && !findLeaf(key)) return;  // already unknown
  uint32_t node = 0;
  for (int l = kTreeDepth; l > 1; --l) node = descend(node, childSlot(key, l - 1));
  const int slot = childSlot(key, 0);
  const Ref r = inner_[node][slot];
  if (!value) {
    inner_[node][slot] = kEmpty;  // the leaf stays behind as garbage until compressFree()
  } else if (r == kEmpty) {
    const Ref leaf = newLeaf(*value);
    inner_[node][slot] = leaf;
  } else {
    setLeaf(inner_[node][slot], *value);
  }
}

std::optional<LeafView> SessionMap::findLeaf(const VoxelKey& key) const {
  uint32_t node = 0;
  for (int child_level = kTreeDepth - 1; child_level >= 0; --child_level) {
    const Ref r = inner_[node][childSlot(key, child_level)];
    if (r == kEmpty) return std::nullopt;
    if (isLeaf(r)) {
      return LeafView{cellCorner(key, child_level), child_level, leaf(r)};
    }
    node = r;
  }
  return std::nullopt;  // unreachable for a valid tree: level 0 children are leaves
}

std::optional<VoxelCounters> SessionMap::find(const VoxelKey& key) const {
  auto leaf = findLeaf(key);
  if (!leaf) return std::nullopt;
  VoxelCounters c = leaf->counters;
  if (leaf->level > 0) c.length_m /= static_cast<float>(uint64_t{1} << (3 * leaf->level));
  return c;
}

VoxelState SessionMap::stateOf(const VoxelKey& key) const {
  auto c = find(key);
  return c ? c->state() : VoxelState::Unknown;
}

SessionMap::Ref SessionMap::pushLeaf(const VoxelCounters& c, std::vector<VoxelCounters>& leaves,
                                     std::vector<float>* free) {
  if (free && freeOnly(c)) {
    free->push_back(c.length_m);
    return static_cast<Ref>(free->size() - 1) | kLeafBit | kFreeBit;
  }
  leaves.push_back(c);
  return static_cast<Ref>(leaves.size() - 1) | kLeafBit;
}

SessionMap::Ref SessionMap::copyInto(Ref r, std::vector<Children>& inner, std::vector<VoxelCounters>& leaves,
                                     std::vector<float>* free) const {
  if (r == kEmpty) return kEmpty;
  if (isLeaf(r)) return pushLeaf(leaf(r), leaves, free);
  const Ref out = static_cast<Ref>(inner.size());
  inner.push_back(emptyChildren());
  for (int i = 0; i < 8; ++i) {
    const Ref c = copyInto(inner_[r][i], inner, leaves, free);
    inner[out][i] = c;
  }
  return out;
}

SessionMap::Ref SessionMap::compressInto(Ref r, std::vector<Children>& inner, std::vector<VoxelCounters>& leaves,
                                         std::vector<float>& free, bool& known_free) const {
  known_free = false;
  if (r == kEmpty) return kEmpty;
  if (isLeaf(r)) {
    const VoxelCounters c = leaf(r);
    known_free = c.isKnownFreeWithoutHits();
    return pushLeaf(c, leaves, &free);
  }
  const Ref out = static_cast<Ref>(inner.size());
  inner.push_back(emptyChildren());
  bool any = false, all_free = true;
  for (int i = 0; i < 8; ++i) {
    bool child_free = false;
    const Ref c = compressInto(inner_[r][i], inner, leaves, free, child_free);
    inner[out][i] = c;
    any = any || c != kEmpty;
    all_free = all_free && child_free;
  }
  if (all_free && r != 0) {  // the root is never replaced
    // The eight children are leaves, each the last its pool received when it was copied (a
    // child replaced in turn left one leaf behind): they make way for their sum.
    const Children children = inner[out];
    inner.pop_back();
    VoxelCounters sum;
    for (int i = 0; i < 8; ++i) {
      sum.length_m += isFreeLeaf(children[i]) ? free[index(children[i])] : leaves[index(children[i])].length_m;
    }
    for (int i = 7; i >= 0; --i) {
      if (isFreeLeaf(children[i])) {
        free.pop_back();
      } else {
        leaves.pop_back();
      }
    }
    known_free = true;  // eight positive lengths, no hits
    return pushLeaf(sum, leaves, &free);  // free-only: a length alone
  }
  if (!any && r != 0) {  // an inner node left without children (assign() emptied it)
    inner.pop_back();
    return kEmpty;
  }
  return out;
}

size_t SessionMap::compressFree() {
  const size_t before = leafCount();
  // One pass copies the reachable tree depth first into fresh pools, replacing free cubes as it
  // goes (it measured faster than a counting pass that replaced them in place followed by the
  // copy). The pools are reserved at the old ones' sizes, which bound the new ones (pages are
  // only touched as they are written), then cut to what they hold: growing them instead copied
  // them several times over. The cut copies the compacted pools once more; peak RSS of a whole
  // integration did not rise with it (the 3DMatch frames, fast, 6 m: 135.2 / 135.1 MB at 0.02 m,
  // 224.5 / 227.0 MB at 0.01 m, 570.7 / 558.6 MB at 0.005 m, counting pass / this). Capacity
  // left uncut would count against the memory limit (reservedBytes()).
  std::vector<Children> inner;
  std::vector<VoxelCounters> leaves;
  std::vector<float> free;
  inner.reserve(inner_.size());
  leaves.reserve(leaves_.size());
  free.reserve(leaves_.size() + free_.size());
  bool root_free = false;
  compressInto(0, inner, leaves, free, root_free);
  inner.shrink_to_fit();
  leaves.shrink_to_fit();
  free.shrink_to_fit();
  inner_ = std::move(inner);
  leaves_ = std::move(leaves);
  free_ = std::move(free);
  moved_ = 0;
  return before - leafCount();
}

SessionMap::Pools SessionMap::pools() const {
  Pools p;
  p.inner.reserve(inner_.size());
  p.leaves.reserve(leafCount());
  copyInto(0, p.inner, p.leaves, nullptr);
  return p;
}

void SessionMap::separateFree() {
  // Depth first, as compressFree() lays the pools out: a map read back has the layout of the
  // one written.
  // Every leaf of the pools is reachable (assignPools checked it): each pool is reserved exactly.
  const auto free_count = static_cast<size_t>(std::count_if(leaves_.begin(), leaves_.end(), freeOnly));
  std::vector<Children> inner;
  std::vector<VoxelCounters> leaves;
  std::vector<float> free;
  inner.reserve(inner_.size());
  leaves.reserve(leaves_.size() - free_count);
  free.reserve(free_count);
  copyInto(0, inner, leaves, &free);
  inner_ = std::move(inner);
  leaves_ = std::move(leaves);
  free_ = std::move(free);
  moved_ = 0;
}

SessionMapCounts SessionMap::counts() const {
  SessionMapCounts c;
  c.inner_nodes = inner_.size();
  forEachLeaf([&](const LeafView& leaf) {
    ++c.leaves;
    const uint64_t voxels = uint64_t{1} << (3 * leaf.level);
    if (leaf.level > 0) ++c.compressed_leaves;
    switch (leaf.counters.state()) {
      case VoxelState::Occupied:
        c.occupied_voxels += voxels;
        break;
      case VoxelState::Free:
        c.free_voxels += voxels;
        break;
      case VoxelState::Unknown:
        break;
    }
  });
  return c;
}

size_t SessionMap::memoryBytes() const {
  return sizeof(*this) + inner_.size() * sizeof(Children) + leaves_.size() * sizeof(VoxelCounters) +
         free_.size() * sizeof(float);
}

size_t SessionMap::reservedBytes() const {
  return sizeof(*this) + inner_.capacity() * sizeof(Children) + leaves_.capacity() * sizeof(VoxelCounters) +
         free_.capacity() * sizeof(float);
}

void SessionMap::assignPools(std::vector<Children> inner, std::vector<VoxelCounters> leaves) {
  if (inner.empty()) throw FormatError("session map has no root node");
  if (inner.size() > kMaxPoolIndex || leaves.size() > kMaxLeafIndex) throw FormatError("session map too large");
  // Every node must be reachable exactly once from the root, inner nodes only above unit level,
  // leaves finite and non-negative, compressed leaves free of hits.
  std::vector<uint8_t> inner_seen(inner.size(), 0);
  std::vector<uint8_t> leaf_seen(leaves.size(), 0);
  std::vector<std::pair<uint32_t, int>> stack{{0u, kTreeDepth}};
  inner_seen[0] = 1;
  size_t inner_reached = 1, leaves_reached = 0;
  while (!stack.empty()) {
    auto [node, level] = stack.back();
    stack.pop_back();
    for (Ref r : inner[node]) {
      if (r == kEmpty) continue;
      const uint32_t i = r & ~kLeafBit;  // a set free-leaf bit reads as an index past the end
      if (isLeaf(r)) {
        if (i >= leaves.size() || leaf_seen[i]) throw FormatError("session map has an invalid leaf reference");
        leaf_seen[i] = 1;
        ++leaves_reached;
        const VoxelCounters& c = leaves[i];
        if (!std::isfinite(c.length_m) || c.length_m < 0.0f) throw FormatError("session map has an invalid ray length");
        if (!c.offsetsValid()) throw FormatError("session map has an invalid hit position");
        if (level - 1 > 0 && !c.isKnownFreeWithoutHits()) {
          throw FormatError("session map has a compressed node that is not known-free");
        }
      } else {
        if (level - 1 == 0) throw FormatError("session map has an inner node below unit level");
        if (i >= inner.size() || inner_seen[i]) throw FormatError("session map has an invalid node reference");
        inner_seen[i] = 1;
        ++inner_reached;
        stack.emplace_back(i, level - 1);
      }
    }
  }
  if (inner_reached != inner.size() || leaves_reached != leaves.size()) {
    throw FormatError("session map has unreachable nodes");
  }
  inner_ = std::move(inner);
  leaves_ = std::move(leaves);
  separateFree();
}

bool operator==(const SessionMap& a, const SessionMap& b) {
  if (a.resolution_m() != b.resolution_m()) return false;
  // Compare leaf by leaf in Morton order: equal trees regardless of pool layout.
  std::vector<LeafView> la, lb;
  a.forEachLeaf([&](const LeafView& l) { la.push_back(l); });
  b.forEachLeaf([&](const LeafView& l) { lb.push_back(l); });
  if (la.size() != lb.size()) return false;
  for (size_t i = 0; i < la.size(); ++i) {
    if (la[i].key != lb[i].key || la[i].level != lb[i].level || !(la[i].counters == lb[i].counters)) return false;
  }
  return true;
}

}  // namespace chronomap
