#include "chronomap/pipeline/rhythm.h"

#include "chronomap/analysis/fitted_on.h"
#include "chronomap/core/error.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/export/map_server.h"
#include "chronomap/ingest/png.h"
#include "chronomap/store/rhythm_file.h"
#include "chronomap/render/top_view.h"

namespace chronomap {

RhythmModels learnRhythm(const TemporalMap& map, const LearnSettings& s) {
  if (s.saved) {
    if (s.range_given || s.save) {
      throw UsageError("--rhythm reads a fitted model: it takes no --learn-from, --learn-to or --save-rhythm");
    }
    RhythmModels models = readRhythmModels(*s.saved);
    const FittedOnCheck check{s.saved->string(), s.map_name,
                              "leave out --rhythm to fit the models on this map (--save-rhythm keeps them)",
                              "--allow-other-map", s.allow_other_map};
    if (const std::string warning = checkFittedOn(models, map, check); !warning.empty() && s.warn) s.warn(warning);
    return models;
  }
  RhythmModels models = fitRhythm(map, s.from_s, s.to_s, s.min_changes);
  if (s.save) writeRhythmModels(*s.save, models);
  return models;
}

ColourModel learnColour(const TemporalMap& map, const ColourLearnSettings& s) {
  if (s.saved) {
    if (s.range_given || s.save) {
      throw UsageError("--colour-model reads a fitted model: it takes no --learn-from, --learn-to or --save-colour");
    }
    ColourModel model = readColourModel(*s.saved);
    const FittedOnCheck check{s.saved->string(), s.map_name,
                              "leave out --colour-model to fit the colour model on this map (--save-colour keeps it)",
                              "--allow-other-map", s.allow_other_map};
    if (const std::string warning = checkFittedOn(model, map, check); !warning.empty() && s.warn) s.warn(warning);
    return model;
  }
  ColourModel model = fitColour(map, s.from_s, s.to_s, s.fit);
  if (s.save) writeColourModel(*s.save, model);
  return model;
}

CostmapFiles costmapFiles(const std::filesystem::path& yaml) {
  if (yaml.extension() != ".yaml") throw UsageError("output '" + yaml.string() + "' must end in .yaml");
  CostmapFiles f{yaml, yaml, yaml};
  f.pgm.replace_extension(".pgm");
  f.png.replace_extension(".png");
  return f;
}

CostmapCounts writeCostmap(const CostmapFiles& files, const Costmap& c, const std::string& source) {
  if (c.width == 0) throw DataError(source + ": nothing is known between --z-min and --z-max");
  writeMapServer(files.yaml, c);
  writePng(files.png, renderCostmap(c));
  CostmapCounts n;
  for (int8_t v : c.cost) ++(v < 0 ? n.unknown : v == 0 ? n.free : v < Costmap::kInscribed ? n.costly : n.blocked);
  return n;
}

}  // namespace chronomap
