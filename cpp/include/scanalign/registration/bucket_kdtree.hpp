// K-d tree with leaf buckets: the CPU search structure of the ICP engine.
//
// The left-balanced tree of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3.1
// (kdtree.hpp) keeps one point per node so
// that it is one pointer-free array a GPU can walk. On a CPU that layout costs a node
// visit -- a cache line, a distance and a branch -- per point on the way down. Here the
// recursion stops at small buckets (8 points by default, as in the FLANN / nanoflann
// trees that PCL, Open3D and small_gicp use): the points of a bucket sit next to each
// other in x, y and z arrays, so a leaf is one short loop the compiler vectorises, and
// the tree has a sixteenth of the nodes.
//
// Every node keeps the tight bounding box of its points. Scan points lie on surfaces, so
// a query a millimetre off the surface is near many splitting planes but near few tight
// boxes; pruning by box distance is exact and visits far fewer nodes. Nodes are stored
// depth first (the left child follows its parent), the build splits at the median along
// the box's longest side, and the top of the tree is built in parallel.
//
// The search is exact: the stack holds every pending branch (its depth bound, kMaxStack,
// exceeds the tree's height for any cloud that fits in 32-bit indices).
//
// ICP asks for nearly the same neighbours in every iteration, so a search may start from
// a hint (last iteration's neighbour). It then starts bottom-up: it scans the hint's
// leaf, and climbs from that leaf only until the ball around the query with the best
// distance so far lies strictly inside a node's k-d cell (the region its splits assign
// to it, not the tight box), searching on the way the sibling subtrees the ball reaches.
// No point outside that node's subtree can be closer, and its whole subtree has then been
// searched. On a 1 mm scan grid about half the queries end in their hint's leaf, without
// touching the top of the tree.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include <omp.h>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/common/threads.hpp"
#include "scanalign/registration/kdtree.hpp"  // NearestNeighbor

namespace scanalign {

template <typename Scalar>
class BucketKdTree {
 public:
  static constexpr int kMaxLeafSize = 64;
  /// Points per leaf. 8 measured fastest for ICP queries on 1 mm scan grids and on
  /// sparse LiDAR (bench/bench_peers.py); 4-16 are within 10 %.
  static constexpr int kDefaultLeafSize = 8;
  static constexpr int kMaxStack = 64;

  struct Node {
    Scalar lo[3], hi[3];   ///< tight bounding box of the node's points
    std::uint32_t first;   ///< leaf: position of its first point; inner: index of the right child
    std::uint32_t count;   ///< leaf: number of points (> 0); inner: 0 (the left child is this + 1)
    bool leaf() const { return count != 0; }
  };

  BucketKdTree() = default;
  explicit BucketKdTree(const CloudView<Scalar>& cloud, int leaf_size = kDefaultLeafSize) { build(cloud, leaf_size); }

  /// Builds over the finite points of `cloud`. O(n log n).
  void build(const CloudView<Scalar>& cloud, int leaf_size = kDefaultLeafSize) {
    build(cloud, [](std::size_t) { return true; }, leaf_size);
  }
  /// As build(cloud), keeping only the finite points i with keep(i). `num_threads` OpenMP
  /// threads build the top of the tree (0: OpenMP's default).
  template <typename Keep>
  void build(const CloudView<Scalar>& cloud, Keep&& keep, int leaf_size = kDefaultLeafSize, int num_threads = 0);

  std::size_t size() const { return index_.size(); }
  bool empty() const { return index_.empty(); }
  int height() const { return height_; }
  int leafSize() const { return leaf_size_; }
  std::size_t nodeCount() const { return nodes_.size(); }
  /// Index in the input cloud of the point at tree position `pos`.
  std::uint32_t index(std::size_t pos) const { return index_[pos]; }
  /// Coordinates of the point at tree position `pos`.
  Scalar x(std::size_t pos) const { return x_[pos]; }
  Scalar y(std::size_t pos) const { return y_[pos]; }
  Scalar z(std::size_t pos) const { return z_[pos]; }
  Scalar squaredDistance(const Scalar* q, std::size_t pos) const {
    const Scalar dx = x_[pos] - q[0], dy = y_[pos] - q[1], dz = z_[pos] - q[2];
    return dx * dx + dy * dy + dz * dz;
  }
  const std::vector<Node>& nodes() const { return nodes_; }
  /// Bytes held by the tree (nodes, coordinates, indices).
  std::size_t memoryBytes() const {
    return nodes_.capacity() * sizeof(Node) +
           (cells_.capacity() + x_.capacity() + y_.capacity() + z_.capacity()) * sizeof(Scalar) +
           (parent_.capacity() + leaf_of_.capacity() + index_.capacity()) * sizeof(std::uint32_t);
  }

