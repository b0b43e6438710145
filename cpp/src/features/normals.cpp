#include "scanalign/features/normals.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

namespace scanalign {

namespace {

void validateSettings(const NormalEstimationSettings& settings) {
  if (!(settings.radius > 0.0) || !std::isfinite(settings.radius))
    throw std::invalid_argument("normal estimation: radius must be a finite positive distance in metres");
  if (!settings.viewpoint.allFinite()) throw std::invalid_argument("normal estimation: viewpoint must be finite");
  if (settings.min_neighbors < 3) throw std::invalid_argument("normal estimation: min_neighbors must be >= 3");
  if (settings.num_threads < 0) throw std::invalid_argument("normal estimation: num_threads must be >= 0");
}

/// Normal (and curvature) of point q from the moments of its neighbours' offsets d = p - q:
/// s1 = sum d, s2 = sum d d^T, k neighbours. Writes NaN when k < min_neighbors.
template <typename Scalar>
void finishNormal(const Scalar* q, const Eigen::Vector3d& s1, const Eigen::Matrix3d& s2, int k,
                  const NormalEstimationSettings& settings, Scalar* out, Scalar* curvature) {
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  out[0] = out[1] = out[2] = nan;
  if (curvature) *curvature = nan;
  if (k < settings.min_neighbors) return;
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
    *curvature = static_cast<Scalar>(sum > 0.0 ? lambda(0) / sum : 0.0);
  }
}

/// Radius neighbourhoods from a uniform grid of cells with edge = radius: every neighbour
/// of a point lies in the 27 cells around its own. Points are sorted by cell so each cell
/// and its candidates are contiguous in memory, and the 27 candidate ranges are looked up
/// once per cell, not per point. On voxel-downsampled scans this is several times faster
/// than a radius search down a one-point-per-node tree. Returns false (nothing written)
/// when the cloud's extent needs more than 2^21 cells along an axis.
template <typename Scalar>
bool gridNormals(const CloudView<Scalar>& points, const NormalEstimationSettings& settings, Scalar* normals,
                 Scalar* curvature) {
  const double r = settings.radius, r2 = r * r, inv = 1.0 / r;
  std::int64_t lo[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, hi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
  std::vector<std::uint32_t> finite;
  finite.reserve(points.size);
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    const Scalar* p = points.ptr(i);
    for (int k = 0; k < 3; ++k) {
      const double c = std::floor(double(p[k]) * inv);
      if (!(std::abs(c) < 1e15)) return false;
      lo[k] = std::min(lo[k], static_cast<std::int64_t>(c));
      hi[k] = std::max(hi[k], static_cast<std::int64_t>(c));
    }
    finite.push_back(static_cast<std::uint32_t>(i));
  }
  if (finite.empty()) return true;
  constexpr std::int64_t kAxis = (std::int64_t{1} << 21) - 2;  // room for the +-1 neighbours
  for (int k = 0; k < 3; ++k)
    if (hi[k] - lo[k] >= kAxis) return false;
  auto cellOf = [&](const Scalar* p, int k) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(double(p[k]) * inv)) - lo[k] + 1);
  };
  auto key = [](std::uint64_t x, std::uint64_t y, std::uint64_t z) { return (z << 42) | (y << 21) | x; };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(finite.size());
  for (std::size_t j = 0; j < finite.size(); ++j) {
    const Scalar* p = points.ptr(finite[j]);
    keyed[j] = {key(cellOf(p, 0), cellOf(p, 1), cellOf(p, 2)), finite[j]};
  }
  std::sort(keyed.begin(), keyed.end());
  const std::size_t m = keyed.size();
  // Sorted copy, as offsets from the cloud's first point for precision; float clouds are
  // processed in float (vectorised), double clouds in double.
  std::vector<Scalar> xyz(3 * m);
  const Scalar* origin = points.ptr(keyed[0].second);
  for (std::size_t j = 0; j < m; ++j) {
    const Scalar* p = points.ptr(keyed[j].second);
    for (int k = 0; k < 3; ++k) xyz[3 * j + k] = static_cast<Scalar>(double(p[k]) - double(origin[k]));
  }
  std::vector<std::uint64_t> cell_keys;
  std::vector<std::uint32_t> cell_start;
  for (std::size_t j = 0; j < m; ++j)
    if (j == 0 || keyed[j].first != keyed[j - 1].first) {
      cell_keys.push_back(keyed[j].first);
      cell_start.push_back(static_cast<std::uint32_t>(j));
    }
  cell_start.push_back(static_cast<std::uint32_t>(m));
  const std::size_t cells = cell_keys.size();
  const int threads = settings.num_threads > 0 ? settings.num_threads : omp_get_max_threads();
  const Scalar r2s = static_cast<Scalar>(r2);
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads)
  for (std::ptrdiff_t cc = 0; cc < static_cast<std::ptrdiff_t>(cells); ++cc) {
    const std::uint64_t k0 = cell_keys[cc];
    const std::uint64_t x = k0 & 0x1FFFFF, y = (k0 >> 21) & 0x1FFFFF, z = k0 >> 42;
    std::array<std::pair<std::uint32_t, std::uint32_t>, 27> ranges;
    int nr = 0;
    for (std::uint64_t dz = z - 1; dz <= z + 1; ++dz)
      for (std::uint64_t dy = y - 1; dy <= y + 1; ++dy) {
        // The three cells along x are consecutive keys: one search finds the first.
        const std::uint64_t first = key(x - 1, dy, dz), last = key(x + 1, dy, dz);
        auto it = std::lower_bound(cell_keys.begin(), cell_keys.end(), first);
        const std::size_t a = static_cast<std::size_t>(it - cell_keys.begin());
        std::size_t b = a;
        while (b < cells && cell_keys[b] <= last) ++b;
        if (b > a) ranges[nr++] = {cell_start[a], cell_start[b]};
      }
    for (std::uint32_t j = cell_start[cc]; j < cell_start[cc + 1]; ++j) {
      const Scalar qx = xyz[3 * j], qy = xyz[3 * j + 1], qz = xyz[3 * j + 2];
      // Moments of the offsets from the query in the cloud's precision: offsets are within
      // the radius, so float sums of a few hundred terms keep ~6 significant digits, plenty
      // for a normal of float data, and float lets the compiler vectorise this loop.
      Scalar m[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};  // x y z xx xy xz yy yz zz count
      for (int rr = 0; rr < nr; ++rr)
        for (std::uint32_t c = ranges[rr].first; c < ranges[rr].second; ++c) {
          const Scalar dx = xyz[3 * c] - qx, dy = xyz[3 * c + 1] - qy, dz = xyz[3 * c + 2] - qz;
          const Scalar w = dx * dx + dy * dy + dz * dz <= r2s ? Scalar(1) : Scalar(0);
          m[0] += w * dx;
          m[1] += w * dy;
          m[2] += w * dz;
          m[3] += w * dx * dx;
          m[4] += w * dx * dy;
          m[5] += w * dx * dz;
          m[6] += w * dy * dy;
          m[7] += w * dy * dz;
          m[8] += w * dz * dz;
          m[9] += w;
        }
      const Eigen::Vector3d s1(m[0], m[1], m[2]);
      Eigen::Matrix3d s2;
      s2 << m[3], m[4], m[5], m[4], m[6], m[7], m[5], m[7], m[8];
      const int k = static_cast<int>(m[9] + Scalar(0.5));
      const std::uint32_t i = keyed[j].second;
      finishNormal(points.ptr(i), s1, s2, k, settings, normals + 3 * i, curvature ? curvature + i : nullptr);
    }
  }
  return true;
}

}  // namespace

template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const LeftBalancedKdTree<Scalar>& tree,
                     const NormalEstimationSettings& settings, Scalar* normals, Scalar* curvature) {
  validateSettings(settings);
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
    finishNormal(q, s1, s2, k, settings, out, curvature ? curvature + i : nullptr);
  }
}

template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const NormalEstimationSettings& settings, Scalar* normals,
                     Scalar* curvature) {
  validateSettings(settings);
  if (points.size > 0 && normals == nullptr) throw std::invalid_argument("normal estimation: null output");
  const Scalar nan = std::numeric_limits<Scalar>::quiet_NaN();
  for (std::size_t i = 0; i < points.size; ++i) {
    normals[3 * i] = normals[3 * i + 1] = normals[3 * i + 2] = nan;
    if (curvature) curvature[i] = nan;
  }
  if (gridNormals(points, settings, normals, curvature)) return;
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
