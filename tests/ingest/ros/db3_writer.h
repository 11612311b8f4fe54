#pragma once
// rosbag2's SQLite storage written by the project's test code (no ROS 2 library): the bag tests'
// .db3 bags and fuzz_db3's seeds hold the CDR messages of MCAP bags from the npm writer.

#include <filesystem>
#include <map>
#include <string>

namespace chronomap::test {

/// Copies the messages of an MCAP bag into a rosbag2 SQLite bag with rosbag2's schema (tables
/// schema, topics and messages, as rosbag2's sqlite3 storage version 4 writes them); `formats`
/// overrides a topic's serialisation format. @throw std::runtime_error naming what failed.
void writeDb3(const std::filesystem::path& mcap, const std::filesystem::path& db3,
              const std::map<std::string, std::string>& formats = {});

}  // namespace chronomap::test
