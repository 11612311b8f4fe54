#pragma once
// The ROS 1 bag reader behind openDataset; librosbag's headers stay in rosbag1.cpp.

#include <filesystem>
#include <memory>
#include <vector>

#include "chronomap/ingest/dataset.h"
#include "chronomap/ingest/ros/rosbag.h"

namespace chronomap {

/// @throw UsageError for topics that do not fit, DataError / FormatError naming the bag.
std::unique_ptr<Dataset> openRosBag(const std::filesystem::path& path, const DatasetSettings& settings);
/// The topics of a ROS 1 bag (listBag dispatches here). @throw as listBag.
std::vector<BagTopic> listRosBag1(const std::filesystem::path& path);

}  // namespace chronomap

namespace chronomap {

/// Walks every record of a ROS 1 bag (format 2.0), decompressing each chunk, and checks what
/// librosbag trusts without checking: record and header lengths inside the file and inside each
/// chunk, the chunk's stated uncompressed size, and that every index entry points at a message
/// record of its chunk. librosbag reads past its buffers on such input (found by fuzz_bag).
/// Returns where the bag stores the time 0 in its indexes: librosbag drops such index entries
/// when it opens a bag ("contains invalid time"), so that messages recorded at time 0
/// (simulated time before /clock, a latched /tf_static) would be invisible.
/// @throw FormatError naming the file, the record's offset and the problem.
struct BagStructure {
  std::vector<uint64_t> zero_times;  ///< file offsets of 8-byte times (sec, nsec) that are 0
  size_t zero_time_messages = 0;     ///< index entries among them (messages at time 0)
};
BagStructure checkBagStructure(const std::filesystem::path& path);

}  // namespace chronomap
