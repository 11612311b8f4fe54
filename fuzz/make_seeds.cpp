// Writes small valid inputs for every fuzz target, made by chronomap's own writers, into
// DIR/<target>/. Usage: make_seeds DIR
// With --db3 MCAP_DIR OUT_DIR: each MCAP seed's messages as a rosbag2 SQLite bag (fuzz_db3).
#include <cstdio>
#include <string>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "chronomap/analysis/colour.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/ingest/cloud_io.h"
#include "chronomap/store/cmap.h"
#include "chronomap/core/file.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/store/tiled_file.h"
#include "chronomap/store/diff_file.h"
#include "chronomap/core/file.h"
#include "chronomap/ingest/jpeg.h"
#include "chronomap/ingest/png.h"
#include "db3_writer.h"
#include "model_map.h"

using namespace chronomap;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  if (argc == 4 && std::string(argv[1]) == "--db3") {
    fs::create_directories(argv[3]);
    for (const auto& entry : fs::directory_iterator(argv[2])) {
      if (entry.path().extension() != ".mcap") continue;
      test::writeDb3(entry.path(), fs::path(argv[3]) / entry.path().filename().replace_extension(".db3"));
    }
    return 0;
  }
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds DIR\n");
    return 2;
  }
  const fs::path root = argv[1];
  for (const char* t : {"cmap", "pcd", "ply", "xyz", "png", "text", "model", "bag", "rosmsg"}) {
    fs::create_directories(root / t);
  }
  // Saved models (fuzz_model): a colour model of two voxels under one light and an empty rhythm
  // model, fitted without a map; the rhythm models fitted on fuzz_model's map (model_map.h), and
  // a colour model recording that map; each also in the previous version, which still reads.
  {
    const TemporalMap fitted_on = fuzz::modelMap();
    ColourModel colour;
    colour.components = 1;
    colour.bins = 4;
    colour.curves.assign(3 * 4, 0.5);
    colour.keys = {VoxelKey{1, 2, 3}, VoxelKey{4, 5, 6}};
    colour.weights = {100.0f, 50.0f, 20.0f, 10.0f, 200.0f, 30.0f};
    colour.resolution_m = fitted_on.resolution_m();
    colour.from_s = 1000.0;
    colour.to_s = 2000.0;
    colour.sessions = 2;
    colour.observations = 4;
    colour.fitted_on = fittedOn(fitted_on, colour.from_s, colour.to_s);
    writeFileAtomic(root / "model/two.colour", serialize(colour));
    writeFileAtomic(root / "model/two_v1.colour", serialize(colour, 1));
    RhythmModels rhythm;
    rhythm.resolution_m = 0.05;
    writeFileAtomic(root / "model/empty.rhythm", serialize(rhythm));
    const RhythmModels fitted = fitRhythm(fitted_on, 0.0, 3000.0);
    writeFileAtomic(root / "model/fitted.rhythm", serialize(fitted));
    writeFileAtomic(root / "model/fitted_v3.rhythm", serialize(fitted, 3));
  }
  // Message decoder heads (fuzz_readers.cpp, FUZZ_ROSMSG): 16UC1 depth 4 x 2, rgb8 colour 2 x 2,
  // a 2 x 1 cloud of 16-byte points; then their data.
  {
    auto head = [](std::initializer_list<int> v) { return std::string(v.begin(), v.end()); };
    std::ofstream(root / "rosmsg" / "depth", std::ios::binary) << head({0, 4, 2, 8, 0, 0, 0, 0, 0, 0, 0, 0})
                                                               << std::string(16, '\x10');
    std::ofstream(root / "rosmsg" / "color", std::ios::binary) << head({1, 2, 2, 6, 0, 0, 3, 0, 0, 0, 0, 0})
                                                               << std::string(12, '\x40');
    std::ofstream(root / "rosmsg" / "cloud", std::ios::binary) << head({2, 2, 1, 32, 0, 0, 0, 16, 0, 0, 0, 27})
                                                               << std::string(32, '\x3f');
  }
  PointCloud cloud;
  cloud.width = 4;
  cloud.height = 3;
  for (int i = 0; i < 12; ++i) {
    cloud.points.emplace_back(0.1f * i, -0.05f * i, 1.0f + 0.01f * i);
    cloud.colours.push_back(Rgb{static_cast<uint8_t>(20 * i), 7, 200});
    cloud.labels.push_back(static_cast<uint32_t>(i / 4));
  }
  cloud.points[5] = Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  writePcd(root / "pcd/ascii.pcd", cloud, PcdEncoding::Ascii);
  writePcd(root / "pcd/binary.pcd", cloud, PcdEncoding::Binary);
  writePcd(root / "pcd/compressed.pcd", cloud, PcdEncoding::BinaryCompressed);
  writePly(root / "ply/cloud.ply", cloud);
  std::ofstream(root / "ply/ascii.ply") << "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                           "property float y\nproperty float z\nproperty uchar red\n"
                                           "property uchar green\nproperty uchar blue\nend_header\n"
                                           "1 2 3 4 5 6\n7 8 9 10 11 12\n";
  std::ofstream(root / "xyz/scan.xyz") << "# x y z\n1 2 3\n4 5 6\n";
  std::ofstream(root / "xyz/color.xyz") << "1 2 3 10 20 30\n";
  writePng(root / "png/depth.png", ImageU16{4, 3, std::vector<uint16_t>(12, 5000)});
  writePng(root / "png/color.png", ImageRgb{4, 3, std::vector<Rgb>(12, Rgb{1, 2, 3})});
  const ImageRgb small{16, 8, std::vector<Rgb>(128, Rgb{90, 160, 30})};
  writeFileAtomic(root / "png/color.jpg", encodeJpeg(small, {30, false, false}));
  writeFileAtomic(root / "png/progressive.jpg", encodeJpeg(small, {30, false, true}));
  std::ofstream(root / "text/intrinsics") << '\0' << "525 0 319.5\n0 525 239.5\n0 0 1\n";
  std::ofstream(root / "text/matrix") << '\1' << "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  std::ofstream(root / "text/list") << '\2' << "# timestamp filename\n1.0 depth/1.png\n1.1 depth/2.png\n";
  std::ofstream(root / "text/trajectory") << '\3' << "1.0 0 0 0 0 0 0 1\n1.1 0.1 0 0 0 0 0.7071068 0.7071068\n";
  std::ofstream(root / "text/clouds") << '\4' << "a.pcd 0 0 0 0 0 0 1\n";
  SessionMap map(0.1);
  VoxelCounters free, hit;
  free.length_m = 0.1f;
  hit.length_m = 0.05f;
  hit.hits = 2;
  hit.red = 100;
  for (uint16_t x = 0; x < 4; ++x) map.add({static_cast<uint16_t>(32768 + x), 32768, 32768}, free);
  map.add({32772, 32768, 32768}, hit);
  for (uint16_t i = 0; i < 8; ++i) {
    map.add({static_cast<uint16_t>(32776 + (i & 1)), static_cast<uint16_t>(32768 + ((i >> 1) & 1)),
             static_cast<uint16_t>(32768 + (i >> 2))},
            free);
  }
  map.compressFree();
  writeSessionMap(root / "cmap/session.cmap", map, {{"seed", true}});
  // The previous format version, which readers still read.
  writeFileAtomic(root / "cmap/session_v1.cmap", encodeSessionMap(map, {{"seed", true}}, 3, 1));
  {
    // A small 4D map: the session, then the same session shifted by a voxel, added out of order.
    TemporalMap four_d(map.resolution_m());
    four_d.add(2000.0, map);
    SessionMap shifted(map.resolution_m());
    map.forEachLeaf([&](const LeafView& leaf) {
      if (leaf.level == 0) shifted.add(VoxelKey{static_cast<uint16_t>(leaf.key.x + 1), leaf.key.y, leaf.key.z}, leaf.counters);
    });
    four_d.add(1000.0, shifted);
    writeTemporalMap(root / "cmap/four_d.cmap", four_d, {{"seed", true}});
    writeFileAtomic(root / "cmap/four_d_v1.cmap", encodeTemporalMap(four_d, {{"seed", true}}, 1));
    writeDiffMap(root / "cmap/diff.cmap", diff(four_d, 1000.0, 2000.0), {{"seed", true}});
    // The same 4D map cut into tiles of 2 voxels: its index (fuzz_cmap reads kind "tiled" too).
    writeTiledMap(root / "tiled", splitIntoTiles(four_d, 1), {{"seed", true}});
    fs::copy_file(root / "tiled" / kTileIndexName, root / "cmap/tile_index.cmap", fs::copy_options::overwrite_existing);
    // Its table as version 2: a tile listed with the first session only (a tile the streaming
    // build kept while a later session was added elsewhere).
    TileIndex kept = readTileIndex(root / "tiled");
    if (!kept.tiles.empty()) kept.tiles.front().sessions = 1;
    writeTileIndex(root / "tiled", kept.top, kept.tile_level, kept.tiles, {{"seed", true}});
    fs::copy_file(root / "tiled" / kTileIndexName, root / "cmap/tile_index_v2.cmap", fs::copy_options::overwrite_existing);
    fs::remove_all(root / "tiled");
    // With history windows of one session (table version 3), and a window file (a 4D map).
    writeTiledMap(root / "tiled", splitIntoTiles(four_d, 1), {{"seed", true}}, 1);
    const TileIndex windowed = readTileIndex(root / "tiled");
    fs::copy_file(root / "tiled" / kTileIndexName, root / "cmap/tile_index_v3.cmap", fs::copy_options::overwrite_existing);
    if (!windowed.tiles.empty() && !windowed.tiles.front().windows.empty()) {
      fs::copy_file(root / "tiled" / windowed.tiles.front().windows.back().file, root / "cmap/tile_window.cmap",
                    fs::copy_options::overwrite_existing);
    }
    fs::remove_all(root / "tiled");
    // Kept as windows of one session (the windowed layout, table version 4).
    writeTiledMap(root / "tiled", splitIntoTiles(four_d, 1), {{"seed", true}}, 1, {}, true);
    fs::copy_file(root / "tiled" / kTileIndexName, root / "cmap/tile_index_v4.cmap", fs::copy_options::overwrite_existing);
    fs::remove_all(root / "tiled");
    // The same 4D map with a third session appended as `chronomap add` appends it.
    writeTemporalMap(root / "cmap/four_d_appended.cmap", four_d, {{"seed", true}});
    const AddSettings options{false, "appended"};
    appendToFile(root / "cmap/four_d_appended.cmap", std::filesystem::file_size(root / "cmap/four_d_appended.cmap"),
                     encodeSessionRecord(3000.0, shifted, options));
  }
  return 0;
}
