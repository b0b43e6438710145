// Left-balanced k-d tree in one flat array, searched with a fixed-size stack.
//
// The eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3.1 (after Qiu et al. 2009): the tree over the model points is built once
// on the CPU; being left-balanced (a complete binary tree) it needs no child pointers --
// node i has children 2i+1 and 2i+2 -- so it is one dense array that can be copied to a
// GPU as is. The nearest-neighbour search keeps the far branches it still has to visit
// on a stack of fixed depth (20 in the eye-in-hand paper). Along any root-to-leaf path at most one
// far branch per level is pending, so a stack as deep as the tree is high makes the
// search exact; a shallower stack drops branches and the search reports whether a
// dropped branch could have held a closer point.
//
// Beside the nodes, a second flat array keeps the tight bounding box of each node's
// subtree. Scan data lie on surfaces, where k-d cells are long in the normal direction; a
// query off the surface is then near many cells but near few tight boxes, so pruning by
// box distance visits far fewer nodes. The bound is exact, so the search stays exact.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/registration/left_balanced_search.hpp"

namespace scanalign {

template <typename Scalar>
class LeftBalancedKdTree {
 public:
  /// Hard upper bound on the search stack; the tree's height never exceeds 31 because
  /// indices are 30-bit, so kMaxStack also makes the radius search always exact.
  static constexpr int kMaxStack = 64;
  static constexpr int kDefaultStack = 20;  ///< eye-in-hand paper §3.1

  /// One node: the point's coordinates and its input index and split axis packed into one
  /// word (left_balanced_search.hpp, the layout a GPU receives as is).
  using Node = LeftBalancedNode<Scalar>;

  LeftBalancedKdTree() = default;
  explicit LeftBalancedKdTree(const CloudView<Scalar>& cloud) { build(cloud); }

  /// Builds the tree over the finite points of `cloud` (non-finite points are skipped;
  /// Node::index() refers to positions in `cloud`). O(n log n) time.
  void build(const CloudView<Scalar>& cloud) {
    build(cloud, [](std::size_t) { return true; });
  }
  /// As build(cloud), keeping only the finite points i for which keep(i) is true.
  template <typename Keep>
  void build(const CloudView<Scalar>& cloud, Keep&& keep);

  std::size_t size() const { return nodes_.size(); }
  bool empty() const { return nodes_.empty(); }
  /// Number of levels below the root (0 for a single node).
  int height() const { return height_; }
  const Node& node(std::size_t i) const { return nodes_[i]; }
  const std::vector<Node>& nodes() const { return nodes_; }
  /// Tight bounding box of node i's subtree.
  using Bounds = SubtreeBounds<Scalar>;
  const std::vector<Bounds>& bounds() const { return bounds_; }

  /// Nearest neighbour of `q` strictly closer than sqrt(max_squared_distance).
  /// `hint` (a node position or kNone) seeds the bound with a known point, which only
  /// prunes the search: the answer is the same as without a hint (up to ties).
  /// `stack_depth` is clamped to [1, kMaxStack].
  NearestNeighbor<Scalar> nearest(const Scalar* q, Scalar max_squared_distance,
                                  int stack_depth = kDefaultStack,
                                  std::uint32_t hint = NearestNeighbor<Scalar>::kNone) const;

  /// Calls f(node_position, squared_distance) for every point with squared distance
  /// <= radius^2 from q. Always exact (stack of kMaxStack >= height).
  template <typename F>
  void forEachInRadius(const Scalar* q, Scalar squared_radius, F&& f) const;

 private:
  void buildRange(const CloudView<Scalar>& cloud, std::uint32_t* first, std::size_t n, std::size_t node, int depth);

  /// Squared distance from q to node i's subtree box (0 inside).
  Scalar boxDistance(const Scalar* q, std::size_t i) const { return detail::boxDistance(q, bounds_[i]); }

