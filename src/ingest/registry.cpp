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
  };
};

Registry& registry() {
  static Registry instance;
  return instance;
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

DatasetReader detectDatasetReader(const fs::path& path) {
  const std::vector<DatasetReader> readers = datasetReaders();
  for (const DatasetReader& reader : readers) {
    if (reader.recognises(path)) return reader;
  }
  std::string names;
  for (const DatasetReader& reader : readers) names += (names.empty() ? "" : ", ") + reader.name;
  std::error_code ec;
  const std::string what = fs::is_directory(path, ec) ? "folder" : "file";
  throw UsageError(path.string() + ": cannot tell the dataset format: no reader (" + names + ") recognises this " +
                   what + "; `chronomap integrate --list-formats` says what each looks for; use --format");
}

}  // namespace chronomap
