#include "chronomap/ingest/registry.h"

#include <algorithm>
#include <mutex>

#include "chronomap/core/error.h"
#include "readers.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

/// The registry: the built-in readers in detection order, then those registered at run time.
struct Registry {
  std::mutex mutex;
  std::vector<DatasetReader> readers{
      readers::tum(),
      readers::threeDMatch(),
      readers::scanNet(),
      readers::clouds(),
      readers::dynamicMap(),
  };
};

Registry& registry() {
  static Registry instance;
  return instance;
}

/// The readers' names in order, "a, b, c", or "a, b or c" with `or_last`.
std::string namesOf(const std::vector<DatasetReader>& readers, bool or_last) {
  std::string names;
  for (size_t i = 0; i < readers.size(); ++i) {
    if (i > 0) names += or_last && i + 1 == readers.size() ? " or " : ", ";
    names += readers[i].name;
  }
  return names;
}

bool answersTo(const DatasetReader& reader, const std::string& name) {
  return reader.name == name || std::find(reader.aliases.begin(), reader.aliases.end(), name) != reader.aliases.end();
}

}  // namespace

std::vector<DatasetReader> datasetReaders() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  return r.readers;
}

bool registerDatasetReader(DatasetReader reader) {
  if (reader.name.empty() || !reader.recognises || !reader.open) {
    throw UsageError("a dataset reader needs a name, a recognise function and an open function");
  }
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  for (const DatasetReader& known : r.readers) {
    if (answersTo(known, reader.name)) return false;
    for (const std::string& alias : reader.aliases) {
      if (answersTo(known, alias)) return false;
    }
  }
  r.readers.push_back(std::move(reader));
  return true;
}

std::optional<DatasetReader> findDatasetReader(const std::string& name) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  for (const DatasetReader& reader : r.readers) {
    if (answersTo(reader, name)) return reader;
  }
  return std::nullopt;
}

DatasetReader datasetReaderNamed(const std::string& name) {
  if (auto reader = findDatasetReader(name)) return std::move(*reader);
  throw UsageError("unknown dataset format '" + name + "' (expected auto, " + namesOf(datasetReaders(), true) + ")");
}

std::string parseDatasetFormat(const std::string& name) { return name == "auto" ? name : datasetReaderNamed(name).name; }

DatasetReader detectDatasetReader(const fs::path& path) {
  const std::vector<DatasetReader> readers = datasetReaders();
  for (const DatasetReader& reader : readers) {
    if (reader.recognises(path)) return reader;
  }
  std::error_code ec;
  const std::string what = fs::is_directory(path, ec) ? "folder" : "file";
  throw UsageError(path.string() + ": cannot tell the dataset format: no reader (" + namesOf(readers, false) + ") recognises this " +
                   what + "; `chronomap integrate --list-formats` says what each looks for; use --format");
}

}  // namespace chronomap
