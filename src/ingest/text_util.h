#pragma once
// Small text parsing helpers shared by the readers (internal).

#include <limits>
#include <string>
#include <vector>

namespace chronomap {

/// Splits on spaces, tabs and carriage returns.
std::vector<std::string> splitWhitespace(const std::string& line);
/// Parses a whole token as a double. @throw FormatError "<context>: '<token>' is not a number".
double parseDouble(const std::string& token, const std::string& context);
/// Parses a whole token as an unsigned integer. @throw FormatError.
unsigned long long parseUnsigned(const std::string& token, const std::string& context);
/// A coordinate read from a file as float: finite values beyond float's range become infinite
/// (and so count as invalid points) instead of an undefined conversion. Inline: it is called for
/// every pixel of every depth image.
inline float toFloat(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);  // also NaN
}
/// A whole number in [lo, hi] read as double. @throw FormatError "<context>: ... out of range".
double checkedInteger(double v, double lo, double hi, const std::string& context);

/// Lines of a text, without '#' comment lines and blank lines; keeps 1-based line numbers.
std::vector<std::pair<size_t, std::string>> contentLines(const std::string& text);

}  // namespace chronomap
