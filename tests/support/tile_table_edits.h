#pragma once
// A tiled map's index encoded again with its tile table changed: what the index tests feed
// decodeTileIndex (tests/store/tiles_test.cpp, tests/pipeline/stream_test.cpp).

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "chronomap/core/error.h"
#include "chronomap/store/cmap.h"
#include "chronomap/store/temporal_file.h"
#include "chronomap/store/tiled_file.h"

namespace chronomap::test {

class TileTableEdits {
 public:
  explicit TileTableEdits(const std::filesystem::path& folder)
      : file_(readCmap(folder / kTileIndexName)), index_(readTileIndex(folder)),
        table_({{"tiles", metadataOf(file_).at("tiles")}}) {}

  /// The table as the index holds it.
  const nlohmann::json& table() const { return table_.at("tiles"); }
  /// The index's bytes with its tile table changed by `change`.
  std::vector<uint8_t> with(const std::function<void(nlohmann::json&)>& change) const {
    nlohmann::json t = table_;
    change(t["tiles"]);
    return encodeTemporalMap(index_.top, userMetadataOf(file_), MapKind::Tiled, &t);
  }
  /// Expects decodeTileIndex to refuse with(change) with a FormatError whose message holds `what`.
  void expectRefused(const std::function<void(nlohmann::json&)>& change, const std::string& what) const {
    try {
      decodeTileIndex(with(change), "index");
      ADD_FAILURE() << "no error for " << what;
    } catch (const FormatError& x) {
      EXPECT_NE(std::string(x.what()).find(what), std::string::npos) << x.what();
    }
  }

 private:
  CmapFile file_;
  TileIndex index_;
  nlohmann::json table_;
};

}  // namespace chronomap::test
