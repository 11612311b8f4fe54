#include "text_util.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "chronomap/core/error.h"

namespace chronomap {

std::vector<std::string> splitWhitespace(const std::string& line) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    if (j > i) out.emplace_back(line, i, j - i);
    i = j;
  }
  return out;
}

double parseDouble(const std::string& token, const std::string& context) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(token.c_str(), &end);
  if (token.empty() || end != token.c_str() + token.size() || errno == ERANGE) {
    throw FormatError(context + ": '" + token + "' is not a number");
  }
  return v;
}

unsigned long long parseUnsigned(const std::string& token, const std::string& context) {
  errno = 0;
  char* end = nullptr;
  if (token.empty() || token[0] == '-') throw FormatError(context + ": '" + token + "' is not a whole number");
  const unsigned long long v = std::strtoull(token.c_str(), &end, 10);
  if (end != token.c_str() + token.size() || errno == ERANGE) {
    throw FormatError(context + ": '" + token + "' is not a whole number");
  }
  return v;
}

double checkedInteger(double v, double lo, double hi, const std::string& context) {
  if (!(v >= lo && v <= hi) || v != std::floor(v)) {
    throw FormatError(context + ": value " + std::to_string(v) + " is not a whole number in range");
  }
  return v;
}

std::vector<std::pair<size_t, std::string>> contentLines(const std::string& text) {
  std::vector<std::pair<size_t, std::string>> out;
  size_t start = 0, number = 0;
  while (start <= text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    ++number;
    std::string line = text.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    size_t first = line.find_first_not_of(" \t");
    if (first != std::string::npos && line[first] != '#') out.emplace_back(number, line);
    if (end == text.size()) break;
    start = end + 1;
  }
  return out;
}

}  // namespace chronomap
