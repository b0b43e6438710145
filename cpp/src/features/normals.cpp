#include "scanalign/features/normals.hpp"

#include <omp.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace scanalign {

template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const LeftBalancedKdTree<Scalar>& tree,
                     const NormalEstimationSettings& settings, Scalar* normals, Scalar* curvature) {
  if (!(settings.radius > 0.0) || !std::isfinite(settings.radius))
    throw std::invalid_argument("normal estimation: radius must be a finite positive distance in metres");
  if (!settings.viewpoint.allFinite()) throw std::invalid_argument("normal estimation: viewpoint must be finite");
  if (settings.min_neighbors < 3) throw std::invalid_argument("normal estimation: min_neighbors must be >= 3");
  if (settings.num_threads < 0) throw std::invalid_argument("normal estimation: num_threads must be >= 0");
  if (points.size > 0 && normals == nullptr) throw std::invalid_argument("normal estimation: null output");
  const Scalar r2 = static_cast<Scalar>(settings.radius * settings.radius);
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  const int threads = settings.num_threads > 0 ? settings.num_threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(points.size); ++ii) {
    const std::size_t i = static_cast<std::size_t>(ii);
    Scalar* out = normals + 3 * i;
    out[0] = out[1] = out[2] = nan;
    if (curvature) curvature[i] = nan;
    if (!points.isFinite(i)) continue;
    const Scalar* q = points.ptr(i);
    // Moments about the query point (not the origin) to avoid cancellation far from it.
    Eigen::Vector3d s1 = Eigen::Vector3d::Zero();
    Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
    int k = 0;
    tree.forEachInRadius(q, r2, [&](std::uint32_t node, Scalar) {
      const Scalar* p = tree.node(node).p;
      const Eigen::Vector3d d(double(p[0]) - q[0], double(p[1]) - q[1], double(p[2]) - q[2]);
      s1 += d;
      s2.noalias() += d * d.transpose();
      ++k;
    });
    if (k < settings.min_neighbors) continue;
    const Eigen::Vector3d mean = s1 / k;
    const Eigen::Matrix3d cov = s2 / k - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(cov);
    Eigen::Vector3d n = eig.eigenvectors().col(0);
    const Eigen::Vector3d to_view = settings.viewpoint - Eigen::Vector3d(q[0], q[1], q[2]);
    if (n.dot(to_view) < 0.0) n = -n;
    n.normalize();
    out[0] = static_cast<Scalar>(n.x());
    out[1] = static_cast<Scalar>(n.y());
    out[2] = static_cast<Scalar>(n.z());
    if (curvature) {
      const Eigen::Vector3d lambda = eig.eigenvalues().cwiseMax(0.0);
      const double sum = lambda.sum();
      curvature[i] = static_cast<Scalar>(sum > 0.0 ? lambda(0) / sum : 0.0);
    }
  }
}

template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const NormalEstimationSettings& settings, Scalar* normals,
                     Scalar* curvature) {
  LeftBalancedKdTree<Scalar> tree(points);
  estimateNormals(points, tree, settings, normals, curvature);
}

#define SCANALIGN_INSTANTIATE(S)                                                                              \
  template void estimateNormals<S>(const CloudView<S>&, const NormalEstimationSettings&, S*, S*);             \
  template void estimateNormals<S>(const CloudView<S>&, const LeftBalancedKdTree<S>&,                         \
                                   const NormalEstimationSettings&, S*, S*);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
