#pragma once
/// @file
/// The depth-first walk shared by chronomap's pooled octrees (session maps and 4D maps).

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "chronomap/core/key.h"

namespace chronomap {

/// Walks a tree stored as a pool of inner nodes, each 8 child references: 0xFFFFFFFF (no
/// child), an inner node index, or `terminal_bit | index` (a leaf or list of the owning tree).
/// Node 0 is the root, spanning kTreeDepth levels. Visits children in slot order, which is the
/// Morton order of their corners; calls on_terminal(ref, corner, level) for every terminal
/// child (level: 2^level voxels per axis) and enters an inner child only when descend(index) is
/// true. @return the number of inner nodes entered, the root included.
template <class Children, class Descend, class OnTerminal>
size_t walkPoolTree(const std::vector<Children>& inner, uint32_t terminal_bit, Descend&& descend,
                    OnTerminal&& on_terminal) {
  constexpr uint32_t kNoChild = 0xffffffffu;
  struct Item {
    uint32_t node;
    int child_level;
    VoxelKey base;
    int next;
  };
  std::array<Item, kTreeDepth + 1> stack;
  int top = 0;
  stack[0] = Item{0, kTreeDepth - 1, VoxelKey{}, 0};
  size_t entered = 1;
  while (top >= 0) {
    Item& it = stack[top];
    if (it.next == 8) {
      --top;
      continue;
    }
    const int slot = it.next++;
    const uint32_t r = inner[it.node][slot];
    if (r == kNoChild) continue;
    const VoxelKey k = childCorner(it.base, slot, it.child_level);
    if ((r & terminal_bit) != 0) {
      on_terminal(r, k, it.child_level);
    } else if (descend(r)) {
      stack[top + 1] = Item{r, it.child_level - 1, k, 0};
      ++top;
      ++entered;
    }
  }
  return entered;
}

}  // namespace chronomap
