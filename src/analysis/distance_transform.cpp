#include "distance_transform.h"

#include <algorithm>

namespace chronomap::analysis_detail {

namespace {

/// Floor division for a positive divisor (C++ division truncates towards zero).
int64_t floorDiv(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

}  // namespace

void forEachSquaredDistance(const std::vector<uint8_t>& source, int width, int height,
                            const std::function<void(int, const int64_t*)>& row) {
  if (width <= 0 || height <= 0) return;
  const auto w = static_cast<size_t>(width);
  // A distance no cell reaches: columns without a source hold it, and it stays larger than any
  // true squared distance after adding one ((w + h)^2 > (w - 1)^2 + (h - 1)^2).
  const int64_t far = static_cast<int64_t>(width) + height;
  // Phase 1, per column: the distance to the nearest source in the same column.
  std::vector<int32_t> column(source.size());
  for (size_t i = 0; i < w; ++i) {
    int64_t d = far;
    for (int j = 0; j < height; ++j) {
      const size_t at = static_cast<size_t>(j) * w + i;
      d = source[at] ? 0 : std::min(far, d + 1);
      column[at] = static_cast<int32_t>(d);
    }
    for (int j = height - 2; j >= 0; --j) {
      const size_t at = static_cast<size_t>(j) * w + i;
      column[at] = std::min(column[at], column[at + w] + 1);
    }
  }
  // Phase 2, per row: the lower envelope of the parabolas (x - i)^2 + g(i)^2 over the row's
  // columns i, then each cell's value on it.
  std::vector<int64_t> g2(w), out(w);
  std::vector<int> apex(w), start(w);  // the envelope's parabolas and where each begins
  for (int j = 0; j < height; ++j) {
    const int32_t* g = column.data() + static_cast<size_t>(j) * w;
    for (size_t i = 0; i < w; ++i) g2[i] = static_cast<int64_t>(g[i]) * g[i];
    auto f = [&](int64_t x, int i) { return (x - i) * (x - i) + g2[static_cast<size_t>(i)]; };
    // The first x from which parabola u lies at or below parabola i (i < u).
    auto separation = [&](int i, int u) {
      const int64_t num = static_cast<int64_t>(u) * u - static_cast<int64_t>(i) * i + g2[static_cast<size_t>(u)] -
                          g2[static_cast<size_t>(i)];
      return floorDiv(num, 2 * static_cast<int64_t>(u - i));
    };
    int q = 0;
    apex[0] = 0;
    start[0] = 0;
    for (int u = 1; u < width; ++u) {
      while (q >= 0 && f(start[static_cast<size_t>(q)], apex[static_cast<size_t>(q)]) > f(start[static_cast<size_t>(q)], u)) --q;
      if (q < 0) {
        q = 0;
        apex[0] = u;
      } else {
        const int64_t begin = 1 + separation(apex[static_cast<size_t>(q)], u);
        if (begin >= width) continue;
        ++q;
        apex[static_cast<size_t>(q)] = u;
        start[static_cast<size_t>(q)] = static_cast<int>(begin);
      }
    }
    for (int x = width - 1; x >= 0; --x) {
      const int64_t d2 = f(x, apex[static_cast<size_t>(q)]);
      out[static_cast<size_t>(x)] = d2 >= far * far ? kNoSource : d2;
      if (x == start[static_cast<size_t>(q)]) --q;
    }
    row(j, out.data());
  }
}

}  // namespace chronomap::analysis_detail