  std::vector<Node> nodes_;
  std::vector<Bounds> bounds_;
  int height_ = 0;
};

namespace detail {

/// Size of the left subtree of a complete ("left-balanced") binary tree of n nodes.
inline std::size_t leftSubtreeSize(std::size_t n) {
  if (n <= 1) return 0;
  int h = 0;  // index of the last level
  while ((std::size_t{2} << h) <= n) ++h;  // 2^(h+1) <= n  => more levels
  const std::size_t full_above = (std::size_t{1} << h) - 1;  // nodes on levels 0..h-1
  const std::size_t last = n - full_above;                    // nodes on level h
  const std::size_t half = std::size_t{1} << (h - 1);         // level-h capacity of the left subtree
  return (half - 1) + std::min(last, half);
}

}  // namespace detail

template <typename Scalar>
template <typename Keep>
void LeftBalancedKdTree<Scalar>::build(const CloudView<Scalar>& cloud, Keep&& keep) {
  nodes_.clear();
  bounds_.clear();
  height_ = 0;
  if (cloud.size >= (std::size_t{1} << 30)) throw std::invalid_argument("k-d tree: at most 2^30 points");
  std::vector<std::uint32_t> order;
  order.reserve(cloud.size);
  for (std::size_t i = 0; i < cloud.size; ++i)
    if (cloud.isFinite(i) && keep(i)) order.push_back(static_cast<std::uint32_t>(i));
  const std::size_t n = order.size();
  nodes_.resize(n);
  if (n == 0) return;
  while ((std::size_t{2} << height_) <= n) ++height_;
  // The top of the tree is split into OpenMP tasks; below a few thousand points per
  // subtree the task overhead outweighs the work.
#pragma omp parallel
#pragma omp single nowait
  buildRange(cloud, order.data(), n, 0, 0);
  // Subtree boxes bottom-up: children come after their parent in the array.
  bounds_.resize(n);
  for (std::size_t i = n; i-- > 0;) {
    Bounds& b = bounds_[i];
    for (int k = 0; k < 3; ++k) b.lo[k] = b.hi[k] = nodes_[i].p[k];
    for (std::size_t c : {2 * i + 1, 2 * i + 2})
      if (c < n)
        for (int k = 0; k < 3; ++k) {
          b.lo[k] = std::min(b.lo[k], bounds_[c].lo[k]);
          b.hi[k] = std::max(b.hi[k], bounds_[c].hi[k]);
        }
  }
}

template <typename Scalar>
void LeftBalancedKdTree<Scalar>::buildRange(const CloudView<Scalar>& cloud, std::uint32_t* first, std::size_t n,
                                            std::size_t node, int depth) {
  while (n > 0) {
    // Split along the axis of largest extent of this subset's bounding box.
    Scalar lo[3], hi[3];
    for (int k = 0; k < 3; ++k) lo[k] = hi[k] = cloud.ptr(first[0])[k];
    for (std::size_t i = 1; i < n; ++i) {
      const Scalar* p = cloud.ptr(first[i]);
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], p[k]);
        hi[k] = std::max(hi[k], p[k]);
      }
    }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    const std::size_t m = detail::leftSubtreeSize(n);
    std::nth_element(first, first + m, first + n, [&](std::uint32_t a, std::uint32_t b) {
      return cloud.ptr(a)[axis] < cloud.ptr(b)[axis];
    });
    Node& nd = nodes_[node];
    const Scalar* p = cloud.ptr(first[m]);
    nd.p[0] = p[0];
    nd.p[1] = p[1];
    nd.p[2] = p[2];
    nd.tag = (first[m] << 2) | static_cast<std::uint32_t>(axis);
    // Left subtree recursively (as a task near the root), right subtree by iteration.
    if (m > 0) {
      if (m > 4096 && depth < 8) {
        std::uint32_t* left_first = first;
        const std::size_t left_node = 2 * node + 1;
#pragma omp task firstprivate(left_first, m, left_node, depth)
        buildRange(cloud, left_first, m, left_node, depth + 1);
      } else {
        buildRange(cloud, first, m, 2 * node + 1, depth + 1);
      }
    }
    first += m + 1;
    n -= m + 1;
    node = 2 * node + 2;
    ++depth;
  }
}

template <typename Scalar>
NearestNeighbor<Scalar> LeftBalancedKdTree<Scalar>::nearest(const Scalar* q, Scalar max_squared_distance,
                                                            int stack_depth, std::uint32_t hint) const {
  return leftBalancedNearest<Scalar, kMaxStack>(nodes_.data(), bounds_.data(), static_cast<std::uint32_t>(nodes_.size()),
                                                q, max_squared_distance, stack_depth, hint);
}

template <typename Scalar>
template <typename F>
void LeftBalancedKdTree<Scalar>::forEachInRadius(const Scalar* q, Scalar squared_radius, F&& f) const {
  const std::size_t n = nodes_.size();
  if (n == 0 || boxDistance(q, 0) > squared_radius) return;
  std::array<std::uint32_t, kMaxStack> stack;
  int sp = 0;
  std::size_t cur = 0;
  for (;;) {
    while (cur < n) {
      const Node& nd = nodes_[cur];
      const Scalar d2 = detail::squaredDistance(q, nd.p);
      if (d2 <= squared_radius) f(static_cast<std::uint32_t>(cur), d2);
      const std::size_t l = 2 * cur + 1, r = 2 * cur + 2;
      const bool go_l = l < n && boxDistance(q, l) <= squared_radius;
      const bool go_r = r < n && boxDistance(q, r) <= squared_radius;
      if (go_l && go_r) stack[sp++] = static_cast<std::uint32_t>(r);
      cur = go_l ? l : (go_r ? r : n);
    }
    if (sp == 0) return;
    cur = stack[--sp];
  }
}

}  // namespace scanalign
