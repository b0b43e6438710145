// Euclidean clustering by union-find over a cell grid. See euclidean_clusters.hpp.
#include "scanalign/segmentation/euclidean_clusters.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include <Eigen/Core>

#include "scanalign/common/interrupt.hpp"
#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

namespace {

/// Clusters of input indices in the documented order: ascending indices within a cluster;
/// clusters by decreasing size, ties by smallest first index; sizes within [min, max].
std::vector<std::vector<std::uint32_t>> orderClusters(std::vector<std::vector<std::uint32_t>> all,
                                                      std::size_t min_size, std::size_t max_size) {
  std::vector<std::vector<std::uint32_t>> clusters;
  for (auto& c : all)
    if (c.size() >= min_size && c.size() <= max_size) {
      std::sort(c.begin(), c.end());
      clusters.push_back(std::move(c));
    }
  std::sort(clusters.begin(), clusters.end(), [](const auto& a, const auto& b) {
    return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
  });
  return clusters;
}

/// Region growing on the k-d tree (PCL's EuclideanClusterExtraction): every point's whole
/// radius neighbourhood is visited, so a tolerance that links most points to most others
/// costs O(N^2). Kept only for clouds whose extent is beyond 2^52 tolerance-sized cells,
/// where the cell grid below cannot index cells.
template <typename Scalar>
std::vector<std::vector<std::uint32_t>> regionGrowing(const CloudView<Scalar>& points,
                                                      const std::vector<std::uint32_t>& sel, Scalar r2) {
  LeftBalancedKdTree<Scalar> tree;
  std::vector<char> selected(points.size, 0);
  for (std::uint32_t i : sel) selected[i] = 1;
  tree.build(points, [&](std::size_t i) { return selected[i] != 0; });
  std::vector<char> visited(points.size, 0);
  std::vector<std::vector<std::uint32_t>> all;
  for (std::uint32_t seed : sel) {
    if (visited[seed]) continue;
    checkInterrupt();
    std::vector<std::uint32_t> cluster{seed};
    visited[seed] = 1;
    for (std::size_t head = 0; head < cluster.size(); ++head)
      tree.forEachInRadius(points.ptr(cluster[head]), r2, [&](std::uint32_t node, Scalar) {
        const std::uint32_t j = tree.node(node).index();
        if (!visited[j]) {
          visited[j] = 1;
          cluster.push_back(j);
        }
      });
    all.push_back(std::move(cluster));
  }
  return all;
}

}  // namespace

