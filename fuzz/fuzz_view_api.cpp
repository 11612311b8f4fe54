// libFuzzer target for the viewer's HTTP API (Api), which answers whatever a browser or
// another program on the machine sends: the input is "PATH?QUERY" (QUERY as name=value pairs
// joined by '&'), asked of a small 4D map. Every answer must be a page, a packet or a 4xx; a
// crash or an exception other than chronomap::Error is a finding.

#include <cstddef>
#include <cstdint>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/view/api.h"

namespace {

using namespace chronomap;

const TemporalMap& smallMap() {
  static const TemporalMap map = [] {
    TemporalMap m(0.05);
    for (int s = 0; s < 3; ++s) {
      SessionMap session(0.05);
      for (int i = 0; i < 64; ++i) {
        VoxelCounters c;
        c.length_m = 0.1f;
        if ((i + s) % 3 == 0) {
          c.hits = 4;
          c.red = 4 * 200;
        }
        session.add(VoxelKey{static_cast<uint16_t>(kKeyOrigin + i % 4), static_cast<uint16_t>(kKeyOrigin + (i / 4) % 4),
                             static_cast<uint16_t>(kKeyOrigin + i / 16)},
                    c);
      }
      m.add(1000.0 * (s + 1), session);
    }
    return m;
  }();
  return map;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Api api(smallMap(), "fuzz.cmap");
  const std::string text(reinterpret_cast<const char*>(data), size);
  const size_t q = text.find('?');
  const std::string path = text.substr(0, q);
  Query query;
  if (q != std::string::npos) {
    size_t start = q + 1;
    while (start <= text.size()) {
      const size_t amp = text.find('&', start);
      const std::string pair = text.substr(start, amp == std::string::npos ? std::string::npos : amp - start);
      const size_t eq = pair.find('=');
      query.emplace(pair.substr(0, eq), eq == std::string::npos ? std::string() : pair.substr(eq + 1));
      if (amp == std::string::npos) break;
      start = amp + 1;
    }
  }
  try {
    const Reply r = api.get(path, query);
    if (r.status != 200 && r.status != 400 && r.status != 404) __builtin_trap();
  } catch (const Error&) {
    // A library error the API did not turn into a 400: acceptable only as a chronomap::Error.
  }
  return 0;
}
