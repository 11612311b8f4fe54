#pragma once
/// @file
/// Session times: seconds since the Unix epoch (UTC), parsed from ISO-8601 or plain numbers.

#include <string>
#include <string_view>

namespace chronomap {

/// Parses "2012-03-01T10:00:00Z", "2012-03-01T10:00:00.250+02:00", "2012-03-01 10:00:00",
/// "2012-03-01" (midnight UTC; a time without a zone is UTC) or seconds since the epoch
/// ("1330596000", "1330596000.5").
/// @throw UsageError naming the text when it is none of these, not a valid calendar time, or
/// outside [kEarliestTime_s, kLatestTime_s].
double parseTime(std::string_view text);

/// The times chronomap accepts, in seconds since the epoch: 0001-01-01T00:00:00Z to
/// 9999-12-31T23:59:59Z (four-digit years, as ISO-8601 writes them).
inline constexpr double kEarliestTime_s = -62135596800.0;
inline constexpr double kLatestTime_s = 253402300799.0;

/// `seconds` when it is a time chronomap accepts: a number within [kEarliestTime_s,
/// kLatestTime_s]. Every front end checks the times it is given with this (parseTime does, for
/// text), so that no session is stored at a time no command can name.
/// @throw UsageError "WHAT lies outside the years 1 to 9999 (...)" or "WHAT is not a number",
/// where `what` names the value ("time '1e300'", "t1 1e+300").
double checkTime(double seconds, const std::string& what);

/// Formats seconds since the epoch as ISO-8601 UTC ("2012-03-01T10:00:00Z"; fractional
/// seconds to the millisecond when present); "invalid-time" outside [kEarliestTime_s, kLatestTime_s].
std::string formatTime(double seconds);

/// The hour of the day (UTC, 0 <= h < 24) of a time in seconds since the epoch.
double hourOfDay(double time_s);

}  // namespace chronomap
