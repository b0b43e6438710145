// alignmentFitness: see alignment_fitness.hpp.
#include "scanalign/registration/alignment_fitness.hpp"

#include <cmath>
#include <cstddef>
#include <stdexcept>

#include "scanalign/common/threads.hpp"
#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

template <typename Scalar>
std::pair<double, double> alignmentFitness(const CloudView<Scalar>& source, const CloudView<Scalar>& target,
                                           const Eigen::Matrix4d& T, double threshold, int num_threads) {
  if (!(threshold > 0) || !std::isfinite(threshold))
    throw std::invalid_argument("alignmentFitness: threshold must be a finite positive distance in metres");
  if (!T.allFinite()) throw std::invalid_argument("alignmentFitness: transform is not finite");
  const LeftBalancedKdTree<Scalar> tree(target);
  if (tree.empty()) return {0.0, 0.0};
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  const Scalar thr2 = static_cast<Scalar>(threshold * threshold);
  std::size_t finite = 0, inl = 0;
  double acc = 0;
#pragma omp parallel for reduction(+ : finite, inl, acc) schedule(static) \
    num_threads(resolveThreads(num_threads))
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(source.size); ++ii) {
    if (!source.isFinite(ii)) continue;
    ++finite;
    const Eigen::Vector3d y = R * source[ii].template cast<double>() + t;
    const Scalar q[3] = {static_cast<Scalar>(y.x()), static_cast<Scalar>(y.y()), static_cast<Scalar>(y.z())};
    const auto nn = tree.nearest(q, thr2, LeftBalancedKdTree<Scalar>::kMaxStack);
    if (nn.found()) {
      ++inl;
      acc += double(nn.squared_distance);
    }
  }
  if (finite == 0) return {0.0, 0.0};
  return {double(inl) / double(finite), inl ? std::sqrt(acc / double(inl)) : 0.0};
}

#define SCANALIGN_INSTANTIATE(S)                                                                \
  template std::pair<double, double> alignmentFitness<S>(const CloudView<S>&, const CloudView<S>&, \
                                                         const Eigen::Matrix4d&, double, int);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
