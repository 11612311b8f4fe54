#pragma once
/// @file
/// Connected components of a sparse octree (thesis §3.2): which changed voxels form one object.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "chronomap/analysis/diff.h"

namespace chronomap {

/// Which neighbours are connected: those sharing a face (6 per voxel), a face or an edge (18),
/// or a face, an edge or a vertex (26).
enum class Connectivity : uint8_t { Face = 0, Edge = 1, Vertex = 2 };
/// "face", "edge", "vertex".
const char* toString(Connectivity c);
/// @throw UsageError naming the accepted names.
Connectivity parseConnectivity(const std::string& name);

/// Settings of a segmentation.
struct SegmentSettings {
  Connectivity connectivity = Connectivity::Face;
  /// >= 0: neighbours join only when their colours lie at most this far apart (Euclidean
  /// distance in 8-bit RGB units). Negative: colour plays no part.
  double colour_tolerance = -1.0;
  /// Components with fewer unit voxels are dropped (counted in Segmentation::dropped).
  uint64_t min_voxels = 1;
  /// Cells of a Continuous diff take part only when their value (|P1 - P2|) exceeds this.
  /// Cells of the other modes always take part.
  double min_value = 0.5;

  /// @throw UsageError for a non-finite tolerance or a min_value outside [0, 1).
  void validate() const;
};

/// One connected component. Appeared and vanished cells never share a component.
struct Component {
  uint32_t id = 0;  ///< 1.. in order of decreasing size
  ChangeKind kind = ChangeKind::Appeared;
  uint64_t voxels = 0;
  double volume_m3 = 0.0;
  Eigen::Vector3d bbox_min_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d bbox_max_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();
  Rgb mean_colour;
  /// Indices into DiffMap::cells(), increasing.
  std::vector<uint32_t> cells;
};

/// The result of a segmentation.
struct Segmentation {
  /// Sorted by decreasing voxel count (ties: by first cell); ids 1..n in that order.
  std::vector<Component> components;
  size_t dropped = 0;  ///< components below min_voxels
};

/// Segments a diff bottom-up with the thesis' bounding-box algorithm (Algorithms 1 and 2): each
/// octree node yields a box whose six faces are quadtrees of the cells touching them; when 8
/// child boxes combine, the faces, edges and vertices that meet inside the parent are matched
/// and their cells joined. Matching descends only where both sides hold cells, so the cost
/// follows the number of changed cells, not the size of the space. Joins use a union-find
/// instead of grafting octrees; the components are the same.
/// @throw UsageError for bad settings.
Segmentation segment(const DiffMap& diff, const SegmentSettings& settings = {});

/// The reference: a plain flood fill over every unit voxel of the selected cells with a hash
/// table. Slow; used by tests and benchmarks to check segment().
Segmentation segmentByFloodFill(const DiffMap& diff, const SegmentSettings& settings = {});

/// The cells of one component as a diff of their own, at the original coordinates.
DiffMap componentDiff(const DiffMap& diff, const Component& component);

}  // namespace chronomap
