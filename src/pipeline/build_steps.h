#pragma once
// The steps of build(), shared by the one-process build (map4d.cpp) and the build
// spread over MPI ranks (distributed.cpp), so that both run the same code in the same order.

#include <cstddef>
#include <optional>
#include <vector>

#include "chronomap/store/cmap.h"
#include "chronomap/pipeline/map4d.h"

namespace chronomap::pipeline_detail {

/// A recording integrated, waiting to be added.
struct Pending {
  size_t index;  // into the settings' datasets
  double time_s;
  IntegratedSession session;
};

/// Refuses bad settings, missing datasets and a map that would overwrite an input.
void checkInputs(const BuildSettings& s);
/// Refuses known clashes with stored sessions before the long integration.
void refuseClashes(const BuildSettings& s, const TemporalMap& map);
/// Integrates dataset `i` (saying so; with `sharing`, other processes cast some of its frames) and
/// finds its time. @throw UsageError when it has none.
Pending integrateOne(const BuildSettings& s, size_t i, FrameSharing* sharing = nullptr);
/// Sorts the sessions by time. @throw UsageError when two have the same time.
void sortByTime(const BuildSettings& s, std::vector<Pending>& pending);
/// Registers the sorted sessions against the consensus of them all (s.registration, which must be
/// set): each session's map becomes its recording integrated again with the correction found.
/// `prior`: the consensus of the sessions registered before (the streaming build's stored ones).
std::vector<PoseCorrection> registerPending(const BuildSettings& s, std::vector<Pending>& pending,
                                            const SessionMap* prior = nullptr);
/// `given` with a depth image cache for registration's second read of every frame (when asked
/// for and not set yet).
BuildSettings withRegistrationCache(const BuildSettings& given);
/// The time of dataset `i` as integrateOne will find it, known before integrating: the given one
/// (--times), else the recording's own (opening it). Nothing when it has none or does not open.
std::optional<double> timeBeforeIntegrating(const BuildSettings& s, size_t i);
/// Adds one integrated session to `map` as finishBuild adds each, with its correction and the
/// voxels re-alignment moved when there are, and says what it added.
BuiltSession addPending(const BuildSettings& s, TemporalMap& map, const Pending& p,
                        const std::optional<PoseCorrection>& correction, std::optional<size_t> realigned);
/// Registers and re-aligns the sorted sessions when asked, adds them to `map` and writes it once,
/// atomically, with the metadata `stored` and the sessions' up (mapMetadata). `added_before`: the
/// sessions of this build already added (all earlier than `pending`), reported first.
BuildResult finishBuild(const BuildSettings& s, TemporalMap& map, bool created, std::vector<Pending>& pending,
                        const ChosenUp& up, const nlohmann::json& stored, std::vector<BuiltSession> added_before = {});
/// `given` with every recording read for `up` (its axis given, the world rotation set), saying so
/// when it was estimated.
BuildSettings withUp(const BuildSettings& given, const ChosenUp& up);
/// Refuses a session whose up axis is not its map's: `session_up` read from the session file
/// `session`, `map_up` from the map `map`. @throw UsageError naming both and the --up to give.
void refuseOtherUp(const std::filesystem::path& session, const ChosenUp& session_up, const std::filesystem::path& map,
                   const ChosenUp& map_up);
/// The metadata a build writes: the up the map stored (`stored`'s up keys) when `up` is the map's
/// own, else `up`'s (ChosenUp::metadata; nothing for +z as recorded, as before --up existed).
nlohmann::json mapMetadata(const nlohmann::json& stored, const ChosenUp& up);
/// The time of the session `add` reads from `file`: the given one, else the file's recorded_at.
/// @throw UsageError when there is neither.
double sessionTime(const AddSessionSettings& s, const CmapFile& file);

}  // namespace chronomap::pipeline_detail
