// lookAt: see look_at.hpp.
#include "scanalign/common/look_at.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Geometry>  // cross()

namespace scanalign {

Eigen::Matrix4d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  for (const auto& [v, name] : {std::pair{&eye, "eye"}, std::pair{&target, "target"}, std::pair{&up, "up"}})
    if (!v->allFinite()) throw std::invalid_argument(std::string(name) + ": expected three finite coordinates (m)");
  Eigen::Vector3d z = target - eye;
  if (!(z.norm() > 0)) throw std::invalid_argument("lookAt: eye and target coincide");
  z.normalize();
  const Eigen::Vector3d up_perp = up - up.dot(z) * z;
  if (up_perp.norm() < 1e-9 * std::max(1.0, up.norm()))
    throw std::invalid_argument("lookAt: viewing direction parallel to up; give another up vector");
  const Eigen::Vector3d y = -up_perp.normalized(), x = y.cross(z);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 1>(0, 0) = x;
  T.block<3, 1>(0, 1) = y;
  T.block<3, 1>(0, 2) = z;
  T.block<3, 1>(0, 3) = eye;
  return T;
}

}  // namespace scanalign
