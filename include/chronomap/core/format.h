#pragma once
/// @file
/// Numbers formatted for people.

#include <string>

namespace chronomap {

/// A byte count as "12.3 MiB" (whole bytes as "512 B").
std::string humanBytes(double bytes);

/// The shortest text that reads back as `v` ("-525", "1e+300", "1330596000.5", "nan", "inf"):
/// how error messages quote a number they were given.
std::string formatNumber(double v);

}  // namespace chronomap
