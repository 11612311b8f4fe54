#pragma once
// The kind of day of a time: the rhythm model's hourly profiles and the alerts' baselines keep
// weekdays and weekends apart.

#include <cmath>
#include <cstdint>

namespace chronomap::analysis_detail {

/// 0 for a weekday, 1 for Saturday and Sunday (UTC); the epoch's day 0 was a Thursday.
inline int kindOfDay(double time_s) {
  const auto day = static_cast<int64_t>(std::floor(time_s / 86400.0));
  const int64_t weekday = ((day + 3) % 7 + 7) % 7;  // 0 Monday
  return weekday >= 5 ? 1 : 0;
}

}  // namespace chronomap::analysis_detail
