#pragma once
/// @file
/// Point cloud files: PCD (ascii, binary, binary_compressed), PLY (ascii and binary) and plain
/// text "x y z [r g b]" (.xyz, .dat), each optionally bzip2-compressed (.bz2).

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "chronomap/core/point_cloud.h"

namespace chronomap {

/// PCD DATA encodings.
enum class PcdEncoding { Ascii, Binary, BinaryCompressed };

/// What a PCD file holds besides x y z, rgb and label: its VIEWPOINT line (the sensor pose, which
/// the dynamic-map benchmark's frames carry) and an `intensity` field (its labels in gt_cloud.pcd).
struct PcdExtras {
  /// The VIEWPOINT line's values as written (tx ty tz qw qx qy qz); empty when the file has none.
  std::vector<std::string> viewpoint;
  /// The `intensity` field, any numeric type, as float; empty when the file has none.
  std::vector<float> intensity;
};

/// Reads a PCD file: fields x y z (F4 or F8), optional rgb/rgba (packed 0x00RRGGBB) and label.
/// Organized clouds keep their width and height; invalid points stay NaN.
/// @throw FormatError naming the file and the problem for malformed input.
PointCloud readPcd(const std::filesystem::path& path);
/// readPcd that also gives the VIEWPOINT and intensity (PcdExtras).
PointCloud readPcd(const std::filesystem::path& path, PcdExtras& extras);
/// The VIEWPOINT values of a PCD file, from its header only; empty when it has none.
/// @throw FormatError for a malformed header, IoError when it cannot be read.
std::vector<std::string> readPcdViewpoint(const std::filesystem::path& path);
/// The sensor pose (T_world_sensor) that VIEWPOINT values "tx ty tz qw qx qy qz" give; the
/// quaternion is normalised when within kQuaternionNormTolerance of unit length.
/// @throw DataError naming `name` when there are none, not 7, not numbers, not finite, or the
/// quaternion is zero or not near unit length.
Eigen::Isometry3d pcdViewpointPose(const std::vector<std::string>& values, const std::string& name);
/// Writes x y z, intensity when `extras` has it, rgb when present and label when present,
/// atomically; VIEWPOINT from `extras` when it has one, else the identity.
void writePcd(const std::filesystem::path& path, const PointCloud& cloud, PcdEncoding encoding,
              const PcdExtras* extras = nullptr);

/// Reads the vertices of a PLY file: x y z and optional red/green/blue (or r/g/b).
/// @throw FormatError naming the file and the problem for malformed input.
PointCloud readPly(const std::filesystem::path& path);
/// Writes vertices (x y z float, red green blue uchar) as binary little-endian PLY, atomically.
void writePly(const std::filesystem::path& path, const PointCloud& cloud);

/// Reads whitespace-separated "x y z" or "x y z r g b" lines ('#' starts a comment).
PointCloud readXyz(const std::filesystem::path& path);

/// The same readers on a file's bytes already in memory; `name` is used in messages.
PointCloud parsePcd(const std::vector<uint8_t>& bytes, const std::string& name, PcdExtras* extras = nullptr);
PointCloud parsePly(const std::vector<uint8_t>& bytes, const std::string& name);
PointCloud parseXyz(const std::string& text, const std::string& name);

/// Reads any supported cloud file by its extension (.pcd, .ply, .xyz, .dat, optionally .bz2).
/// @throw UsageError for an unknown extension.
PointCloud readCloud(const std::filesystem::path& path);

/// True when readCloud understands the file's extension.
bool isCloudFile(const std::filesystem::path& path);

}  // namespace chronomap
