// libFuzzer targets for every reader. One source, one target per reader (FUZZ_TARGET picks it).
// A reader may reject input only with a chronomap::Error; anything else (a crash, a sanitizer
// report, another exception) is a bug.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/io/cloud_io.h"
#include "chronomap/io/cmap.h"
#include "chronomap/io/temporal_file.h"
#include "chronomap/io/diff_file.h"
#include "chronomap/align/consensus.h"
#include "chronomap/align/realign.h"
#include "chronomap/analysis/segment.h"
#include "chronomap/io/dataset.h"
#include "chronomap/io/jpeg.h"
#include "chronomap/io/png.h"

namespace {

using namespace chronomap;

void fuzzOne(const std::vector<uint8_t>& bytes) {
  const std::string name = "fuzz-input";
#if defined(FUZZ_CMAP)
  const io::CmapFile file = io::decodeCmap(bytes, name);
  if (file.header.kind == io::MapKind::Session) {
    const SessionMap map = io::sessionMapFrom(file, name);
    volatile size_t leaves = map.counts().leaves;
    (void)leaves;
    map.find(VoxelKey{32768, 32768, 32768});
    // A session map that reads must also merge and re-align against itself.
    const SessionMap* both[] = {&map, &map};
    const SessionMap avg = consensus(std::span<const SessionMap* const>(both));
    volatile size_t moved = realign(map, avg).leafCount();
    (void)moved;
  } else if (file.header.kind == io::MapKind::Temporal) {
    // A 4D map that reads must also answer queries without crashing.
    TemporalMap map = io::temporalMapFrom(file, name);
    if (map.sessionCount() > 0) {
      const SessionMap snap = map.snapshot(map.sessions().back().time_s);
      volatile size_t leaves = snap.leafCount();
      (void)leaves;
    }
    map.history(VoxelKey{32768, 32768, 32768});
    if (map.sessionCount() > 0) {
      volatile size_t leaves = consensus(map, map.sessions().front().time_s, map.sessions().back().time_s).leafCount();
      (void)leaves;
    }
    if (map.sessionCount() > 1) {
      volatile size_t cells = diff(map, map.sessions().front().time_s, map.sessions().back().time_s).cells().size();
      (void)cells;
    }
    map.compact();
  } else if (file.header.kind == io::MapKind::Diff) {
    // A diff that reads must also segment without crashing.
    const DiffMap d = io::diffMapFrom(file, name);
    SegmentSettings s;
    s.connectivity = Connectivity::Vertex;
    volatile size_t n = segment(d, s).components.size();
    (void)n;
  }
  io::metadataOf(file);
#elif defined(FUZZ_PCD)
  io::parsePcd(bytes, name);
#elif defined(FUZZ_PLY)
  io::parsePly(bytes, name);
#elif defined(FUZZ_XYZ)
  io::parseXyz(std::string(bytes.begin(), bytes.end()), name);
#elif defined(FUZZ_PNG)
  // Colour frames: PNG or JPEG, as readColorImage tells them apart; depth is PNG only.
  if (io::looksLikeJpeg(bytes)) {
    io::decodeJpegRgb(bytes, name);
    return;
  }
  try {
    io::decodePngRgb(bytes, name);
  } catch (const Error&) {
  }
  io::decodePngU16(bytes, name);
#elif defined(FUZZ_TEXT)
  // The first byte picks the format, the rest is the text.
  if (bytes.empty()) return;
  const std::string text(bytes.begin() + 1, bytes.end());
  switch (bytes[0] % 5) {
    case 0: io::parseIntrinsicsText(text, name); break;
    case 1: chronomap::io::parseMatrix4(text, name); break;
    case 2: io::parseStampedList(text, name); break;
    case 3: io::parseTumTrajectory(text, name); break;
    default: io::parseCloudList(text, name); break;
  }
#else
#error "define one FUZZ_* target"
#endif
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    fuzzOne(std::vector<uint8_t>(data, data + size));
  } catch (const chronomap::Error&) {
    // Rejected with a clear error: the expected outcome for bad input.
  }
  return 0;
}
