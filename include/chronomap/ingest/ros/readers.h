#pragma once
// Registers the ROS bag readers ("rosbag": ROS 1 through librosbag; "ros2bag": MCAP and .db3
// storage) with ingest's registry (ingest/registry.h). chronomap_ingest_ros is the only target
// that links librosbag, SQLite and lz4; the pipeline calls this before it opens a recording, and
// a program that calls openDataset on bags itself calls it once first.

namespace chronomap {

/// Adds the bag readers after the built-in ones; safe to call any number of times, from any thread.
void registerRosReaders();

}  // namespace chronomap
