#pragma once
/// @file
/// The viewer's HTTP API as a plain function of a request, so that it is tested without a
/// network and served by any server (server.h uses cpp-httplib). Answers are the page, its
/// script, JSON metadata and histories, and binary packets (packet.h) of voxels and diffs.

#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "chronomap/analysis/costmap.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/temporal/temporal_map.h"
#include "chronomap/view/scene.h"

namespace chronomap {

/// How far past a map's last session /api/predict and /api/costmap answer: a week (the temporal
/// models have daily and weekly rhythms; beyond a week they only repeat them).
inline constexpr double kPredictionHorizon_s = 7 * 24 * 3600.0;

/// Limits of the API: what a request may ask for.
struct ApiSettings {
  /// Cells of a snapshot when the request names no budget.
  size_t default_max_voxels = 200000;
  /// The largest budget a request may name (a larger one is refused with 400).
  size_t max_voxels_limit = 2000000;
  /// Changed cells sent with a diff (its objects are always sent whole).
  size_t max_diff_cells = 300000;
  /// How diffs are computed and segmented (a request may ask for another min_voxels).
  DiffSettings diff = changeSettings().diff;
  SegmentSettings segment = changeSettings().segment;
  /// Temporal models for /api/predict (a saved .rhythm, `chronomap view --rhythm`); when null,
  /// they are fitted to every session of the map on the first such request.
  std::shared_ptr<const RhythmModels> rhythm;
};

/// One answer: HTTP status, content type and body.
struct Reply {
  int status = 200;
  std::string content_type;
  std::string body;
};

/// Query parameters of a request (a name may repeat; a repeated name is refused).
using Query = std::multimap<std::string, std::string>;

/// Answers GET requests about one 4D map. The paths:
///  - `/` the page; `/viewer.js` its script (both built into the binary);
///  - `/api/map` JSON: resolution, sessions, counts (mapInfoJson);
///  - `/api/snapshot?session=R|t=T[&budget=N][&level=L][&region=x0,y0,z0,x1,y1,z1]` a packet of
///    the occupied cells (snapshotVoxels);
///  - `/api/diff?from=R|t0=T&to=R|t1=T[&min_voxels=N]` a packet of the changed cells and, in its
///    header, the objects (diffObjects);
///  - `/api/history?key=x,y,z[&level=L]` JSON (historyJson);
///  - `/api/predict?session=R|t=T[&model=M]` a packet of every modelled cube's predicted
///    probability of occupancy at that time (encodePrediction; model: rhythm.h's names,
///    default combined); T may lie up to kPredictionHorizon_s past the last session;
///  - `/api/costmap?session=R|t=T[&model=M]` a packet of the navigation cost map at that time
///    (costmap() of predictMap(), the default CostmapSettings of `chronomap costmap`), T as for
///    /api/predict.
/// Anything else is 404; a malformed or unknown parameter, a time outside the map's sessions (for
/// predictions: before the first or more than a week past the last) or
/// a budget above the limit is 400 with a JSON {"error": ...}. Safe to call from several threads
/// at once (the map is only read; the constructor prepares its lazily built summaries).
class Api {
 public:
  Api(const TemporalMap& map, std::string name, ApiSettings settings = {});
  Reply get(const std::string& path, const Query& query) const;

 private:
  Reply snapshot(const Query& query) const;
  Reply diffReply(const Query& query) const;
  Reply history(const Query& query) const;
  Reply predict(const Query& query) const;
  Reply costmapReply(const Query& query) const;
  const RhythmModels& rhythm() const;
  const TemporalMap& map_;
  std::string name_;
  ApiSettings settings_;
  // Models fitted on the first /api/predict (when settings_.rhythm is null), once for all threads.
  struct Fitted {
    std::once_flag once;
    std::shared_ptr<const RhythmModels> models;
    double seconds = 0.0;
  };
  std::shared_ptr<Fitted> fitted_ = std::make_shared<Fitted>();
};

/// The modelled cubes' probabilities at `time_s` under `model` as a packet: header {"time_s",
/// "model", "cubes", "fit_s" (seconds the models took to fit, 0 when loaded)}, arrays "keys"
/// (u16 x, y, z of each cube's corner), "levels", "p" (f32, RhythmModels::predict).
std::string encodePrediction(const RhythmModels& models, RhythmModel model, double time_s, double fit_s);

/// A cost map as a packet: header {"time_s", "model", "width", "height", "resolution_m",
/// "origin_m": [x, y], "z_min_m", "z_max_m"}, array "cost" (u8: the int8 costs, 255 = -1 unknown,
/// row-major from the lowest y).
std::string encodeCostmap(const Costmap& costmap, const CostmapSettings& settings, RhythmModel model, double time_s);

/// A snapshot's cells as a packet: header {"level", "rank", "time_s", "occupied_voxels",
/// "cells"}, arrays "keys" (u16 x, y, z per cell), "levels", "colors" (u8 r, g, b), "changes",
/// "since" (u16), "members" (u32).
std::string encodeSnapshot(const VoxelSet& voxels, const TemporalMap& map);

/// A diff's cells (at most max_cells, in Morton order) and objects as a packet: header
/// {"t0_s", "t1_s", "cells", "cells_sent", "voxels", "components": [componentJson...],
/// "dropped"}, arrays "keys" (u16 x, y, z), "levels", "kinds" (1 appeared, 2 vanished),
/// "component" (u32 id, 0 for none).
std::string encodeDiff(const DiffObjects& objects, const DiffRequest& request, size_t max_cells);

/// The page's HTML with the script referenced as `viewer.js` (for the server).
std::string servedPage();
/// The bundled script of the page.
std::string_view viewerScript();
/// The page's HTML with the script and `data` (a packet, base64 in the page) inside it: a file
/// that opens with no server (tour.h).
std::string selfContainedPage(const std::string& data);

}  // namespace chronomap
