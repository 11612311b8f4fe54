#include "chronomap/core/counters.h"

namespace chronomap {

const char* toString(VoxelState state) {
  switch (state) {
    case VoxelState::Unknown:
      return "unknown";
    case VoxelState::Free:
      return "free";
    case VoxelState::Occupied:
      return "occupied";
  }
  return "invalid";
}

}  // namespace chronomap