  /// Nearest point strictly closer than sqrt(max_squared_distance) (node = its tree
  /// position, kNone if none). `hint` (a tree position or kNone) seeds the bound with a
  /// known point; it only prunes, so the answer equals a cold search's up to ties.
  NearestNeighbor<Scalar> nearest(const Scalar* q, Scalar max_squared_distance,
                                  std::uint32_t hint = NearestNeighbor<Scalar>::kNone) const;

 private:
  /// A point during the build: its coordinates next to its input index, so that the
  /// median selections move contiguous records instead of chasing indices into the cloud.
  struct Record {
    Scalar p[3];
    std::uint32_t index;
  };
  template <typename Keep>
  void collect(const CloudView<Scalar>& cloud, Keep&& keep, std::vector<Record>& records) const;
  void buildNode(Record* first, std::size_t n, std::size_t node, std::size_t offset, int depth,
                 std::uint32_t parent, const Scalar* cell);
  static void selectMedian(Record* first, std::size_t n, std::size_t m, int axis);
  std::size_t subtreeNodes(std::size_t n) const {
    return n <= static_cast<std::size_t>(leaf_size_) ? 1 : 1 + subtreeNodes(n / 2) + subtreeNodes(n - n / 2);
  }
  int subtreeHeight(std::size_t n) const {
    return n <= static_cast<std::size_t>(leaf_size_) ? 0 : 1 + subtreeHeight(n - n / 2);
  }
  static Scalar boxDistance(const Scalar* q, const Node& nd) {
    Scalar d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const Scalar e = std::max(std::max(nd.lo[k] - q[k], q[k] - nd.hi[k]), Scalar(0));
      d2 += e * e;
    }
    return d2;
  }

  /// Scans leaf `nd` for a point closer than best_d2 (updated in place).
  void scanLeaf(const Scalar* q, const Node& nd, Scalar& best_d2, std::uint32_t& best_pos) const {
    // Distances first, into a small array (a loop the compiler vectorises), then their
    // minimum by a SIMD reduction; only a leaf that improves the bound is searched for
    // the position. Ties go to the first point, as a sequential scan would.
    alignas(32) Scalar d2[kMaxLeafSize];
    const Scalar* xs = x_.data() + nd.first;
    const Scalar* ys = y_.data() + nd.first;
    const Scalar* zs = z_.data() + nd.first;
    const int n = static_cast<int>(nd.count);
    const Scalar qx = q[0], qy = q[1], qz = q[2];
#pragma omp simd
    for (int i = 0; i < n; ++i) {
      const Scalar dx = xs[i] - qx, dy = ys[i] - qy, dz = zs[i] - qz;
      d2[i] = dx * dx + dy * dy + dz * dz;
    }
    Scalar m = best_d2;
#pragma omp simd reduction(min : m)
    for (int i = 0; i < n; ++i) m = std::min(m, d2[i]);
    if (!(m < best_d2)) return;
    for (int i = 0; i < n; ++i)
      if (d2[i] == m) {
        best_pos = nd.first + static_cast<std::uint32_t>(i);
        break;
      }
    best_d2 = m;
  }
  /// Searches the subtree of `start` for points closer than best_d2 (updated in place).
  void searchDown(const Scalar* q, std::uint32_t start, Scalar& best_d2, std::uint32_t& best_pos) const;
  /// The open ball of squared radius r2 around q lies strictly inside node i's cell.
  bool ballInCell(const Scalar* q, Scalar r2, std::uint32_t i) const {
    const Scalar* c = &cells_[6 * static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      const Scalar below = q[k] - c[k], above = c[3 + k] - q[k];
      if (!(below > 0 && below * below > r2 && above > 0 && above * above > r2)) return false;
    }
    return true;
  }

  std::vector<Node> nodes_;
  std::vector<Scalar> cells_;             ///< per node: k-d cell {lo x, lo y, lo z, hi x, hi y, hi z} (may be infinite)
  std::vector<std::uint32_t> parent_;     ///< per node: parent index (the root's is kNone)
  std::vector<std::uint32_t> leaf_of_;    ///< per tree position: its leaf node
  std::vector<Scalar> x_, y_, z_;
  std::vector<std::uint32_t> index_;
  int leaf_size_ = kDefaultLeafSize;
  int height_ = 0;
};

