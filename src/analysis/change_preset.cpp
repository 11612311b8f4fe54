#include "chronomap/analysis/change_preset.h"

#include "chronomap/core/error.h"

namespace chronomap {

void ChangeSettings::validate() const {
  diff.validate();
  segment.validate();
  moves.validate();
}

ChangeSettings recommendedChangeSettings() {
  ChangeSettings s;
  s.diff.mode = DiffMode::Band;
  s.diff.neighbourhood_voxels = 1;
  s.diff.min_shift_voxels = DiffSettings::kRecommendedMinShift;
  s.diff.shift_plane_ratio = DiffSettings::kRecommendedShiftPlaneRatio;
  s.diff.kept_surface_radius_voxels = DiffSettings::kRecommendedKeptSurfaceRadius;
  s.diff.dark_surface_radius_voxels = DiffSettings::kDarkSurfaceRadius;
  s.diff.seen_at_both = true;
  s.segment.connectivity = Connectivity::Vertex;
  s.segment.min_voxels = kRecommendedMinObjectVoxels;
  return s;
}

ChangeSettings rawChangeSettings() {
  ChangeSettings s;
  s.moves.pair = false;
  return s;
}

ChangeSettings changeSettingsNamed(const std::string& preset) {
  if (preset == "recommended") return recommendedChangeSettings();
  if (preset == "raw") return rawChangeSettings();
  throw UsageError("--preset '" + preset + "' is not a preset: give recommended (the default) or raw");
}

}  // namespace chronomap
