// The left-balanced k-d tree's flat layout and its fixed-stack nearest-neighbour search,
// shared by the CPU engine (kdtree.hpp) and the CUDA kernel (cuda/icp_device.hpp).
//
// The eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3.1 and Algorithm 1
// (after Qiu et al. 2009): node i has children 2i+1 and 2i+2, so the tree is one dense
// array that is copied to the GPU as is, and each GPU thread descends it with a stack of
// fixed depth. Plain C++ on raw arrays: the same function runs on both sides.
#pragma once

#include <cstdint>

#include "scanalign/common/host_device.hpp"

namespace scanalign {

/// One node: the point's coordinates and, packed into one word, the index of the point in
/// the input cloud (high 30 bits) and the split axis (low 2 bits). 16 bytes for float.
template <typename Scalar>
struct LeftBalancedNode {
  Scalar p[3];
  std::uint32_t tag;
  SCANALIGN_HOST_DEVICE std::uint32_t index() const { return tag >> 2; }
  SCANALIGN_HOST_DEVICE int axis() const { return static_cast<int>(tag & 3u); }
};

/// Tight bounding box of a node's subtree (m).
template <typename Scalar>
struct SubtreeBounds {
  Scalar lo[3], hi[3];
};

/// Result of one nearest-neighbour query.
template <typename Scalar>
struct NearestNeighbor {
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  std::uint32_t node = kNone;  ///< position in the tree's node array (kNone: nothing within range)
  Scalar squared_distance = static_cast<Scalar>(INFINITY);  ///< m^2
  bool exact = true;  ///< false when a branch dropped for lack of stack could hold a closer point
  SCANALIGN_HOST_DEVICE bool found() const { return node != kNone; }
};

namespace detail {

template <typename Scalar>
SCANALIGN_HOST_DEVICE inline Scalar squaredDistance(const Scalar* a, const Scalar* b) {
  const Scalar dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return dx * dx + dy * dy + dz * dz;
}

/// Squared distance from q to a subtree box (0 inside).
template <typename Scalar>
SCANALIGN_HOST_DEVICE inline Scalar boxDistance(const Scalar* q, const SubtreeBounds<Scalar>& b) {
  Scalar d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const Scalar below = b.lo[k] - q[k], above = q[k] - b.hi[k];
    const Scalar e = below > 0 ? below : (above > 0 ? above : Scalar(0));
    d2 += e * e;
  }
  return d2;
}

}  // namespace detail

/// Nearest node of the n-node tree (nodes, bounds) to q strictly closer than
/// sqrt(max_squared_distance). `hint` (a node position or kNone) seeds the bound with a known
/// point, which only prunes. Far branches wait on a stack of `stack_depth` entries (clamped to
/// [1, Capacity]); a branch dropped for lack of room makes the result inexact only if it could
/// have held a closer point. Along a root-to-leaf path at most one far branch per level is
/// pending, so a stack as deep as the tree is high is always exact.
template <typename Scalar, int Capacity>
SCANALIGN_HOST_DEVICE inline NearestNeighbor<Scalar> leftBalancedNearest(const LeftBalancedNode<Scalar>* nodes,
                                                                         const SubtreeBounds<Scalar>* bounds,
                                                                         std::uint32_t n, const Scalar* q,
                                                                         Scalar max_squared_distance, int stack_depth,
                                                                         std::uint32_t hint) {
  NearestNeighbor<Scalar> best;
  if (n == 0) return best;
  best.squared_distance = max_squared_distance;
  if (hint < n) {
    const Scalar d2 = detail::squaredDistance(q, nodes[hint].p);
    if (d2 < best.squared_distance) {
      best.squared_distance = d2;
      best.node = hint;
    }
  }
  stack_depth = stack_depth < 1 ? 1 : (stack_depth > Capacity ? Capacity : stack_depth);
  std::uint32_t stack_node[Capacity];
  Scalar stack_d2[Capacity];  ///< squared distance from q to the pending branch's subtree box
  int sp = 0;
  Scalar min_dropped = static_cast<Scalar>(INFINITY);
  std::uint32_t cur = detail::boxDistance(q, bounds[0]) < best.squared_distance ? 0u : n;
  for (;;) {
    while (cur < n) {
      const LeftBalancedNode<Scalar>& nd = nodes[cur];
      const Scalar d2 = detail::squaredDistance(q, nd.p);
      if (d2 < best.squared_distance) {
        best.squared_distance = d2;
        best.node = cur;
      }
      // Near side of the split first. The far child is kept only if both the split plane
      // and its subtree box can still hold a closer point: the plane test is cheap and
      // rejects most, the box test catches the cells that are long and empty.
      const int axis = nd.axis();
      const Scalar diff = q[axis] - nd.p[axis];
      const std::uint32_t near = diff < 0 ? 2 * cur + 1 : 2 * cur + 2;
      const std::uint32_t far = diff < 0 ? 2 * cur + 2 : 2 * cur + 1;
      if (far < n && diff * diff < best.squared_distance) {
        const Scalar d_far = detail::boxDistance(q, bounds[far]);
        if (d_far < best.squared_distance) {
          if (sp < stack_depth) {
            stack_node[sp] = far;
            stack_d2[sp++] = d_far;
          } else if (d_far < min_dropped) {
            min_dropped = d_far;
          }
        }
      }
      cur = near;
    }
    // Pop the next branch whose box can still hold a closer point.
    for (;;) {
      if (sp == 0) {
        best.exact = !(min_dropped < best.squared_distance);
        if (!best.found()) best.squared_distance = static_cast<Scalar>(INFINITY);
        return best;
      }
      --sp;
      if (stack_d2[sp] < best.squared_distance) break;
    }
    cur = stack_node[sp];
  }
}

}  // namespace scanalign