template <typename Scalar>
template <typename Keep>
void BucketKdTree<Scalar>::collect(const CloudView<Scalar>& cloud, Keep&& keep, std::vector<Record>& records) const {
  records.clear();
  records.reserve(cloud.size);
  for (std::size_t i = 0; i < cloud.size; ++i)
    if (cloud.isFinite(i) && keep(i)) {
      const Scalar* p = cloud.ptr(i);
      records.push_back({{p[0], p[1], p[2]}, static_cast<std::uint32_t>(i)});
    }
}

template <typename Scalar>
template <typename Keep>
void BucketKdTree<Scalar>::build(const CloudView<Scalar>& cloud, Keep&& keep, int leaf_size, int num_threads) {
  if (leaf_size < 1 || leaf_size > kMaxLeafSize)
    throw std::invalid_argument("bucket k-d tree: leaf_size must be in [1, 64]");
  if (cloud.size >= (std::size_t{1} << 32) - 1) throw std::invalid_argument("bucket k-d tree: too many points");
  leaf_size_ = leaf_size;
  std::vector<Record> records;
  collect(cloud, keep, records);
  const std::size_t n = records.size();
  const std::size_t nn = n ? subtreeNodes(n) : 0;
  nodes_.assign(nn, Node{});
  cells_.assign(6 * nn, Scalar(0));
  parent_.assign(nn, NearestNeighbor<Scalar>::kNone);
  leaf_of_.resize(n);
  x_.resize(n);
  y_.resize(n);
  z_.resize(n);
  index_.resize(n);
  height_ = n ? subtreeHeight(n) : 0;
  if (n == 0) return;
  const Scalar inf = std::numeric_limits<Scalar>::infinity();
  const Scalar root_cell[6] = {-inf, -inf, -inf, inf, inf, inf};
#pragma omp parallel num_threads(resolveThreads(num_threads))
#pragma omp single nowait
  buildNode(records.data(), n, 0, 0, 0, NearestNeighbor<Scalar>::kNone, root_cell);
}

template <typename Scalar>
void BucketKdTree<Scalar>::buildNode(Record* first, std::size_t n, std::size_t node, std::size_t offset, int depth,
                                     std::uint32_t parent, const Scalar* cell) {
  Node& nd = nodes_[node];
  parent_[node] = parent;
  std::copy(cell, cell + 6, &cells_[6 * node]);
  for (int k = 0; k < 3; ++k) nd.lo[k] = nd.hi[k] = first[0].p[k];
  for (std::size_t i = 1; i < n; ++i) {
    const Scalar* p = first[i].p;
    for (int k = 0; k < 3; ++k) {
      nd.lo[k] = std::min(nd.lo[k], p[k]);
      nd.hi[k] = std::max(nd.hi[k], p[k]);
    }
  }
  if (n <= static_cast<std::size_t>(leaf_size_)) {
    nd.first = static_cast<std::uint32_t>(offset);
    nd.count = static_cast<std::uint32_t>(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Scalar* p = first[i].p;
      x_[offset + i] = p[0];
      y_[offset + i] = p[1];
      z_[offset + i] = p[2];
      index_[offset + i] = first[i].index;
      leaf_of_[offset + i] = static_cast<std::uint32_t>(node);
    }
    return;
  }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (nd.hi[k] - nd.lo[k] > nd.hi[axis] - nd.lo[axis]) axis = k;
  const std::size_t m = n / 2;
  selectMedian(first, n, m, axis);
  const std::size_t left = node + 1, right = node + 1 + subtreeNodes(m);
  nd.first = static_cast<std::uint32_t>(right);
  nd.count = 0;
  // Points left of the median are <= the split value, points right of it >= it, so the
  // children's closed cells meet only on the splitting plane.
  const Scalar split = first[m].p[axis];
  Scalar left_cell[6], right_cell[6];
  std::copy(cell, cell + 6, left_cell);
  std::copy(cell, cell + 6, right_cell);
  left_cell[3 + axis] = split;
  right_cell[axis] = split;
  const auto self = static_cast<std::uint32_t>(node);
  // Tasks near the root only: below a few thousand points the task overhead dominates.
  if (n > 8192 && depth < 8) {
#pragma omp task firstprivate(first, m, left, offset, depth, self, left_cell)
    buildNode(first, m, left, offset, depth + 1, self, left_cell);
    buildNode(first + m, n - m, right, offset + m, depth + 1, self, right_cell);
#pragma omp taskwait
  } else {
    buildNode(first, m, left, offset, depth + 1, self, left_cell);
    buildNode(first + m, n - m, right, offset + m, depth + 1, self, right_cell);
  }
}

