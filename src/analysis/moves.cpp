#include "chronomap/analysis/moves.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "chronomap/core/error.h"

namespace chronomap {

namespace {

double colourDistance(const Rgb& a, const Rgb& b) {
  const double dr = a.r - b.r, dg = a.g - b.g, db = a.b - b.b;
  return std::sqrt(dr * dr + dg * dg + db * db);
}

/// True when the two footprints are alike: their longer horizontal sides, and their shorter
/// ones, within `ratio` of each other, each side with kFootprintSlack_m added (a side seen one
/// or two voxels thick is a thin side, whatever its exact width). A door leaf (5 cm by 90 cm)
/// is not a robot (50 by 50 cm) however alike their voxel counts, heights and colours.
constexpr double kFootprintSlack_m = 0.1;
bool sameFootprint(const Component& a, const Component& b, double ratio) {
  auto sides = [](const Component& c) {
    const double x = c.bbox_max_m.x() - c.bbox_min_m.x() + kFootprintSlack_m;
    const double y = c.bbox_max_m.y() - c.bbox_min_m.y() + kFootprintSlack_m;
    return std::make_pair(std::min(x, y), std::max(x, y));
  };
  const auto [a_short, a_long] = sides(a);
  const auto [b_short, b_long] = sides(b);
  return std::max(a_short, b_short) <= ratio * std::min(a_short, b_short) &&
         std::max(a_long, b_long) <= ratio * std::min(a_long, b_long);
}

/// How unlike two objects are, or nothing when they cannot be the halves of one move.
std::optional<double> moveDissimilarity(const Component& gone, const Component& come, const MoveSettings& s) {
  if (gone.kind != ChangeKind::Vanished || come.kind != ChangeKind::Appeared) return std::nullopt;
  const double small = static_cast<double>(std::min(gone.voxels, come.voxels));
  const double large = static_cast<double>(std::max(gone.voxels, come.voxels));
  const double height = std::abs((gone.bbox_max_m.z() - gone.bbox_min_m.z()) - (come.bbox_max_m.z() - come.bbox_min_m.z()));
  const double colour = colourDistance(gone.mean_colour, come.mean_colour);
  if (small <= 0.0 || large > s.max_size_ratio * small || height > s.max_height_difference_m ||
      colour > s.max_colour_distance || (s.alike_footprints && !sameFootprint(gone, come, s.max_size_ratio))) {
    return std::nullopt;
  }
  // Each difference as a share of what it may be, summed: the likeliest pairs are matched first.
  const double size = s.max_size_ratio > 1.0 ? std::log(large / small) / std::log(s.max_size_ratio) : 0.0;
  const double h = s.max_height_difference_m > 0.0 ? height / s.max_height_difference_m : 0.0;
  const double c = s.max_colour_distance > 0.0 ? colour / s.max_colour_distance : 0.0;
  return size + h + c;
}

}  // namespace

void MoveSettings::validate() const {
  if (!(max_size_ratio >= 1.0) || !std::isfinite(max_size_ratio)) {
    throw UsageError("the size ratio of a move's halves must be a number of at least 1");
  }
  if (!(max_height_difference_m >= 0.0) || !std::isfinite(max_height_difference_m) || !(max_colour_distance >= 0.0) ||
      !std::isfinite(max_colour_distance)) {
    throw UsageError("a move's height and colour differences must be numbers of at least 0");
  }
}

std::vector<MovePair> pairMoves(const std::vector<Component>& components, const MoveSettings& settings) {
  settings.validate();
  std::vector<MovePair> moves;
  if (!settings.pair) return moves;
  struct Candidate {
    double dissimilarity;
    size_t gone, come;
  };
  std::vector<Candidate> candidates;
  for (size_t i = 0; i < components.size(); ++i) {
    for (size_t j = 0; j < components.size(); ++j) {
      if (auto d = moveDissimilarity(components[i], components[j], settings)) candidates.push_back({*d, i, j});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& x, const Candidate& y) { return x.dissimilarity < y.dissimilarity; });
  std::vector<bool> taken(components.size(), false);
  for (const Candidate& m : candidates) {
    if (taken[m.gone] || taken[m.come]) continue;
    taken[m.gone] = taken[m.come] = true;
    moves.push_back({m.gone, m.come});
  }
  return moves;
}

}  // namespace chronomap
