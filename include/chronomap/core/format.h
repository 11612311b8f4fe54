#pragma once
/// @file
/// Numbers formatted for people.

#include <cstdint>
#include <string>
#include <string_view>

namespace chronomap {

/// A byte count as "12.3 MiB" (whole bytes as "512 B").
std::string humanBytes(double bytes);

/// A count with its noun, singular or plural as the count asks: "1 session", "0 sessions",
/// "3 sessions" (the plural adds "s"; for nouns that do, such as "session" or "voxel").
std::string countOf(uint64_t count, std::string_view noun);

/// The shortest decimal that reads back as exactly `value` ("0.05", "0.050000000000000003",
/// "-525", "1e+300", "nan", "inf"), so that two numbers a message calls different are printed
/// differently, and a number a message quotes is the number it was given.
std::string exactNumber(double value);

}  // namespace chronomap
