#include "chronomap/io/colour_file.h"

#include "chronomap/io/file.h"

namespace chronomap::io {

void writeColourModel(const std::filesystem::path& path, const ColourModel& model) {
  writeFileAtomic(path, serialize(model));
}

ColourModel readColourModel(const std::filesystem::path& path) {
  return readNamingMemory(path, [&] { return deserializeColour(readFileBytes(path), path.string()); });
}

}  // namespace chronomap::io
