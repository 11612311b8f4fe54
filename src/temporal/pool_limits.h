#pragma once
/// @file
/// Internal to the temporal module: the sizes TemporalMap's pools and history lists may reach.
/// pools.cpp allocates within them; fromParts() refuses files beyond them.

#include <cstddef>
#include <cstdint>

namespace chronomap::temporal_detail {

/// Most inner nodes, list records, arena entries or hit parts (indices keep the list bit free).
inline constexpr uint32_t kMaxIndex = 0x7ffffff0u;
/// Most entries in one history list (its size is 16 bits).
inline constexpr size_t kMaxListSize = 0xffff;

}  // namespace chronomap::temporal_detail
