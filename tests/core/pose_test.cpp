#include <gtest/gtest.h>

#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"

namespace chronomap {
namespace {

TEST(Pose, BuildsFromTranslationAndQuaternion) {
  const double s = std::sqrt(0.5);
  const auto T = poseFromTranslationQuaternion({1, 2, 3}, 0, 0, s, s, "test");  // 90 deg about z
  const Eigen::Vector3d p = T * Eigen::Vector3d(1, 0, 0);
  EXPECT_NEAR(p.x(), 1.0, 1e-12);
  EXPECT_NEAR(p.y(), 3.0, 1e-12);
  EXPECT_NEAR(p.z(), 3.0, 1e-12);
}

TEST(Pose, NormalisesSlightlyOffQuaternions) {
  const auto T = poseFromTranslationQuaternion({0, 0, 0}, 0, 0, 0, 1.005, "test");
  EXPECT_NEAR((T.linear() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
}

TEST(Pose, RejectsZeroNonUnitAndNonFiniteQuaternions) {
  EXPECT_THROW(poseFromTranslationQuaternion({0, 0, 0}, 0, 0, 0, 0, "t"), DataError);
  EXPECT_THROW(poseFromTranslationQuaternion({0, 0, 0}, 0, 0, 0, 2, "t"), DataError);
  EXPECT_THROW(poseFromTranslationQuaternion({0, 0, 0}, 0, 0, 0, std::nan(""), "t"), DataError);
  EXPECT_THROW(poseFromTranslationQuaternion({std::nan(""), 0, 0}, 0, 0, 0, 1, "t"), DataError);
  try {
    poseFromTranslationQuaternion({0, 0, 0}, 0, 0, 0, 2, "poses.txt:7");
    FAIL();
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("poses.txt:7"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("not a unit quaternion"), std::string::npos);
  }
}

TEST(Pose, RejectsMatricesThatAreNotRigid) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  EXPECT_NO_THROW(poseFromMatrix(m, "t"));
  m(0, 0) = 2.0;  // scale
  EXPECT_THROW(poseFromMatrix(m, "t"), DataError);
  m = Eigen::Matrix4d::Identity();
  m(0, 0) = -1.0;  // reflection
  EXPECT_THROW(poseFromMatrix(m, "t"), DataError);
  m = Eigen::Matrix4d::Identity();
  m(3, 0) = 1.0;  // projective bottom row
  EXPECT_THROW(poseFromMatrix(m, "t"), DataError);
  m = Eigen::Matrix4d::Identity();
  m(1, 3) = std::nan("");
  EXPECT_THROW(poseFromMatrix(m, "t"), DataError);
}

TEST(Pose, ParsesTheCommandLineForm) {
  const auto T = parsePose("1,2,3,0,0,0,1");
  EXPECT_EQ(T.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_THROW(parsePose("1,2,3"), UsageError);
  EXPECT_THROW(parsePose("1,2,x,0,0,0,1"), UsageError);
}

}  // namespace
}  // namespace chronomap