/// Reorders first[0, n) so that first[m] holds the m-th smallest coordinate along `axis`,
/// with no larger one before it and no smaller one after it (as std::nth_element).
/// Quickselect whose pivot is the median of a small sample, so that each round keeps
/// about a tenth of the range, and whose partition is branch-free: comparisons on
/// scattered coordinates are unpredictable, and std::nth_element's mispredicted branches
/// were most of the build's time.
template <typename Scalar>
void BucketKdTree<Scalar>::selectMedian(Record* first, std::size_t n, std::size_t m, int axis) {
  constexpr std::size_t kSmall = 64, kSample = 15;
  while (n > kSmall) {
    Scalar sample[kSample];
    for (std::size_t s = 0; s < kSample; ++s) sample[s] = first[(2 * s + 1) * n / (2 * kSample)].p[axis];
    // The sample's order statistic nearest m's rank.
    const std::size_t rank = std::min(kSample - 1, m * kSample / n);
    std::nth_element(sample, sample + rank, sample + kSample);
    const Scalar pivot = sample[rank];
    // Branch-free Lomuto partitions: [0, lt) < pivot, then (only when m is not below
    // them) [lt, le) == pivot.
    std::size_t lt = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Record r = first[i];
      first[i] = first[lt];
      first[lt] = r;
      lt += r.p[axis] < pivot;
    }
    if (m < lt) {
      n = lt;
      continue;
    }
    std::size_t le = lt;
    for (std::size_t i = lt; i < n; ++i) {
      const Record r = first[i];
      first[i] = first[le];
      first[le] = r;
      le += !(pivot < r.p[axis]);
    }
    if (m < le) {
      return;  // first[m] equals the pivot: done
    } else {
      first += le;
      m -= le;
      n -= le;
    }
  }
  std::nth_element(first, first + m, first + n,
                   [axis](const Record& a, const Record& b) { return a.p[axis] < b.p[axis]; });
}

template <typename Scalar>
void BucketKdTree<Scalar>::searchDown(const Scalar* q, std::uint32_t start, Scalar& best_d2,
                                      std::uint32_t& best_pos) const {
  if (!(boxDistance(q, nodes_[start]) < best_d2)) return;
  struct Pending {
    std::uint32_t node;
    Scalar box_d2;
  };
  std::array<Pending, kMaxStack> stack;
  int sp = 0;
  std::uint32_t cur = start;
  for (;;) {
    const Node& nd = nodes_[cur];
    if (nd.leaf()) {
      scanLeaf(q, nd, best_d2, best_pos);
    } else {
      // Nearer child first; the farther one waits on the stack if its box can still
      // hold a closer point.
      std::uint32_t a = cur + 1, c = nd.first;
      Scalar da = boxDistance(q, nodes_[a]), dc = boxDistance(q, nodes_[c]);
      if (dc < da) {
        std::swap(a, c);
        std::swap(da, dc);
      }
      if (da < best_d2) {
        if (dc < best_d2) stack[sp++] = {c, dc};
        cur = a;
        continue;
      }
    }
    // Pop the next pending branch that can still hold a closer point.
    while (sp > 0 && !(stack[sp - 1].box_d2 < best_d2)) --sp;
    if (sp == 0) return;
    cur = stack[--sp].node;
  }
}

template <typename Scalar>
NearestNeighbor<Scalar> BucketKdTree<Scalar>::nearest(const Scalar* q, Scalar max_squared_distance,
                                                      std::uint32_t hint) const {
  NearestNeighbor<Scalar> best;
  if (nodes_.empty()) return best;
  Scalar best_d2 = max_squared_distance;
  std::uint32_t best_pos = NearestNeighbor<Scalar>::kNone;
  if (hint < index_.size()) {
    // Bottom-up: the hint's leaf first.
    const std::uint32_t leaf = leaf_of_[hint];
    scanLeaf(q, nodes_[leaf], best_d2, best_pos);
    // Climb: at each level the sibling subtree is searched (its box test rejects it
    // unless the ball reaches it), until the ball lies inside the current node's cell.
    std::uint32_t cur = leaf;
    while (cur != 0 && !ballInCell(q, best_d2, cur)) {
      const std::uint32_t parent = parent_[cur];
      const std::uint32_t sibling = cur == parent + 1 ? nodes_[parent].first : parent + 1;
      searchDown(q, sibling, best_d2, best_pos);
      cur = parent;
    }
    best.node = best_pos;
    best.squared_distance = best.found() ? best_d2 : std::numeric_limits<Scalar>::infinity();
    return best;
  }
  searchDown(q, 0, best_d2, best_pos);
  best.node = best_pos;
  best.squared_distance = best.found() ? best_d2 : std::numeric_limits<Scalar>::infinity();
  return best;
}

}  // namespace scanalign
