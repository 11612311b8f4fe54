// Pose corrections: the World and PerPose models, per-frame parts, composition.

#include <gtest/gtest.h>

#include <numbers>

#include <Eigen/Geometry>

#include "chronomap/core/error.h"
#include "chronomap/align/pose_correction.h"

using namespace chronomap;

TEST(PoseCorrection, ComposesAndAppliesPerModel) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(10.0, 0.0, 0.5);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  m.translation() = Eigen::Vector3d(1.0, 2.0, 0.0);
  // World: the map frame turns about its origin, so the sensor moves from (10, 0) to (1, 12).
  const Eigen::Isometry3d w = PoseCorrection{m, CorrectionModel::World}.apply(pose);
  EXPECT_TRUE(w.translation().isApprox(Eigen::Vector3d(1.0, 12.0, 0.5)));
  // Per pose: the sensor turns in place and moves by the translation.
  const Eigen::Isometry3d p = PoseCorrection{m, CorrectionModel::PerPose}.apply(pose);
  EXPECT_TRUE(p.translation().isApprox(Eigen::Vector3d(11.0, 2.0, 0.5)));
  EXPECT_TRUE(p.linear().isApprox(m.linear()));
  // Composition equals applying one after the other, for both models.
  Eigen::Isometry3d m2 = Eigen::Isometry3d::Identity();
  m2.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  m2.translation() = Eigen::Vector3d(-0.5, 0.25, 2.0);
  for (CorrectionModel model : {CorrectionModel::World, CorrectionModel::PerPose}) {
    const PoseCorrection a{m, model}, b{m2, model};
    EXPECT_TRUE(a.then(b).apply(pose).isApprox(b.apply(a.apply(pose)), 1e-12));
  }
  EXPECT_THROW((PoseCorrection{m, CorrectionModel::World}.then(PoseCorrection{m2, CorrectionModel::PerPose})),
               UsageError);
  EXPECT_TRUE(PoseCorrection{}.isIdentity());
}

TEST(PoseCorrection, PerFramePartsApplyByIndexAndCompose) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(10.0, 0.0, 0.5);
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  Eigen::Isometry3d f0 = Eigen::Isometry3d::Identity(), f1 = Eigen::Isometry3d::Identity();
  f0.translation() = Eigen::Vector3d(0.0, 0.5, 0.0);
  f1.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const PoseCorrection c{m, CorrectionModel::World, {f0, f1}};
  EXPECT_TRUE(c.apply(pose, 0).translation().isApprox(Eigen::Vector3d(11.0, 0.5, 0.5)));
  // Frame 1 turns about its own (corrected) position.
  EXPECT_TRUE(c.apply(pose, 1).translation().isApprox(Eigen::Vector3d(11.0, 0.0, 0.5)));
  EXPECT_TRUE(c.apply(pose, 1).linear().isApprox(f1.linear()));
  EXPECT_THROW(c.apply(pose, 2), UsageError);
  EXPECT_FALSE(c.isIdentity());
  EXPECT_FALSE((PoseCorrection{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f0}}.isIdentity()));
  // A motion, then per-frame parts, then more per-frame parts: the same as one after the other.
  const PoseCorrection rigid{m, CorrectionModel::World, {}};
  const PoseCorrection drift{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f0, f1}};
  const PoseCorrection more{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f1, f0}};
  const PoseCorrection all = rigid.then(drift).then(more);
  for (size_t i = 0; i < 2; ++i) {
    const Eigen::Isometry3d step = more.apply(drift.apply(rigid.apply(pose, i), i), i);
    EXPECT_TRUE(all.apply(pose, i).isApprox(step, 1e-12)) << i;
  }
  // A motion cannot follow per-frame parts; per-frame parts of different lengths do not combine.
  EXPECT_THROW(drift.then(rigid), UsageError);
  EXPECT_THROW(drift.then(PoseCorrection{Eigen::Isometry3d::Identity(), CorrectionModel::World, {f0}}), UsageError);
}
