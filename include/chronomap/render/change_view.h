#pragma once
/// @file
/// The changes between two visits drawn from above: the objects of findChanges over the later
/// map, each framed and numbered (labels that do not cover each other), a move as an arrow from
/// the old place to the new; and a close-up of one object.

#include "chronomap/analysis/changes.h"
#include "chronomap/core/image.h"
#include "chronomap/octree/session_map.h"
#include "chronomap/render/top_view.h"

namespace chronomap {

/// Settings of a change picture.
struct ChangeViewSettings {
  /// The background's top view: scale, colours, axes, named areas (its colours are faded).
  TopViewSettings view;
  /// Scale of the objects' numbers (the 5x7 font).
  int label_scale = 2;
  Rgb appeared{20, 150, 40};
  Rgb vanished{210, 40, 30};
  Rgb moved_from{150, 130, 215};  ///< a moved object's old place
  Rgb moved_to{90, 40, 190};      ///< and its new place
  Rgb arrow{40, 20, 120};         ///< the arrow from the old place to the new
  /// A close-up shows the object's places and this much around them (metres).
  double close_up_margin_m = 1.0;
};

/// The later (or any) map `background` from above, faded, with every object of `changes` drawn
/// over it: its changed cells in its kind's colour, its place framed and labelled with its id
/// (labels placed so that none covers another or an area's name; a label moved away is joined
/// to its object by a leader line), a move as an arrow from the old place's centroid to the
/// new one's. With settings.view.axes, framed by axes in metres, a scale bar and a legend.
/// @throw DataError as drawTopView.
TopView drawChanges(const SessionMap& background, const Changes& changes, const ChangeViewSettings& settings = {});

/// As drawChanges, but only around `object` (one of changes.objects): its places (a move's old
/// and new) and settings.close_up_margin_m around them.
/// @throw DataError as drawTopView, and when the background has no column there.
TopView drawObjectCloseUp(const SessionMap& background, const Changes& changes, const ChangedObject& object,
                          const ChangeViewSettings& settings = {});

}  // namespace chronomap
