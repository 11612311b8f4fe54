#pragma once
/// @file
/// Numbers formatted for people.

#include <string>

namespace chronomap {

/// A byte count as "12.3 MiB" (whole bytes as "512 B").
std::string humanBytes(double bytes);

}  // namespace chronomap
