#pragma once
// A point as the pipeline's JSON reports write it: [x, y, z].

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace chronomap::pipeline_detail {

inline nlohmann::json vec3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace chronomap::pipeline_detail