// Connected components of the graph "|p - q| <= tolerance" (the links PCL's region growing
// follows) by union-find over a grid of cells of edge a bit under tolerance / sqrt(3):
// any two points of one cell are closer than tolerance, so each cell is one node, and only
// cells within 2 cells of each other along every axis can hold linked points. A pair of cells
// already in one component is never tested; otherwise the first linked pair ends the test.
// So the cost is O(N log N) in the number of points whatever the tolerance -- region
// growing visits every neighbour of every point, O(N^2) once the tolerance spans the scene
// (200k points: minutes). Pairs of large cells are tested through a k-d tree over the
// larger one, so no pair costs more than (smaller cell) x log(larger cell). The links are
// decided by the same test in the cloud's precision as the k-d tree's radius search, so
// the clusters are those of region growing.
template <typename Scalar>
std::vector<std::vector<std::uint32_t>> euclideanClusters(const CloudView<Scalar>& points,
                                                          const std::vector<std::uint32_t>& indices,
                                                          double tolerance, std::size_t min_size,
                                                          std::size_t max_size) {
  if (indices.empty()) return {};
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw std::invalid_argument("euclideanClusters: tolerance must be a finite positive distance in metres");
  std::vector<std::uint32_t> sel;
  sel.reserve(indices.size());
  for (std::uint32_t i : indices) {
    if (i >= points.size) throw std::invalid_argument("euclideanClusters: index out of range");
    if (points.isFinite(i)) sel.push_back(i);
  }
  std::sort(sel.begin(), sel.end());
  sel.erase(std::unique(sel.begin(), sel.end()), sel.end());
  if (sel.empty()) return {};
  const Scalar r2 = static_cast<Scalar>(tolerance * tolerance);
  // Cell edge: the cell's diagonal is tolerance (1 - 1e-6), a margin far above the rounding
  // of the squared-distance test, so points of one cell are always linked.
  const double edge = tolerance / std::sqrt(3.0) * (1.0 - 1e-6);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (std::uint32_t i : sel) lo = lo.cwiseMin(points[i].template cast<double>());
  struct Keyed {
    std::int64_t z, y, x;
    std::uint32_t i;
  };
  std::vector<Keyed> keyed(sel.size());
  for (std::size_t j = 0; j < sel.size(); ++j) {
    const Eigen::Vector3d c = ((points[sel[j]].template cast<double>() - lo) / edge).array().floor();
    if (!(c.maxCoeff() < 4503599627370496.0))  // 2^52: cells no longer indexable
      return orderClusters(regionGrowing(points, sel, r2), min_size, max_size);
    keyed[j] = {static_cast<std::int64_t>(c.z()), static_cast<std::int64_t>(c.y()), static_cast<std::int64_t>(c.x()),
                sel[j]};
  }
  auto before = [](const Keyed& a, const Keyed& b) {
    return a.z != b.z ? a.z < b.z : (a.y != b.y ? a.y < b.y : a.x < b.x);
  };
  std::sort(keyed.begin(), keyed.end(), [&](const Keyed& a, const Keyed& b) {
    return before(a, b) || (!before(b, a) && a.i < b.i);
  });
  // Cells (contiguous runs of keyed) and their points, packed in the cloud's precision.
  std::vector<std::uint32_t> cell_start;
  for (std::size_t j = 0; j < keyed.size(); ++j)
    if (j == 0 || before(keyed[j - 1], keyed[j])) cell_start.push_back(static_cast<std::uint32_t>(j));
  const std::size_t nc = cell_start.size();
  cell_start.push_back(static_cast<std::uint32_t>(keyed.size()));
  std::vector<Scalar> packed(3 * keyed.size());
  for (std::size_t j = 0; j < keyed.size(); ++j)
    for (int k = 0; k < 3; ++k) packed[3 * j + k] = points.ptr(keyed[j].i)[k];
  std::vector<std::uint32_t> parent(nc);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t c) {
    while (parent[c] != c) c = parent[c] = parent[parent[c]];
    return c;
  };
  std::vector<LeftBalancedKdTree<Scalar>> trees(nc);  // built on demand, for large cells
  const Scalar below_r2 = std::nextafter(r2, std::numeric_limits<Scalar>::infinity());  // nearest() is strict
  auto linked = [&](std::size_t a, std::size_t b) {
    std::size_t na = cell_start[a + 1] - cell_start[a], nb = cell_start[b + 1] - cell_start[b];
    if (na > nb) {
      std::swap(a, b);
      std::swap(na, nb);
    }
    const Scalar* pa = &packed[3 * std::size_t{cell_start[a]}];
    const Scalar* pb = &packed[3 * std::size_t{cell_start[b]}];
    if (na * nb <= 4096) {
      for (std::size_t u = 0; u < na; ++u)
        for (std::size_t v = 0; v < nb; ++v)
          if (detail::squaredDistance(pa + 3 * u, pb + 3 * v) <= r2) return true;
      return false;
    }
    if (trees[b].empty()) trees[b].build(CloudView<Scalar>(pb, nb, 3));
    for (std::size_t u = 0; u < na; ++u)
      if (trees[b].nearest(pa + 3 * u, below_r2, LeftBalancedKdTree<Scalar>::kMaxStack).found()) return true;
    return false;
  };
  // Each pair of cells once: cell b after cell a in (z, y, x) order, in the 13 rows
  // (dz, dy) at or after a's own. For a fixed row offset, the first candidate (z + dz,
  // y + dy, x - 2) grows with a, so one pointer per row walks the cells once. Near pairs
  // (within one cell along every axis) first: on dense data they join almost every
  // component, so the farther pairs, which are the expensive ones to refute, are mostly
  // skipped as already joined.
  for (const std::int64_t reach : {1, 2}) {
    for (std::int64_t dz = 0; dz <= reach; ++dz)
      for (std::int64_t dy = dz == 0 ? 0 : -reach; dy <= reach; ++dy) {
        std::size_t next = 0;  // first cell not before the current row window
        for (std::size_t a = 0; a < nc; ++a) {
          if (a % 4096 == 0) checkInterrupt();
          const Keyed& ka = keyed[cell_start[a]];
          const std::int64_t x0 = dz == 0 && dy == 0 ? ka.x + 1 : ka.x - reach;
          const Keyed first{ka.z + dz, ka.y + dy, x0, 0};
          while (next < nc && before(keyed[cell_start[next]], first)) ++next;
          for (std::size_t b = next; b < nc; ++b) {
            const Keyed& kb = keyed[cell_start[b]];
            if (kb.z != first.z || kb.y != first.y || kb.x > ka.x + reach) break;
            // Pairs within one cell along every axis belong to the first pass only.
            if (reach == 2 && std::abs(dz) < 2 && std::abs(dy) < 2 && std::abs(kb.x - ka.x) < 2) continue;
            const std::uint32_t ra = find(static_cast<std::uint32_t>(a)), rb = find(static_cast<std::uint32_t>(b));
            if (ra != rb && linked(a, b)) parent[std::max(ra, rb)] = std::min(ra, rb);
          }
        }
      }
  }
  std::vector<std::vector<std::uint32_t>> all;
  std::vector<std::int64_t> slot(nc, -1);
  for (std::size_t c = 0; c < nc; ++c) {
    const std::uint32_t r = find(static_cast<std::uint32_t>(c));
    if (slot[r] < 0) {
      slot[r] = static_cast<std::int64_t>(all.size());
      all.emplace_back();
    }
    auto& cluster = all[static_cast<std::size_t>(slot[r])];
    for (std::uint32_t j = cell_start[c]; j < cell_start[c + 1]; ++j) cluster.push_back(keyed[j].i);
  }
  return orderClusters(std::move(all), min_size, max_size);
}

#define SCANALIGN_INSTANTIATE(S)                                                                                   \
  template std::vector<std::vector<std::uint32_t>> euclideanClusters<S>(                                           \
      const CloudView<S>&, const std::vector<std::uint32_t>&, double, std::size_t, std::size_t);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
