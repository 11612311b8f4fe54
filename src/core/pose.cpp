#include "chronomap/core/pose.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "chronomap/core/error.h"

namespace chronomap {

Eigen::Isometry3d poseFromTranslationQuaternion(const Eigen::Vector3d& t, double qx, double qy, double qz,
                                                double qw, const std::string& context) {
  if (!t.allFinite() || !std::isfinite(qx) || !std::isfinite(qy) || !std::isfinite(qz) || !std::isfinite(qw)) {
    throw DataError(context + ": pose has a value that is not a finite number");
  }
  Eigen::Quaterniond q(qw, qx, qy, qz);
  const double norm = q.norm();
  if (norm == 0.0) throw DataError(context + ": pose quaternion is zero");
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    std::ostringstream msg;
    msg << context << ": pose quaternion is not a unit quaternion (norm " << norm << ")";
    throw DataError(msg.str());
  }
  q.normalize();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.toRotationMatrix();
  pose.translation() = t;
  return pose;
}

Eigen::Isometry3d poseFromMatrix(const Eigen::Matrix4d& m, const std::string& context) {
  if (!m.allFinite()) throw DataError(context + ": pose matrix has a value that is not a finite number");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const double ortho_error = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const Eigen::RowVector4d bottom = m.row(3);
  if (ortho_error > kRotationOrthonormalityTolerance || r.determinant() < 0.0 ||
      (bottom - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    std::ostringstream msg;
    msg << context << ": pose is not a rigid transform (|R^T R - I| = " << ortho_error
        << ", det R = " << r.determinant() << ")";
    throw DataError(msg.str());
  }
  // Re-orthonormalise so that small rounding in text files does not accumulate.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Quaterniond(r).normalized().toRotationMatrix();
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

Eigen::Isometry3d parsePose(const std::string& text) {
  std::string cleaned = text;
  for (char& c : cleaned) {
    if (c == ',') c = ' ';
  }
  std::istringstream in(cleaned);
  std::vector<double> v;
  std::string token;
  while (in >> token) {
    try {
      size_t used = 0;
      v.push_back(std::stod(token, &used));
      if (used != token.size()) throw std::invalid_argument(token);
    } catch (const std::exception&) {
      throw UsageError("pose '" + text + "': '" + token + "' is not a number");
    }
  }
  if (v.size() != 7) throw UsageError("pose '" + text + "' must be seven numbers: tx,ty,tz,qx,qy,qz,qw");
  return poseFromTranslationQuaternion({v[0], v[1], v[2]}, v[3], v[4], v[5], v[6], "pose '" + text + "'");
}

}  // namespace chronomap
