#pragma once
/// @file
/// Session times: seconds since the Unix epoch (UTC), parsed from ISO-8601 or plain numbers.

#include <string>
#include <string_view>

namespace chronomap {

/// Parses "2012-03-01T10:00:00Z", "2012-03-01T10:00:00.250+02:00", "2012-03-01 10:00:00",
/// "2012-03-01" (midnight UTC; a time without a zone is UTC) or seconds since the epoch
/// ("1330596000", "1330596000.5").
/// @throw UsageError naming the text when it is none of these or not a valid calendar time.
double parseTime(std::string_view text);

/// Formats seconds since the epoch as ISO-8601 UTC ("2012-03-01T10:00:00Z"; fractional
/// seconds to the millisecond when present).
std::string formatTime(double seconds);

}  // namespace chronomap
