// The saved models' files (.rhythm version 4, .colour version 2): what they were fitted on comes
// back; older versions still read without it; headers that announce more than their bytes hold,
// or times out of order, are refused with a clear error before anything is allocated.

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "builders.h"
#include "chronomap/analysis/colour.h"
#include "chronomap/analysis/rhythm.h"
#include "chronomap/core/error.h"
#include "chronomap/store/colour_file.h"
#include "chronomap/store/rhythm_file.h"

namespace chronomap {
namespace {

using test::at;

/// Five sessions at 100 .. 500 s; the voxel at x = 3 occupied in every other one.
TemporalMap fiveSessions() {
  TemporalMap map(0.05);
  for (int i = 0; i < 5; ++i) {
    SessionMap s(0.05);
    for (int x = 0; x < 6; ++x) {
      s.add(at(x, 0, 0), x == 3 && i % 2 == 0 ? test::occupiedVoxel(Rgb{9, 9, 9}) : test::freeVoxel());
    }
    map.add(100.0 * (i + 1), s);
  }
  return map;
}

/// A colour model of two voxels recording `map`'s sessions.
ColourModel colourOf(const TemporalMap& map) {
  ColourModel m;
  m.components = 1;
  m.bins = 4;
  m.curves.assign(3 * 4, 0.5);
  m.keys = {VoxelKey{1, 2, 3}, VoxelKey{4, 5, 6}};
  m.weights = {100.0f, 50.0f, 20.0f, 10.0f, 200.0f, 30.0f};
  m.resolution_m = map.resolution_m();
  m.from_s = map.times().front();
  m.to_s = map.times().back();
  m.sessions = map.sessionCount();
  m.observations = 8;
  m.fitted_on = fittedOn(map, m.from_s, m.to_s);
  return m;
}

template <class T>
void put(std::vector<uint8_t>& bytes, size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof(T));
}

/// What the reader says of `bytes` ("read" when it reads them).
template <class Read>
std::string refusal(Read read, const std::vector<uint8_t>& bytes) {
  try {
    read(bytes);
  } catch (const FormatError& e) {
    return e.what();
  }
  return "read";
}

const auto readRhythm = [](const std::vector<uint8_t>& b) { return deserializeRhythm(b, "m.rhythm"); };
const auto readColour = [](const std::vector<uint8_t>& b) { return deserializeColour(b, "m.colour"); };

// Offsets in a version 4 .rhythm: sessions (u32) at 32, the fingerprint at 36, the number of
// times at 44, the times from 52; in a version 2 .colour: sessions (u64) at 36, the fingerprint
// at 60, the number of times at 68, the times from 76.
constexpr size_t kRhythmSessions = 32, kRhythmFingerprint = 36, kRhythmTimes = 44;
constexpr size_t kColourSessions = 36, kColourFingerprint = 60, kColourTimes = 68;

TEST(ModelFiles, WhatAModelWasFittedOnComesBackAndOldVersionsStillRead) {
  const TemporalMap map = fiveSessions();
  const RhythmModels models = fitRhythm(map, 0.0, 1000.0);
  ASSERT_FALSE(models.voxels.empty());
  const std::vector<uint8_t> bytes = serialize(models);
  EXPECT_EQ(bytes.size(), models.bytes());
  EXPECT_EQ(bytes[4], 4);
  const RhythmModels back = deserializeRhythm(bytes, "m.rhythm");
  EXPECT_EQ(back.fitted_on.times_s, map.times());
  EXPECT_EQ(back.fitted_on.fingerprint, models.fitted_on.fingerprint);
  EXPECT_EQ(serialize(back), bytes);
  for (uint32_t version = 1; version <= 3; ++version) {
    const RhythmModels old = deserializeRhythm(serialize(models, version), "old.rhythm");
    EXPECT_FALSE(old.fitted_on.recorded()) << version;
    EXPECT_EQ(old.sessions, 5u);
    EXPECT_EQ(old.voxels.size(), models.voxels.size());
  }
  EXPECT_THROW(serialize(models, 5), UsageError);

  const ColourModel colour = colourOf(map);
  const std::vector<uint8_t> colour_bytes = serialize(colour);
  EXPECT_EQ(colour_bytes[4], 2);
  const ColourModel colour_back = deserializeColour(colour_bytes, "m.colour");
  EXPECT_EQ(colour_back.fitted_on.times_s, map.times());
  EXPECT_EQ(colour_back.fitted_on.fingerprint, colour.fitted_on.fingerprint);
  EXPECT_EQ(serialize(colour_back), colour_bytes);
  const ColourModel colour_v1 = deserializeColour(serialize(colour, 1), "old.colour");
  EXPECT_FALSE(colour_v1.fitted_on.recorded());
  EXPECT_EQ(colour_v1.keys, colour.keys);
  // A model fitted without a map records nothing, and reads back so.
  RhythmModels unfitted = models;
  unfitted.fitted_on = {};
  EXPECT_FALSE(deserializeRhythm(serialize(unfitted), "u.rhythm").fitted_on.recorded());
}

TEST(ModelFiles, HeadersThatAnnounceMoreThanTheBytesHoldAreRefused) {
  const TemporalMap map = fiveSessions();
  const std::vector<uint8_t> rhythm = serialize(fitRhythm(map, 0.0, 1000.0));
  const std::vector<uint8_t> colour = serialize(colourOf(map));
  constexpr uint32_t kHuge32 = 0xffffffffu;
  constexpr uint64_t kHuge64 = uint64_t{1} << 61;
  // Learning sessions' times beyond the bytes (the session count agreeing): refused, naming the
  // count, before 32 GiB (rhythm) or 16 EiB (colour) are asked for.
  std::vector<uint8_t> bad = rhythm;
  put(bad, kRhythmSessions, kHuge32);
  put(bad, kRhythmTimes, uint64_t{kHuge32});
  EXPECT_EQ(refusal(readRhythm, bad), "m.rhythm: the header announces 4294967295 learning sessions' times, more than the " +
                                          std::to_string(rhythm.size() - 52) + " bytes left hold (truncated or corrupt)");
  bad = colour;
  put(bad, kColourSessions, kHuge64);
  put(bad, kColourTimes, kHuge64);
  EXPECT_NE(refusal(readColour, bad).find("m.colour: the header announces 2305843009213693952 learning sessions' times"),
            std::string::npos);
  // Times that disagree with the session count, a fingerprint without times and times without one.
  bad = rhythm;
  put(bad, kRhythmTimes, uint64_t{4});
  EXPECT_EQ(refusal(readRhythm, bad), "m.rhythm: bad header (5 learning sessions but 4 times)");
  bad = rhythm;
  put(bad, kRhythmFingerprint, uint64_t{0});
  EXPECT_NE(refusal(readRhythm, bad).find("bad header (a map fingerprint missing for"), std::string::npos);
  bad = colour;
  put(bad, kColourFingerprint, uint64_t{0});
  EXPECT_NE(refusal(readColour, bad).find("m.colour: bad header (a map fingerprint"), std::string::npos);
  // Times out of order, not finite, or not the header's first and last.
  for (const auto& [index, value, message] :
       std::vector<std::tuple<size_t, double, std::string>>{{2, 150.0, "not finite and increasing"},
                                                            {1, std::numeric_limits<double>::quiet_NaN(), "not finite"},
                                                            {4, 450.0, "do not run from the header's first to its last"}}) {
    bad = rhythm;
    put(bad, 52 + 8 * index, value);
    EXPECT_NE(refusal(readRhythm, bad).find(message), std::string::npos) << refusal(readRhythm, bad);
    bad = colour;
    put(bad, 76 + 8 * index, value);
    EXPECT_NE(refusal(readColour, bad).find(message), std::string::npos) << refusal(readColour, bad);
  }
  // The learning range itself: not finite or backwards, in every version.
  for (uint32_t version : {3u, 4u}) {
    bad = serialize(fitRhythm(map, 0.0, 1000.0), version);
    put(bad, 16, std::numeric_limits<double>::infinity());
    EXPECT_EQ(refusal(readRhythm, bad),
              "m.rhythm: bad header (the learning sessions' first and last times are not a range of times)");
    bad = serialize(fitRhythm(map, 0.0, 1000.0), version);
    put(bad, 24, 50.0);  // before the first
    EXPECT_NE(refusal(readRhythm, bad).find("not a range of times"), std::string::npos) << version;
  }
  bad = serialize(colourOf(map), 1);
  put(bad, 28, -1e300);  // the last learning time before the first
  EXPECT_NE(refusal(readColour, bad).find("m.colour: bad header (the learning sessions'"), std::string::npos);
  // Voxel and group counts beyond the bytes.
  bad = rhythm;
  put(bad, 52 + 5 * 8, kHuge64);
  EXPECT_NE(refusal(readRhythm, bad).find("m.rhythm: the header announces 2305843009213693952 voxels, more than the"),
            std::string::npos);
  bad = rhythm;
  put(bad, bad.size() - 8, kHuge64);  // the group count: no groups in this model
  EXPECT_NE(refusal(readRhythm, bad).find("2305843009213693952 groups, more than its 0 bytes left hold"),
            std::string::npos);
  // A resolution no map has.
  bad = rhythm;
  put(bad, 8, 0.0);
  EXPECT_NE(refusal(readRhythm, bad).find("m.rhythm: bad header (resolution"), std::string::npos);
  // Every truncation is refused.
  for (size_t n = 0; n < rhythm.size(); ++n) {
    EXPECT_NE(refusal(readRhythm, std::vector<uint8_t>(rhythm.begin(), rhythm.begin() + static_cast<long>(n))), "read");
  }
  for (size_t n = 0; n < colour.size(); ++n) {
    EXPECT_NE(refusal(readColour, std::vector<uint8_t>(colour.begin(), colour.begin() + static_cast<long>(n))), "read");
  }
}

}  // namespace
}  // namespace chronomap
