// RANSAC over correspondences. See correspondence_ransac.hpp.
#include "scanalign/pose/correspondence_ransac.hpp"

#include "scanalign/common/rigid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

#include "scanalign/segmentation/ransac.hpp"
#include "scanalign/pose/motor_estimation.hpp"

namespace scanalign {

namespace {

/// The rigid motion of three pairs (Kabsch, common/rigid.hpp); false when a triangle is degenerate.
bool kabsch3(const Eigen::Vector3d x[3], const Eigen::Vector3d y[3], Eigen::Matrix4d& T) {
  const Eigen::Vector3d cx = (x[0] + x[1] + x[2]) / 3.0, cy = (y[0] + y[1] + y[2]) / 3.0;
  const Eigen::Vector3d ax = (x[1] - x[0]).cross(x[2] - x[0]), ay = (y[1] - y[0]).cross(y[2] - y[0]);
  const double ex = std::max({(x[1] - x[0]).squaredNorm(), (x[2] - x[0]).squaredNorm(), (x[2] - x[1]).squaredNorm()});
  const double ey = std::max({(y[1] - y[0]).squaredNorm(), (y[2] - y[0]).squaredNorm(), (y[2] - y[1]).squaredNorm()});
  if (!(ax.norm() > 1e-9 * ex) || !(ay.norm() > 1e-9 * ey)) return false;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 3; ++k) H += (y[k] - cy) * (x[k] - cx).transpose();
  const Eigen::Matrix3d R = rotationFromCrossCovariance(H).R;
  T.setIdentity();
  T.topLeftCorner<3, 3>() = R;
  T.topRightCorner<3, 1>() = cy - R * cx;
  return true;
}

}  // namespace

