#pragma once
// The registry of readers: every layout or file format chronomap reads recordings from, by name.
// openDataset, --format, `chronomap integrate --list-formats` and the Python package all ask it,
// so a new reader is one file (its open and recognise functions) and one line in registry.cpp
// (or one registerDatasetReader call from a target of its own, as ingest/ros does).

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "chronomap/ingest/dataset.h"

namespace chronomap {

/// One reader of other people's recordings.
struct DatasetReader {
  /// What --format takes and Dataset::format() gives: "tum", "3dmatch", ...
  std::string name;
  /// Other names --format accepts for it ("7scenes" for "3dmatch").
  std::vector<std::string> aliases;
  /// One line for people: what it reads and how it is recognised.
  std::string description;
  /// Whether `path` is this reader's input; detection asks the readers in registry order and
  /// takes the first that says yes. Must not throw for paths that exist.
  bool (*recognises)(const std::filesystem::path& path) = nullptr;
  /// Opens `path`, checking first that it is this reader's kind of input (a folder or a file).
  /// @throw UsageError for input of the wrong kind; DataError / FormatError naming the file.
  std::unique_ptr<Dataset> (*open)(const std::filesystem::path& path, const DatasetSettings& settings) = nullptr;
  /// Whether DatasetSettings::pose (--pose) applies: only to a single cloud.
  bool takes_pose = false;
};

/// Every registered reader, in detection order: the built-in ones, then those registered since.
std::vector<DatasetReader> datasetReaders();

/// Adds a reader after the others (a target of its own, such as ingest/ros, calls this).
/// Registering a name or alias that is already taken replaces nothing and returns false.
bool registerDatasetReader(DatasetReader reader);

/// The reader of that name or alias, or nullopt.
std::optional<DatasetReader> findDatasetReader(const std::string& name);

/// The reader of that name or alias.
/// @throw UsageError for a name no registered reader has, listing the names there are.
DatasetReader datasetReaderNamed(const std::string& name);

/// The first reader that recognises `path`.
/// @throw UsageError when none does, saying what was looked for and to use --format.
DatasetReader detectDatasetReader(const std::filesystem::path& path);

}  // namespace chronomap
