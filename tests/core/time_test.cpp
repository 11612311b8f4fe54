#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/core/time.h"

namespace chronomap {
namespace {

TEST(Time, ParsesIsoAndEpochSeconds) {
  EXPECT_DOUBLE_EQ(parseTime("1970-01-01T00:00:00Z"), 0.0);
  EXPECT_DOUBLE_EQ(parseTime("2012-03-01T10:00:00Z"), 1330596000.0);  // date -u -d @1330596000
  EXPECT_DOUBLE_EQ(parseTime("2012-03-01T12:00:00+02:00"), 1330596000.0);
  EXPECT_DOUBLE_EQ(parseTime("2012-03-01 10:00:00"), 1330596000.0);
  EXPECT_DOUBLE_EQ(parseTime("2012-03-01"), 1330560000.0);
  EXPECT_DOUBLE_EQ(parseTime("2012-03-01T10:00:00.250Z"), 1330596000.25);
  EXPECT_DOUBLE_EQ(parseTime("2000-02-29T00:00:00Z"), 951782400.0);  // a leap day
  EXPECT_DOUBLE_EQ(parseTime("1330596000"), 1330596000.0);
  EXPECT_DOUBLE_EQ(parseTime(" 1305031102.175304 "), 1305031102.175304);
}

TEST(Time, RejectsNonsenseWithTheText) {
  for (const char* bad : {"", "yesterday", "2012-13-01", "2011-02-29", "2012-03-01T25:00:00Z", "2012-03-01T10:00Zx",
                          "12abc", "nan", "inf"}) {
    EXPECT_THROW(parseTime(bad), UsageError) << bad;
  }
  try {
    parseTime("2012-3-1");
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("2012-3-1"), std::string::npos);
  }
}

TEST(Time, RefusesTimesOutsideFourDigitYears) {
  EXPECT_DOUBLE_EQ(parseTime("-62135596800"), kEarliestTime_s);  // 0001-01-01T00:00:00Z
  EXPECT_DOUBLE_EQ(parseTime("9999-12-31T23:59:59Z"), kLatestTime_s);
  EXPECT_EQ(formatTime(kLatestTime_s), "9999-12-31T23:59:59Z");
  EXPECT_EQ(formatTime(kEarliestTime_s), "0001-01-01T00:00:00Z");
  for (const char* bad : {"1e300", "-1e300", "253402300800", "-62135596801", "0000-06-01", "9999-12-31T23:59:59-01:00"}) {
    EXPECT_THROW(parseTime(bad), UsageError) << bad;
  }
  try {
    parseTime("1e300");
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("years 1 to 9999"), std::string::npos) << e.what();
  }
  EXPECT_EQ(formatTime(1e300), "invalid-time");  // never a year in the past
  EXPECT_EQ(formatTime(-1e300), "invalid-time");
}

TEST(Time, CheckTimeIsParseTimesRangeForNumbers) {
  // Python's times arrive as numbers; checkTime gives them the rule and words parseTime gives text.
  EXPECT_EQ(checkTime(kEarliestTime_s, "t"), kEarliestTime_s);
  EXPECT_EQ(checkTime(kLatestTime_s, "t"), kLatestTime_s);
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  for (double bad : {1e300, -1e300, kLatestTime_s + 1, kEarliestTime_s - 1, inf, -inf, nan}) {
    EXPECT_THROW(checkTime(bad, "t"), UsageError) << bad;
  }
  try {
    checkTime(1e300, "time 1e+300");
    FAIL();
  } catch (const UsageError& e) {
    std::string expected;
    try {
      parseTime("1e300");
    } catch (const UsageError& text) {
      expected = text.what();
    }
    EXPECT_EQ(std::string(e.what()), "time 1e+300" + expected.substr(expected.find(" lies outside")));
  }
  try {
    checkTime(nan, "t1 nan");
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("t1 nan is not a number", 0), 0u) << e.what();
  }
}

TEST(Time, FormatsAndRoundTrips) {
  EXPECT_EQ(formatTime(1330596000.0), "2012-03-01T10:00:00Z");
  EXPECT_EQ(formatTime(1330596000.25), "2012-03-01T10:00:00.250Z");
  EXPECT_EQ(formatTime(-1.0), "1969-12-31T23:59:59Z");
  for (double t : {0.0, 951782400.0, 1700000000.5, 4102444800.0}) EXPECT_DOUBLE_EQ(parseTime(formatTime(t)), t);
}

}  // namespace
}  // namespace chronomap