CorrespondenceRansacResult ransacRigidMotion(const CloudView<double>& source, const CloudView<double>& target,
                                             const std::uint32_t* pairs, std::size_t n_pairs,
                                             const CorrespondenceRansacSettings& s) {
  if (s.max_iterations < 1) throw std::invalid_argument("RANSAC: max_iterations must be >= 1");
  if (!(s.inlier_threshold > 0) || !std::isfinite(s.inlier_threshold))
    throw std::invalid_argument("RANSAC: inlier_threshold must be a finite positive distance in metres");
  if (!(s.edge_similarity >= 0 && s.edge_similarity < 1))
    throw std::invalid_argument("RANSAC: edge_similarity must be in [0, 1)");
  if (!(s.min_edge >= 0) || !std::isfinite(s.min_edge)) throw std::invalid_argument("RANSAC: min_edge must be >= 0");
  if (!(s.confidence > 0 && s.confidence < 1)) throw std::invalid_argument("RANSAC: confidence must be in (0, 1)");
  if (s.refine_iterations < 0 || s.num_threads < 0)
    throw std::invalid_argument("RANSAC: refine_iterations and num_threads must be >= 0");
  if (n_pairs > 0 && pairs == nullptr) throw std::invalid_argument("RANSAC: null pair list");
  // Gather the usable pairs' coordinates once.
  std::vector<Eigen::Vector3d> xs, ys;
  std::vector<std::uint32_t> ids;
  xs.reserve(n_pairs);
  ys.reserve(n_pairs);
  for (std::size_t k = 0; k < n_pairs; ++k) {
    const std::uint32_t i = pairs[2 * k], j = pairs[2 * k + 1];
    if (i >= source.size || j >= target.size) throw std::invalid_argument("RANSAC: pair index out of range");
    if (!source.isFinite(i) || !target.isFinite(j)) continue;
    xs.push_back(source[i]);
    ys.push_back(target[j]);
    ids.push_back(static_cast<std::uint32_t>(k));
  }
  CorrespondenceRansacResult out;
  const std::size_t n = xs.size();
  if (n < 3) {
    out.message = "fewer than 3 finite correspondences";
    return out;
  }
  const double thr2 = s.inlier_threshold * s.inlier_threshold, min_edge2 = s.min_edge * s.min_edge;
  auto countInliers = [&](const Eigen::Matrix4d& T) {
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    const Eigen::Vector3d t = T.topRightCorner<3, 1>();
    std::size_t c = 0;
    for (std::size_t k = 0; k < n; ++k) c += (ys[k] - (R * xs[k] + t)).squaredNorm() < thr2;
    return c;
  };
  // A 3-pair hypothesis: prerejected unless the two triangles' edges agree (a rigid motion
  // preserves lengths, so dissimilar triangles cannot both be inlier triples), then Kabsch.
  auto build = [&](const std::uint32_t* sample, Eigen::Matrix4d& T) {
    const Eigen::Vector3d x[3] = {xs[sample[0]], xs[sample[1]], xs[sample[2]]};
    const Eigen::Vector3d y[3] = {ys[sample[0]], ys[sample[1]], ys[sample[2]]};
    for (int e = 0; e < 3; ++e) {
      const double lx = (x[(e + 1) % 3] - x[e]).squaredNorm(), ly = (y[(e + 1) % 3] - y[e]).squaredNorm();
      if (lx < min_edge2 || ly < min_edge2) return false;
      if (std::sqrt(std::min(lx, ly) / std::max(std::max(lx, ly), 1e-300)) < s.edge_similarity) return false;
    }
    return kabsch3(x, y, T);
  };
  auto error = [&](const Eigen::Matrix4d& T, std::size_t k) {
    return (ys[k] - (T.topLeftCorner<3, 3>() * xs[k] + T.topRightCorner<3, 1>())).norm();
  };
  // The generic loop of fitting/ransac.hpp: deterministic samples per (seed, iteration),
  // adaptive stop at `confidence`, MSAC ranking, ties to the earlier hypothesis.
  RansacSettings loop;
  loop.threshold = s.inlier_threshold;
  loop.max_iterations = s.max_iterations;
  loop.confidence = s.confidence;
  loop.seed = s.seed;
  loop.num_threads = s.num_threads;
  loop.refine = false;
  loop.msac = true;
  Eigen::Matrix4d best_T = Eigen::Matrix4d::Identity();
  const RansacLoopStats st = ransacLoop(n, 3, build, error, loop, best_T);
  out.iterations = st.iterations;
  if (st.status != RansacStatus::kSuccess || st.best_inliers < 3) {
    out.message = "no hypothesis with 3 or more inliers (matches are inconsistent or degenerate)";
    return out;
  }
  // Least-squares refit on the inliers with the motor estimator (Valkenburg and Dorst; thesis paper 5, (36)-(44)), re-collecting them.
  Eigen::Matrix4d T = best_T;
  for (int r = 0; r < s.refine_iterations; ++r) {
    std::vector<double> xi, yi;
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    const Eigen::Vector3d t = T.topRightCorner<3, 1>();
    for (std::size_t k = 0; k < n; ++k)
      if ((ys[k] - (R * xs[k] + t)).squaredNorm() < thr2) {
        xi.insert(xi.end(), xs[k].data(), xs[k].data() + 3);
        yi.insert(yi.end(), ys[k].data(), ys[k].data() + 3);
      }
    const MotorEstimationResult m = estimateMotor(CloudView<double>(xi.data(), xi.size() / 3),
                                          CloudView<double>(yi.data(), yi.size() / 3));
    if (!m.valid || countInliers(m.T_target_source) < countInliers(T)) break;
    T = m.T_target_source;
  }
  out.T_target_source = T;
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  double acc = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double d2 = (ys[k] - (R * xs[k] + t)).squaredNorm();
    if (d2 < thr2) {
      out.inliers.push_back(ids[k]);
      acc += d2;
    }
  }
  out.found = out.inliers.size() >= 3;
  out.inlier_rmse = out.inliers.empty() ? 0.0 : std::sqrt(acc / out.inliers.size());
  if (!out.found) out.message = "the refit lost its inliers";
  return out;
}

}  // namespace scanalign
