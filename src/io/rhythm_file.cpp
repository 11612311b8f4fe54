#include "chronomap/io/rhythm_file.h"

#include "chronomap/io/file.h"

namespace chronomap::io {

void writeRhythmModels(const std::filesystem::path& path, const RhythmModels& models) {
  writeFileAtomic(path, serialize(models));
}

RhythmModels readRhythmModels(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return deserializeRhythm(readFileBytes(path), path.string()); });
}

}  // namespace chronomap::io
